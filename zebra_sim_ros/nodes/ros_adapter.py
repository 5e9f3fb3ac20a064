"""What every node adapter shares: the node base class (parameters declared from the stage's config, validated,
changed at run time where allowed; start and stop), QoS, stamps and a guarded ``main``.

Only modules under ``zebra_sim_ros.nodes`` import rclpy.
"""

from __future__ import annotations

import importlib
import sys
import threading
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any, Generic, TypeVar

import numpy as np
import rclpy
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, Pose, PoseStamped, PoseWithCovariance, Quaternion, Vector3
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.executors import Executor, ExternalShutdownException, MultiThreadedExecutor, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Image, PointCloud2, PointField
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import ImageMarker

from zebra_sim_ros.errors import ZebraSimError
from zebra_sim_ros.geometry.locate import StampedPose
from zebra_sim_ros.health import Activity, Health, HealthMonitor, status_name
from zebra_sim_ros.messages import Detections, SceneZebra, Stamp
from zebra_sim_ros.messages import stamp_ns as messages_stamp_ns
from zebra_sim_ros.params import ROS_BUILTIN_PARAMS, ParamSpec, StageConfig


def descriptor(spec: ParamSpec, ranges: bool = True) -> ParameterDescriptor:
    """The ROS descriptor of a parameter: its description and allowed values, and (with ``ranges``) its numeric
    range, which ``ros2 param describe`` and rqt show and rclpy enforces on values of the range's type.

    Parameters are dynamically typed so that ``rate_hz: 2`` in YAML is accepted for a float (rclpy checks a
    floating-point range only on float values, an integer range only on integers); the stage's validation then
    coerces and range-checks every value and names any bad one.
    """
    runtime = "; can change while the node runs" if spec.runtime else "; fixed while the node runs"
    d = ParameterDescriptor(description=f"{spec.description} (allowed: {spec.allowed}{runtime})",
                            additional_constraints=spec.allowed, dynamic_typing=True)
    if ranges and spec.lo is not None and spec.hi is not None:
        if isinstance(spec.default, float):
            d.floating_point_range = [FloatingPointRange(from_value=float(spec.lo), to_value=float(spec.hi), step=0.0)]
        elif isinstance(spec.default, int) and not isinstance(spec.default, bool):
            d.integer_range = [IntegerRange(from_value=int(spec.lo), to_value=int(spec.hi), step=1)]
    return d


def declare_and_read(node: Node, specs: Iterable[ParamSpec]) -> dict[str, Any]:
    """Declare every spec as a parameter (with its description, without its range) and return the raw values.

    The range is left out here so that a value out of range reaches the stage's validation, which names it,
    instead of failing in rclpy; :func:`add_ranges` adds the ranges once the values are valid.
    """
    values: dict[str, Any] = {}
    for s in specs:
        node.declare_parameter(s.name, s.default, descriptor(s, ranges=False))
        values[s.name] = node.get_parameter(s.name).value
    return values


def add_ranges(node: Node, specs: Iterable[ParamSpec]) -> None:
    """Give every declared parameter its full descriptor (with its numeric range); the values must be valid."""
    for s in specs:
        node.set_descriptor(s.name, descriptor(s))


C = TypeVar("C", bound=StageConfig)
DIAGNOSTICS_TOPIC = "/diagnostics"  # absolute by convention: one topic for every node, as aggregators expect


class ZebraNode(Node, Generic[C]):
    """A node of the pipeline and its lifecycle: declare the stage's parameters, validate them into ``cfg`` (a
    :class:`ZebraSimError` here stops the node before anything starts), :meth:`start`, spin until ``done``,
    :meth:`stop`.

    Parameters marked ``runtime`` in the stage's config may change while the node runs (``ros2 param set``): the
    new values are validated by the same rules and the new config goes to :meth:`on_config`. Any other change is
    refused with a reason, as is a bad value.

    Every ``diagnostics_period_s`` (a parameter of every node) the node's :meth:`activity` is reported on
    :data:`DIAGNOSTICS_TOPIC` as one ``diagnostic_msgs/DiagnosticStatus`` named ``<node>: <executable>``
    (:mod:`zebra_sim_ros.health` says what the levels mean); a node that ends by itself reports once more first.
    """

    #: threads of the executor :func:`run_node` spins the node with: one serves every callback in turn; a node whose
    #: service answers only after a wait (the replay's ``~/burst``) takes two, that service in a callback group of its
    #: own, so that its timers, parameters and other services are served meanwhile
    executor_threads = 1

    def __init__(self, name: str, config: type[C], **node_args: Any) -> None:
        super().__init__(name, **node_args)  # node_args: rclpy Node's (context, cli_args, parameter_overrides)
        self.executable = name
        self.config_class = config
        self.health: HealthMonitor | None = None
        self.diagnostics_pub: Any = None
        # one report at a time: with two executor threads a timer's report may still run when the node's last one
        # is made; each takes the activity and remembers its counters for the next, so two interleaved would count
        # a period twice or from a later report's counters (a negative rate). After the last, none.
        self._report_lock = threading.Lock()
        self._reports_closed = False
        self.done = False  # set to end the spin
        self.exit_code = 0
        self.cfg: C = config.from_params(declare_and_read(self, config.specs()))
        add_ranges(self, config.specs())
        self._warn_unknown_parameters()
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.start()
        self._start_diagnostics()

    def activity(self) -> Activity:
        """What the node has done since it started, for /diagnostics: every node whose config has a
        ``diagnostics_period_s`` says."""
        raise NotImplementedError(f"{type(self).__name__} reports diagnostics but does not say its activity")

    def _start_diagnostics(self) -> None:
        period = float(getattr(self.cfg, "diagnostics_period_s", 0.0))  # 0, or a config without it: no reports
        if period <= 0:
            return
        self.health = HealthMonitor(time.monotonic())
        self.diagnostics_pub = self.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, qos("reliable", 10))
        self.wall_timer(period, self._diagnostics_tick)

    def _diagnostics_tick(self) -> None:
        self.publish_diagnostics()

    def publish_diagnostics(self, last: bool = False) -> Health | None:
        """Report the node's health since the last report on /diagnostics; the report (None: diagnostics off, or
        the node's ``last`` report made already: a timer's report waiting for the lock then makes none)."""
        if self.health is None or self.diagnostics_pub is None:
            return None
        with self._report_lock:
            if self._reports_closed:
                return None
            self._reports_closed = last
            act = self.activity()
            h = self.health.report(time.monotonic(), act)
            status = DiagnosticStatus(level=bytes([int(h.level)]),
                                      name=status_name(self.get_fully_qualified_name(), self.executable),
                                      message=h.message, hardware_id=act.hardware,
                                      values=[KeyValue(key=k, value=v) for k, v in h.values])
            self.diagnostics_pub.publish(DiagnosticArray(header=Header(stamp=self.get_clock().now().to_msg()),
                                                         status=[status]))
        return h

    def _warn_unknown_parameters(self) -> None:
        """A parameter given on the command line or in a params file that this node does not declare is ignored by
        rclpy without a word; say so (a typo otherwise looks like a setting that does nothing)."""
        known = {s.name for s in self.config_class.specs()} | set(ROS_BUILTIN_PARAMS)
        given = getattr(self, "_parameter_overrides", {}) or {}
        unknown = sorted(n for n in given if n not in known and not n.startswith("qos_overrides."))
        if unknown:
            self.get_logger().warning(f"unknown parameter(s) ignored: {unknown}; {self.get_name()} declares "
                                      f"{sorted(known - set(ROS_BUILTIN_PARAMS))}")

    def skip_bad(self, counts: dict[str, int], what: str, exc: BaseException) -> None:
        """A message that cannot be used: counted in ``counts["bad_messages"]`` and logged with why, then skipped."""
        counts["bad_messages"] = counts.get("bad_messages", 0) + 1
        self.get_logger().error(f"{what} skipped ({counts['bad_messages']} bad so far): {type(exc).__name__}: {exc}")

    def skip_unmatched(self, counts: dict[str, int], dropped: list[tuple[int, str]]) -> None:
        """Cameras' inputs of a stamp dropped before they were used (:meth:`FrameParts.put`'s pushed out: some never
        arrived, or what else the node needs for them did not): counted in ``counts["unmatched"]`` and logged."""
        for old, camera in dropped:
            counts["unmatched"] = counts.get("unmatched", 0) + 1
            self.get_logger().warning(f"{camera}: inputs of stamp {old} dropped unused (not all arrived, or what "
                                      f"else they need did not: a scene, a camera_info; {counts['unmatched']} so "
                                      "far)")

    def wall_timer(self, period_s: float, callback: Callable[[], None]) -> Any:
        """A timer on the steady wall clock. rclpy's timers follow the node's clock, which under ``use_sim_time``
        stands still between two ``/clock`` messages: a recorder's topic discovery or a detector's batch window
        would then wait for the next simulated step, which waits for them."""
        return self.create_timer(period_s, callback, clock=Clock(clock_type=ClockType.STEADY_TIME))

    def start(self) -> None:
        """Load what the node needs and create its publishers, subscriptions and timers (``cfg`` is valid)."""

    def stop(self) -> None:
        """Release what :meth:`start` took (GL contexts, open files); called once, before the node is destroyed."""

    def on_config(self, cfg: C) -> None:
        """Apply a config in which runtime parameters changed (already validated). By default: keep it."""
        self.cfg = cfg

    def refuse_config(self, cfg: C, changes: Mapping[str, Any]) -> str:
        """Why a validated config set at run time (``changes``: the parameters set, changed or not) cannot be
        taken now, or "" where it can. By default every valid one can; a node whose state bounds a value (the
        replay: a time past its bags' end) says why not."""
        return ""

    def serve_pause(self) -> None:
        """``~/pause``, ``~/resume`` and ``~/toggle_paused`` (rosbag2_interfaces/srv/Pause, Resume and TogglePaused,
        as ``ros2 bag``'s: their answers are empty): each sets the node's runtime ``paused`` parameter, so ``ros2
        param get`` shows the state and :meth:`on_config` applies it, and the node logs the state it leaves and
        whether it changed (``~/pause: paused``, ``already paused``, ``~/resume: resumed``, ``not paused``) or why
        the change was refused. ``~/is_paused`` (rosbag2_interfaces/srv/IsPaused) gives the state."""
        from rosbag2_interfaces.srv import IsPaused, Pause, Resume, TogglePaused

        if "paused" not in {s.name for s in self.config_class.specs()}:
            raise TypeError(f"{self.executable}: serve_pause needs a runtime 'paused' parameter in its config")

        def setter(service: str, to: bool | None) -> Callable[[Any, Any], Any]:  # None: the other state
            def handle(request: Any, response: Any) -> Any:
                was = bool(self.get_parameter("paused").value)
                value = not was if to is None else to
                refused = self.set_param("paused", value)
                word, unchanged = ("paused", "already paused") if value else ("resumed", "not paused")
                self.log_service(service, not refused, refused or (word if was != value else unchanged))
                return response
            return handle

        self.create_service(Pause, "~/pause", setter("~/pause", True))
        self.create_service(Resume, "~/resume", setter("~/resume", False))
        self.create_service(TogglePaused, "~/toggle_paused", setter("~/toggle_paused", None))

        def is_paused(request: Any, response: Any) -> Any:
            response.paused = bool(self.get_parameter("paused").value)
            return response

        self.create_service(IsPaused, "~/is_paused", is_paused)

    def log_service(self, service: str, ok: bool, message: str) -> bool:
        """Log a service call's outcome, one line: ``~/pause: paused`` (info), or ``~/pause refused: why``
        (warning) where the call did nothing. rosbag2's services answer with no words (or a bare success), so the
        log is where a caller reads them. Returns ``ok``."""
        if ok:
            self.get_logger().info(f"{service}: {message}")
        else:
            self.get_logger().warning(f"{service} refused: {message}")
        return ok

    def set_param(self, name: str, value: bool | float) -> str:
        """Set one of the node's own parameters from inside the node (a service), through the same checks as
        ``ros2 param set``; returns why it was refused, or "" where it was set."""
        kind = Parameter.Type.BOOL if isinstance(value, bool) else Parameter.Type.DOUBLE
        result = self.set_parameters([Parameter(name, kind, value)])[0]
        return "" if result.successful else (result.reason or f"'{name}' refused")

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        specs = {s.name: s for s in self.config_class.specs()}
        changes = {p.name: p.value for p in params if p.name in specs}  # others (use_sim_time) are rclpy's
        current = self.cfg.as_params()
        fixed = [n for n, v in changes.items() if not specs[n].runtime and v != current[n]]
        if fixed:
            return SetParametersResult(successful=False, reason=f"'{fixed[0]}' cannot change while the node runs; "
                                       "restart it")
        try:
            cfg = self.cfg.with_changes(changes)
            if why := self.refuse_config(cfg, changes):
                return SetParametersResult(successful=False, reason=why)
            if cfg != self.cfg:
                self.on_config(cfg)
                self.get_logger().info(f"parameters changed: {changes}")
        except ZebraSimError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)


def message_class(type_name: str) -> Any:
    """The Python class of ``pkg/msg/Type``."""
    pkg, kind, name = type_name.split("/")
    return getattr(importlib.import_module(f"{pkg}.{kind}"), name)


def message_module(type_name: str) -> Any:
    """The message module of ``pkg/msg/Type``'s package (``pkg.msg``: the type's siblings, e.g. a Detection3DArray's
    Detection3D and BoundingBox3D in the same layout)."""
    return importlib.import_module(f"{type_name.split('/')[0]}.msg")


def qos(reliability: str = "reliable", depth: int = 10, transient_local: bool = False) -> QoSProfile:
    """A keep-last QoS profile from parameter values."""
    return profile_qos({"history": "keep_last", "depth": depth, "reliability": reliability,
                        "durability": "transient_local" if transient_local else "volatile"})


def profile_qos(profile: Mapping[str, Any]) -> QoSProfile:
    """The QoS profile of a profile dict in rosbag2's names (``recording.qos``: history, depth, reliability,
    durability; what it does not name takes :func:`qos`'s defaults)."""
    keep_all = profile.get("history") == "keep_all"
    return QoSProfile(
        history=HistoryPolicy.KEEP_ALL if keep_all else HistoryPolicy.KEEP_LAST,
        depth=int(profile.get("depth", 10)),
        reliability=ReliabilityPolicy.RELIABLE if profile.get("reliability", "reliable") == "reliable"
        else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if profile.get("durability") == "transient_local"
        else DurabilityPolicy.VOLATILE,
    )


def describe_qos(q: QoSProfile) -> str:
    """One line for the start-up log: QoS mismatches are the first thing users hit."""
    return (f"reliability={q.reliability.name.lower()} durability={q.durability.name.lower()} "
            f"history={q.history.name.lower()} depth={q.depth}")


def image_msg(header: Header, array: np.ndarray, encoding: str) -> Image:
    """A sensor_msgs/Image of a C-contiguous little-endian array (H, W[, C])."""
    a = np.ascontiguousarray(array)
    h, w = a.shape[:2]
    return Image(header=header, height=h, width=w, encoding=encoding, is_bigendian=0, step=int(a.strides[0]),
                 data=a.tobytes())


def point_cloud_msg(header: Header, points: np.ndarray, rgb: np.ndarray | None = None) -> PointCloud2:
    """An organised sensor_msgs/PointCloud2 of (h, w, 3) points (NaN: no point there, so not dense): float32 fields
    x, y, z and, with an (h, w, 3) uint8 ``rgb``, PCL's packed ``rgb`` (a float32 field holding 0x00RRGGBB, what
    RViz's RGB8 and Foxglove's packed colour read)."""
    h, w = points.shape[:2]
    names = ("x", "y", "z") + (("rgb",) if rgb is not None else ())
    cloud = np.empty((h, w), dtype=np.dtype({"names": list(names), "formats": ["<f4"] * len(names)}))
    for i, name in enumerate(("x", "y", "z")):
        cloud[name] = points[..., i]
    if rgb is not None:
        c = rgb.astype(np.uint32)
        cloud["rgb"] = ((c[..., 0] << 16) | (c[..., 1] << 8) | c[..., 2]).view("<f4")
    fields = [PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1) for i, n in enumerate(names)]
    step = cloud.dtype.itemsize
    return PointCloud2(header=header, height=h, width=w, fields=fields, is_bigendian=False, point_step=step,
                       row_step=step * w, data=cloud.tobytes(), is_dense=bool(np.isfinite(points).all()))


ACK_TOPIC = "zebra_sim/frame_done"  # std_msgs/Header: stamp = the step's, frame_id = who is done with it


def box_marker(header: Header, ns: str, boxes: Iterable[tuple[Sequence[float], ColorRGBA]]) -> ImageMarker:
    """One LINE_LIST ImageMarker with the four edges of every ``(x0, y0, x1, y1)`` box, each in its colour."""
    points, colors = [], []
    first: ColorRGBA | None = None
    for box, col in boxes:
        x0, y0, x1, y1 = (float(v) for v in box[:4])
        corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
        for a, b in zip(corners, corners[1:] + corners[:1], strict=True):
            points += [Point(x=a[0], y=a[1]), Point(x=b[0], y=b[1])]
            colors += [col, col]
        first = first or col
    return ImageMarker(header=header, ns=ns, id=0, type=ImageMarker.LINE_LIST, action=ImageMarker.ADD, scale=1.0,
                       outline_color=first or ColorRGBA(), points=points, outline_colors=colors)


V = TypeVar("V")


class RecentStamps(Generic[V]):
    """Values by stamp (ns), keeping the ``window`` stamps that arrived last. Not the largest ``window``: a restarted
    placer or a looping replay sends older stamps again, and those must be kept, not forgotten as they arrive."""

    def __init__(self, window: int) -> None:
        self.window = window
        self.items: dict[int, V] = {}  # in order of arrival, the latest last

    def __contains__(self, t: int) -> bool:
        return t in self.items

    def get(self, t: int) -> V | None:
        return self.items.get(t)

    def pop(self, t: int) -> V | None:
        return self.items.pop(t, None)

    def touch(self, t: int, make: Callable[[], V]) -> tuple[V, list[tuple[int, V]]]:
        """Stamp ``t``'s value (``make()`` if new), now the latest arrival; and the stamps this pushed out."""
        v = self.items.pop(t) if t in self.items else make()
        return v, self.put(t, v)

    def put(self, t: int, v: V) -> list[tuple[int, V]]:
        """Set stamp ``t``'s value, now the latest arrival; returns the stamps (and values) this pushed out."""
        self.items.pop(t, None)
        self.items[t] = v
        out: list[tuple[int, V]] = []
        while len(self.items) > self.window:
            old = next(iter(self.items))
            out.append((old, self.items.pop(old)))
        return out


class FrameParts:
    """Each camera's messages of one stamp (its ``parts``: an image, its depth, a pose...) gathered until all have
    arrived and the node takes them, for the ``window`` stamps that arrived last (:class:`RecentStamps`): a camera's
    parts of a stamp pushed out of the window before they were taken (some never came, or what else the node needs
    for them did not: a scene, a camera_info) are dropped, and :meth:`put` returns them."""

    def __init__(self, window: int, parts: Iterable[str]) -> None:
        self.parts = frozenset(parts)
        self.stamps: RecentStamps[dict[str, dict[str, Any]]] = RecentStamps(window)  # stamp: camera: part: message

    def put(self, t: int, camera: str, part: str, value: Any) -> list[tuple[int, str]]:
        """Hold ``camera``'s ``part`` of stamp ``t``; returns the (stamp, camera) pairs this pushed out, not taken."""
        by_camera, dropped = self.stamps.touch(t, dict)
        by_camera.setdefault(camera, {})[part] = value
        return [(old, c) for old, cameras in dropped for c in cameras]

    def take(self, t: int, camera: str) -> dict[str, Any] | None:
        """``camera``'s parts of stamp ``t`` by name, no longer held, once all have arrived; else None (held)."""
        by_camera = self.stamps.get(t) or {}
        got = by_camera.get(camera)
        if got is None or not self.parts <= got.keys():
            return None
        del by_camera[camera]
        if not by_camera:
            self.stamps.pop(t)
        return got

    def waiting(self) -> list[int]:
        """The stamps some camera's parts are held for, the oldest arrival first."""
        return list(self.stamps.items)


class StepAcks:
    """Acknowledges a stamp on :data:`ACK_TOPIC` as ``name`` once each of ``parts`` (drones, image topics) is
    done with it, for the placer's lockstep; remembers the last ``window`` stamps to arrive. No name: no
    acknowledgements."""

    def __init__(self, node: Node | None, name: str, parts: Iterable[str], window: int) -> None:
        self.name, self.parts = name, frozenset(parts)
        self.pub = node.create_publisher(Header, ACK_TOPIC, qos("reliable", 100)) if name and node else None
        self.done: RecentStamps[set[str]] = RecentStamps(window)

    def part_done(self, stamp_msg: Time, part: str) -> bool:
        """Note ``part`` done with this stamp; True (and acknowledged, with a name) when it was the last one."""
        t = stamp_ns(stamp_msg)
        done, _ = self.done.touch(t, set)
        done.add(part)
        complete = done >= self.parts
        if complete:  # a step sent again (a restarted placer, a re-sent step) is acknowledged when all are done again
            self.done.pop(t)
        if complete and self.pub is not None:
            self.pub.publish(Header(stamp=stamp_msg, frame_id=self.name))
        return complete


def flush(node: Node, publishers: Iterable[Any], timeout_s: float = 5.0) -> None:
    """Wait (up to ``timeout_s`` each) until reliable subscribers acknowledge what was published; warn if not.

    A node about to exit calls this: reliable writers may still owe their last messages to slow readers, and
    exiting at once would drop them (best-effort publishers return at once).
    """
    unacked = [p.topic_name for p in publishers if not p.wait_for_all_acked(Duration(seconds=timeout_s))]
    if unacked:
        node.get_logger().warning(f"not acknowledged by every subscriber within {timeout_s:g} s: {unacked}")


def stamp(ns: int) -> Time:
    """builtin_interfaces/Time from integer nanoseconds."""
    s = Stamp.from_ns(ns)
    return Time(sec=s.sec, nanosec=s.nanosec)


def stamp_ns(t: Time) -> int:
    """Integer nanoseconds of a builtin_interfaces/Time."""
    return messages_stamp_ns(t.sec, t.nanosec)


def help_text(executable: str, doc: str, specs: Iterable[ParamSpec]) -> str:
    """``--help`` text of a node: its docstring and a table of its parameters."""
    lines = [f"usage: ros2 run zebra_sim_ros {executable} [--ros-args -p name:=value ... "
             f"--params-file FILE]", "", doc.strip(), "",
             "parameters (name, default, meaning, allowed; * = can change while the node runs):"]
    for s in specs:
        lines.append(f"  {s.name} = {s.default!r}{' *' if s.runtime else ''}\n      {s.description}; "
                     f"allowed {s.allowed}")
    return "\n".join(lines)


def run_node(name: str, factory: Callable[[], ZebraNode[Any]], argv: list[str] | None = None,
             help: str = "") -> int:
    """Init rclpy, build the node (declare, validate, start), spin until it is ``done`` or interrupted, stop it
    and shut down; returns the exit status.

    ``-h``/``--help`` before ``--ros-args`` prints ``help`` and returns 0 without starting ROS. A
    :class:`ZebraSimError` at start-up (a bad parameter, a missing world) is logged as one line naming the
    problem and gives exit status 2.
    """
    args = list(argv if argv is not None else sys.argv)
    own = args[1:args.index("--ros-args")] if "--ros-args" in args else args[1:]
    if "-h" in own or "--help" in own:
        print(help or f"usage: ros2 run zebra_sim_ros {name} [--ros-args ...]")
        return 0
    rclpy.init(args=args)
    node: ZebraNode[Any] | None = None
    executor: Executor | None = None
    try:
        try:
            node = factory()
        except ZebraSimError as exc:
            rclpy.logging.get_logger(name).fatal(f"cannot start: {exc}")
            return 2
        # An executor of our own, built while the context is valid: rclpy's global one is rebuilt after a shutdown.
        executor = (MultiThreadedExecutor(num_threads=node.executor_threads) if node.executor_threads > 1
                    else SingleThreadedExecutor())
        executor.add_node(node)
        while rclpy.ok() and not node.done:
            try:
                executor.spin_once(timeout_sec=0.1)
            except Exception:
                if rclpy.ok():
                    raise
                # rclpy's SIGINT handler shut the context down after the loop's rclpy.ok() and before the wait set
                # was built, which then fails (RCLError): a Ctrl-C like any other.
                break
        try:
            if node.done and rclpy.ok() and node.publish_diagnostics(last=True) is not None:  # ended by itself: say how
                flush(node, [node.diagnostics_pub], timeout_s=1.0)
        except Exception:
            if rclpy.ok():
                raise
            # a Ctrl-C during the last report: rclpy's handler ended the context under it
        return node.exit_code
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    finally:
        if node is not None:
            node.stop()
            if executor is not None:  # emptied before the node goes: it holds the node's waitables
                executor.shutdown()
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()


# -- typed detections ---------------------------------------------------------------------------------------------
# vision_msgs/Detection2DArray where a ROS 2 install has vision_msgs; else ours, with the same fields.
DETECTION_TYPES = ("vision_msgs/msg/Detection2DArray", "zebra_sim_msgs/msg/Detection2DArray")


# The placed animals in 3D: vision_msgs/Detection3DArray where installed; else ours, with the same fields.
DETECTION3D_TYPES = ("vision_msgs/msg/Detection3DArray", "zebra_sim_msgs/msg/Detection3DArray")


def _first_importable(names: Sequence[str]) -> str:
    for name in names:
        try:
            message_class(name)
            return name
        except (ImportError, AttributeError):
            continue
    raise ZebraSimError(f"none of {tuple(names)} can be imported: run scripts/build_interfaces.sh")


def detection_array_type() -> str:
    """The Detection2DArray type this machine can publish (the first of :data:`DETECTION_TYPES` that imports)."""
    return _first_importable(DETECTION_TYPES)


def detection3d_array_type() -> str:
    """The Detection3DArray type this machine can publish (the first of :data:`DETECTION3D_TYPES` that imports)."""
    return _first_importable(DETECTION3D_TYPES)


def pose_msg(position: Sequence[float], orientation_xyzw: Sequence[float] = (0.0, 0.0, 0.0, 1.0)) -> Pose:
    """A Pose from a position (x, y, z) and a quaternion (x, y, z, w; identity by default)."""
    (px, py, pz), (qx, qy, qz, qw) = (float(v) for v in position), (float(v) for v in orientation_xyzw)
    return Pose(position=Point(x=px, y=py, z=pz), orientation=Quaternion(x=qx, y=qy, z=qz, w=qw))


def stamped_pose(msg: PoseStamped) -> StampedPose:
    """A geometry_msgs/PoseStamped as the locator's :class:`~zebra_sim_ros.geometry.locate.StampedPose`."""
    p, o = msg.pose.position, msg.pose.orientation
    return StampedPose(stamp_ns(msg.header.stamp), (p.x, p.y, p.z), (o.x, o.y, o.z, o.w), msg.header.frame_id)


def detection3d_array_msg(type_name: str, header: Header,
                          detections: Iterable[tuple[str, float, Pose, Pose, Sequence[float], str]]) -> Any:
    """A Detection3DArray of ``type_name`` (vision_msgs' or zebra_sim_msgs' layout) in ``header``'s frame, one
    Detection3D per (class id, score, the hypothesis' pose, the box's centre pose, the box's size x, y, z in m,
    id); the header on the array and on each detection. The locator's placed detections and census and the
    placer's scene animals are all built here."""
    msg = message_module(type_name)
    out = []
    for class_id, score, pose, center, (sx, sy, sz), ident in detections:
        hyp = msg.ObjectHypothesisWithPose(hypothesis=msg.ObjectHypothesis(class_id=class_id, score=float(score)),
                                           pose=PoseWithCovariance(pose=pose))
        box = msg.BoundingBox3D(center=center, size=Vector3(x=float(sx), y=float(sy), z=float(sz)))
        out.append(msg.Detection3D(header=header, results=[hyp], bbox=box, id=ident))
    return msg.Detection3DArray(header=header, detections=out)


def scene_animals_msg(type_name: str, header: Header, animals: Sequence[SceneZebra]) -> Any:
    """A scene's placed ``animals`` as a Detection3DArray of ``type_name`` in ``header``'s frame (the scene's
    ``map``): per animal one hypothesis, its species (``zebra``, ``elephant`` ...) with score 1 and the animal's own
    pose (its origin on the ground, its orientation), its oriented box (centre pose and size: length, width, height in
    m) and ``id`` the scene's id (the instance masks' id - 1); the header on the array and on each detection."""
    return detection3d_array_msg(type_name, header, (
        (z.species, 1.0, pose_msg(z.position, z.orientation_xyzw), pose_msg(z.box.center, z.box.orientation_xyzw),
         z.box.size, str(z.id)) for z in animals))


_ENCODING = {"mono16": "<u2", "16UC1": "<u2", "32SC1": "<i4", "32FC1": "<f4"}


def image_array(msg: Image) -> np.ndarray:
    """A single-channel image message as a 2D array; raises ValueError for encodings we do not read."""
    dtype = _ENCODING.get(msg.encoding)
    if dtype is None:
        raise ValueError(f"unsupported encoding {msg.encoding!r} (want one of {sorted(_ENCODING)})")
    dt = np.dtype(dtype).newbyteorder(">" if msg.is_bigendian else "<")
    row = msg.width * dt.itemsize
    buf = np.frombuffer(bytes(msg.data), dtype=np.uint8).reshape(msg.height, msg.step)[:, :row]
    return np.ascontiguousarray(buf).view(dt).reshape(msg.height, msg.width).astype(dt.newbyteorder("="))


def detection_array_msg(type_name: str, header: Header, dets: Detections, ids: Sequence[int] = ()) -> Any:
    """``dets`` as a Detection2DArray of ``type_name``: per box one hypothesis (class name, score), the box as
    centre and size in the image's pixels, ``id`` its rank by score (or ``ids``' value, where given); the image's
    header on the array and on each detection."""
    if ids and len(ids) != len(dets.detections):
        raise ValueError(f"{len(ids)} ids for {len(dets.detections)} detections")
    msg = message_module(type_name)
    out = []
    for k, d in enumerate(dets.detections):
        x0, y0, x1, y1 = d.box_xyxy
        hyp = msg.ObjectHypothesisWithPose(hypothesis=msg.ObjectHypothesis(class_id=d.class_name, score=d.score))
        box = msg.BoundingBox2D(center=msg.Pose2D(position=msg.Point2D(x=(x0 + x1) / 2, y=(y0 + y1) / 2)),
                                size_x=float(x1 - x0), size_y=float(y1 - y0))
        out.append(msg.Detection2D(header=header, results=[hyp], bbox=box, id=str(ids[k] if ids else k)))
    return msg.Detection2DArray(header=header, detections=out)
