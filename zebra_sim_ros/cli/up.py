"""``zebra-sim up``: the whole graph in one command (placer, cameras, labeller, detector, scorer, recorder).

Starts every node as its own process with the parameter files of the config folder, waits until each one is
ready (its topics published, recorded and scored), then starts the placer in lockstep: a step ends when the
labeller and the detector have both acknowledged it, so no frame is skipped. After the last step it stops the graph
(recorder last), reads the bag back and prints frames per drone, detection scores against the live ground truth
(and the scorer node's live figures, the same for a run no longer than its window), throughput and stage times; it
writes ``summary.json`` and ``preview.jpg`` beside the bag (and with ``--locate`` ``census.geojson``, the census
on the Earth), and at the start ``zebra_sim.rviz``, the package's RViz
configuration for this graph's drones and namespace (the command that opens it is printed). If a node dies, the rest
are stopped and the command says which died and why; Ctrl-C stops everything cleanly too.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from zebra_sim_ros.cli.common import Summary, add_json_flag, parse_set, parse_size
from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.params import add_option, spec_of

if TYPE_CHECKING:  # the graph and rclpy are imported only when the command runs
    from collections.abc import Sequence

    from zebra_sim_ros.detection.config import LocatorConfig, ScorerConfig
    from zebra_sim_ros.graph.spec import NodeSpec, UpConfig
    from zebra_sim_ros.graph.supervisor import Child, Supervisor
    from zebra_sim_ros.nodes.graph_watch import GraphWatch
    from zebra_sim_ros.rendering.config import CameraConfig


CENSUS_MAP = "census.geojson"  # up --locate: the locator's census on the Earth, beside the bag


def register(sub: Any) -> None:
    """Add the ``up`` subcommand."""
    from zebra_sim_ros.detection.config import DetectorConfig
    from zebra_sim_ros.placement.config import PlacerConfig

    p = sub.add_parser("up", help="run the whole graph for N steps in lockstep, record it and score the detector",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--frames", type=int, default=10, help="steps to run (each gives one frame per drone)")
    p.add_argument("--drones", type=int, default=3, help="cameras, drone_0 .. drone_<N-1>, each its own camera node "
                   "(1..16; the paper's three by default)")
    for name in ("world", "seed", "strategy"):
        add_option(p, spec_of(PlacerConfig, name))
    p.add_argument("--size", default="1280x720", help="image size of the cameras, WxH px")
    p.add_argument("--weights", default="", help="detector checkpoint (default: the shipped weights)")
    add_option(p, spec_of(DetectorConfig, "device"))
    add_option(p, spec_of(DetectorConfig, "scale"), "--detect-scale", note="the checkpoint's rule serves the shipped "
               "weights at 1.7 x the cameras' long side; 1.0: native resolution")
    add_option(p, spec_of(DetectorConfig, "amp"), "--detect-amp")
    add_option(p, spec_of(DetectorConfig, "verifier"))
    p.add_argument("--out", default="out/up", help="folder for the bag, logs, summary.json, preview.jpg, "
                   "zebra_sim.rviz and, with --locate, census.geojson")
    p.add_argument("--config", default="", help="folder of the parameter files (default: the installed config/)")
    p.add_argument("--domain-id", type=int, default=None, help="ROS_DOMAIN_ID for the graph (default: inherited)")
    p.add_argument("--namespace", default="", help="run the whole graph in this namespace (e.g. /g1): every topic "
                   "moves under it, and /tf, /tf_static and /clock become <namespace>/tf, ... (default: the root)")
    p.add_argument("--ready-timeout", type=float, default=180.0, help="longest wait for the nodes to be ready, s")
    p.add_argument("--step-timeout", type=float, default=120.0, help="longest wait for one step, s")
    p.add_argument("--bag-images", default="raw", help="the cameras' images in the bag: raw, or jpeg or png (each "
                   "camera also publishes image_raw/compressed, recorded instead of image_raw; the detector's "
                   "annotated copy, detections/image, is left out): jpeg 90 is about 5%% of a raw frame (default raw)")
    p.add_argument("--no-record", action="store_true", help="run without the recorder (no bag; the scores are the "
                   "scorer node's)")
    p.add_argument("--no-score", action="store_true", help="run without the scorer node (its live figures on "
                   "/diagnostics); the bag is still scored at the end")
    p.add_argument("--set", action="append", default=[], metavar="NODE.NAME=VALUE",
                   help="set a node's parameter for this run over its file (a YAML value; repeatable), e.g. --set "
                        "placer.fix_sigma_m=2.5 --set locator.pose=camera/pose_nav; camera.NAME sets every camera's; "
                        "a parameter up sets itself is refused")
    p.add_argument("--locate", action="store_true", help="also run the locator node: each drone's detections placed "
                   "on the map (<drone>/detections/located, Detection3DArray in map) and each step's zebras counted "
                   "once across the drones (census/animals), scored at the end against the placed and the labelled "
                   "zebras")
    add_json_flag(p)
    p.set_defaults(func=cmd_up)


class _Stop(Exception):
    """SIGTERM to the supervisor: stop like Ctrl-C."""


def _located(specs: Sequence[NodeSpec]) -> LocatorConfig | None:
    """The settings the graph's locator starts with, as the graph read them (None: a graph without it)."""
    from zebra_sim_ros.detection.config import LocatorConfig

    return next((s.config for s in specs if isinstance(s.config, LocatorConfig)), None)


def _rviz_view(cfg: UpConfig, conf: Path, located: LocatorConfig | None,
               cameras: Sequence[tuple[str, CameraConfig]]) -> dict[str, Any] | None:
    """The package's RViz view drawn for this graph's drones and namespace, its census display on the census this
    graph's locator publishes (``located``; off without one), a point cloud display per camera of ``cameras``
    (:func:`~zebra_sim_ros.graph.spec.graph_cameras`) that publishes its points; None, with a warning, where it
    cannot be drawn (no reason to stop the run)."""
    from zebra_sim_ros.graph.rviz import rviz_view
    from zebra_sim_ros.graph.spec import cloud_topics, rviz_census

    try:
        return rviz_view(conf, cfg.drone_names, cfg.namespace, *rviz_census(located), clouds=cloud_topics(cameras))
    except ValueError as exc:
        print(f"[up] warning: no RViz view for this graph ({exc})", flush=True)
        return None


def cmd_up(args: argparse.Namespace) -> Summary:
    """Run the graph; returns the summary (``exit_code`` 0, 1 when a node died, 130 when interrupted)."""
    from zebra_sim_ros.detection.config import ScorerConfig
    from zebra_sim_ros.graph.rviz import RVIZ_FILE, rviz_command, write_rviz
    from zebra_sim_ros.graph.spec import config_dir
    from zebra_sim_ros.zebra.asset import load_library

    cfg, specs = _up_config(args)
    from zebra_sim_ros.graph.spec import aim_warning, graph_cameras

    cameras = graph_cameras(specs)
    if warning := aim_warning(cameras):
        print(f"[up] warning: {warning}", flush=True)
    if not cfg.record and not cfg.score:
        print("[up] --no-record --no-score: the run is neither recorded nor scored (no figures at the end)", flush=True)
    detect_imgsz = cfg.detect_imgsz  # reads the checkpoint's serving rule: an unreadable file stops here
    conf = config_dir(cfg.config_dir)
    scorer = next((s.config for s in specs if s.executable == "scorer"), None)  # read by the graph for its topics
    scoring = ScorerRun.of(scorer) if isinstance(scorer, ScorerConfig) else None
    located = _located(specs)  # its topics, for the summary and the RViz view
    view = _rviz_view(cfg, conf, located, cameras)
    out = Path(cfg.out)
    out.mkdir(parents=True, exist_ok=True)
    for old in (*cfg.bag_files(), out / "summary.json", out / "preview.jpg", out / RVIZ_FILE, out / CENSUS_MAP):
        old.unlink(missing_ok=True)
    env = _graph_environment(conf, args.domain_id)
    load_library()  # build the zebra cache once here, not in every node at the same time
    result: dict[str, Any] = {"out": str(out), "config": str(conf), "frames_asked": cfg.frames, "exit_code": 0,
                              "detect_imgsz": detect_imgsz, "sets": [f"{e}.{n}={v}" for e, n, v in cfg.sets]}
    if view is not None:
        try:
            result["rviz"] = str(write_rviz(view, out / RVIZ_FILE))
            print(f"[up] to watch it: {rviz_command(out / RVIZ_FILE, cfg.namespace)}", flush=True)
        except OSError as exc:  # a full disk: the run goes on without its view
            print(f"[up] warning: cannot write {out / RVIZ_FILE}: {exc.strerror or exc}", flush=True)
    t_start = time.monotonic()
    _run_graph(cfg, specs, conf, env, args.domain_id, result, t_start, scoring)
    result["wall_s"] = round(time.monotonic() - t_start, 2)
    recorder_log = out / "logs" / (next((s.label for s in specs if s.executable == "recorder"), "recorder")
                                   .replace("/", "_") + ".log")
    result.update(_recorder_report(recorder_log))
    if cfg.record and (bag := cfg.bag_files()):
        from zebra_sim_ros.detection.scoring import COUNT_CONF
        from zebra_sim_ros.graph.summary import summarize_run

        count_conf = scoring.count_conf if scoring is not None else COUNT_CONF  # as the scorer counts them live
        # split (by size, duration or the recorder's ~/split_bagfile): every piece, in the order written
        recorded: list[str | Path] = list(bag)
        try:
            result.update(summarize_run(recorded, out / "preview.jpg", count_conf, out / CENSUS_MAP, located))
        except OSError as exc:  # a full disk: the scores still come, the preview does not
            result.update(summarize_run(recorded, None, count_conf, out / CENSUS_MAP, located))
            result["preview_error"] = f"{exc.strerror or exc}: {out / 'preview.jpg'}"
        _print_summary(result, cfg.drone_names)
    if (live := result.get("live_scores")) and "all" in live:
        a = live["all"]
        print(f"[up] the scorer node, live over its last {live['frames']} frames"
              f"{'' if live['complete'] else ' (not every frame of the run: its window, or a report missed)'}: "
              f"P {a['precision']:.3f} "
              f"R {a['recall']:.3f} mAP50 {a['mAP50']:.3f} mAP50-95 {a['mAP50-95']:.3f}"
              + (f"; counted {c['counted']} for {c['true']} zebras"
                 if (c := a.get("count", {})).keys() >= {"counted", "true"} else ""), flush=True)
    if result.get("recording_error"):
        result["exit_code"] = result["exit_code"] or 1
    try:
        with open(out / "summary.json", "w") as f:
            json.dump(result, f, indent=1, sort_keys=True)
        print(f"[up] summary: {out / 'summary.json'}", flush=True)
    except OSError as exc:
        result["summary_error"] = f"cannot write {out / 'summary.json'}: {exc.strerror or exc}"
        result["exit_code"] = result["exit_code"] or 1
    if result.get("recording_error"):  # the last line says what went wrong, once
        kept = f" (the bag is finalised with the {result['recorded_messages']} messages written)" \
            if "recorded_messages" in result else ""
        print(f"[up] error: the recording stopped early: {result['recording_error']}{kept}", flush=True)
    elif result.get("summary_error"):
        print(f"[up] error: {result['summary_error']}", flush=True)
    return result


def _recorder_report(log: Path) -> dict[str, Any]:
    """What the recorder said of its bag: the messages it wrote (its last line) and why it stopped early, if it did."""
    try:
        text = log.read_text(errors="replace")
    except OSError:
        return {}
    out: dict[str, Any] = {}
    if m := re.findall(r"\[recorder\] bag .*?: (\d+) messages, (\d+) dropped", text):
        out["recorded_messages"], out["recorder_dropped"] = int(m[-1][0]), int(m[-1][1])
    if m := re.findall(r"recording ended: (.*)", text):
        out["recording_error"] = m[-1].strip()
    return out


def parse_sets(items: Sequence[str]) -> tuple[tuple[str, str, Any], ...]:
    """``--set NODE.NAME=VALUE`` items as (node's executable, parameter, YAML value); a malformed one is named."""
    out = []
    for item in items:
        key, value = parse_set(item, "placer.fix_sigma_m=2.5 (NODE.NAME=VALUE)")
        node, dot, name = key.partition(".")
        if not (dot and node and name.strip()):
            raise ParameterError("--set", item, "NODE.NAME=VALUE, e.g. placer.fix_sigma_m=2.5")
        out.append((node, name.strip(), value))
    return tuple(out)


def _up_config(args: argparse.Namespace) -> tuple[UpConfig, list[NodeSpec]]:
    """The run's :class:`~zebra_sim_ros.graph.spec.UpConfig` from the options, checked (``ParameterError``), and its
    graph's nodes."""
    from zebra_sim_ros.graph.spec import UpConfig

    w, h = parse_size(args.size)
    cfg = UpConfig(frames=args.frames, drones=args.drones, world=args.world, seed=args.seed, out=args.out, width=w,
                   height=h, weights=args.weights, device=args.device, detect_scale=args.scale, detect_amp=args.amp,
                   strategy=args.strategy, config_dir=args.config, ready_timeout_s=args.ready_timeout,
                   step_timeout_s=args.step_timeout, record=not args.no_record, score=not args.no_score,
                   namespace=args.namespace, verifier=args.verifier, bag_images=args.bag_images, locate=args.locate,
                   sets=parse_sets(args.set))
    specs = cfg.check()
    if args.domain_id is not None and not 0 <= args.domain_id <= 232:
        raise ParameterError("--domain-id", args.domain_id, "0..232 (ROS_DOMAIN_ID)")
    if args.weights and not Path(args.weights).is_file():
        raise ParameterError("--weights", args.weights, "an existing checkpoint file")
    return cfg, specs


def _graph_environment(conf: Path, domain_id: int | None) -> dict[str, str]:
    """The nodes' environment: ours with the config's DDS profile and ``domain_id`` (None: inherited), and
    :data:`~zebra_sim_ros.graph.spec.NODE_ENVIRONMENT` where the caller set none of it."""
    from zebra_sim_ros.graph.spec import NODE_ENVIRONMENT, dds_environment

    env = dds_environment(conf, NODE_ENVIRONMENT | dict(os.environ, PYTHONUNBUFFERED="1", RCUTILS_COLORIZED_OUTPUT="0"))
    if env.get("FASTRTPS_DEFAULT_PROFILES_FILE"):  # the watcher's participant reads it from this process's env
        os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"] = env["FASTRTPS_DEFAULT_PROFILES_FILE"]
    if domain_id is not None:
        env["ROS_DOMAIN_ID"] = str(domain_id)
    return env


def _run_graph(cfg: UpConfig, specs: list[NodeSpec], conf: Path, env: dict[str, str], domain_id: int | None,
               result: dict[str, Any], t_start: float, scoring: ScorerRun | None) -> None:
    """Start the nodes, wait until ready, run the placer's steps and stop the graph (recorder last).

    The placer is the last of ``specs``. How it ended goes into ``result`` (``exit_code``, ``died``, ``error``,
    ``exit_status``, ``ready_s``, and the scorer's last figures as ``live_scores``: ``scoring`` is the scorer's
    settings, None when the graph has none); SIGTERM stops it like Ctrl-C.
    """
    from zebra_sim_ros.graph.spec import command
    from zebra_sim_ros.graph.supervisor import NodeDied, Supervisor
    from zebra_sim_ros.health import status_name
    from zebra_sim_ros.nodes.graph_watch import GraphWatch

    placer, others = specs[-1], specs[:-1]
    scorer = next((status_name(s.fqn, s.executable) for s in specs if s.executable == "scorer"), None)
    out = Path(cfg.out)

    def on_term(signum: int, frame: Any) -> None:
        raise _Stop()

    old_term = signal.signal(signal.SIGTERM, on_term)
    sup = Supervisor(out / "logs", env)
    try:
        # domain_id None: rclpy reads ROS_DOMAIN_ID as the nodes do
        statuses = [status_name(s.fqn, s.executable) for s in specs]
        with GraphWatch(placer.overrides["lockstep_ack_from"], domain_id, cfg.namespace, statuses) as watch:
            try:
                result["ready_s"] = _start_and_wait(sup, watch, others, conf, cfg, t_start)
                print(f"[up] {len(others)} nodes ready in {result['ready_s']:.1f} s; placer starts "
                      f"{cfg.frames} steps of '{cfg.world}' (seed {cfg.seed}) in lockstep", flush=True)
                _run_steps(sup, watch, sup.start(placer, command(placer, conf), expected_exit=True), cfg)
                if scorer is not None and scoring is not None:
                    _await_scores(sup, watch, scorer, scoring, watch.steps_done())
            except NodeDied as exc:
                print(f"\n[up] {exc}\n[up] stopping the other nodes", flush=True)
                result.update(exit_code=1, died=exc.child.label, died_status=exc.code)
            except TimeoutError as exc:
                print(f"\n[up] {exc}; stopping the graph", flush=True)
                result.update(exit_code=1, error=str(exc))
            except (KeyboardInterrupt, _Stop):
                print("\n[up] interrupted: stopping the graph", flush=True)
                result["exit_code"] = 130
            finally:
                codes = sup.stop([c for c in sup.children if c.spec.executable != "recorder"])  # recorder last
                result["health"] = watch.health
                if scorer is not None and scoring is not None and scorer in watch.values:
                    result["live_scores"] = _live_scores(watch.values[scorer], scoring, watch.steps_done())
                result["exit_status"] = codes
                bad = {k: v for k, v in codes.items() if v not in (0, None) and k != result.get("died")}
                if bad:
                    print(f"[up] nodes that did not stop cleanly (exit status): {bad}", flush=True)
    finally:
        signal.signal(signal.SIGTERM, old_term)


def _start_and_wait(sup: Supervisor, watch: GraphWatch, others: list[NodeSpec], conf: Path, cfg: UpConfig,
                    t_start: float) -> float:
    """Start every node but the placer and wait until their topics are up (and recorded); seconds it took."""
    from zebra_sim_ros.graph.spec import command

    out = Path(cfg.out)
    for s in others:
        sup.start(s, command(s, conf))
    print(f"[up] started {', '.join(s.label for s in others)}; logs in {out / 'logs'}", flush=True)
    topics = [t for s in others for t in s.publishes]
    readers = {s.name: s.subscribes for s in others if s.subscribes}
    while missing := watch.missing(topics, readers):
        sup.check()
        if time.monotonic() - t_start > cfg.ready_timeout_s:
            raise TimeoutError(f"the graph was not ready after {cfg.ready_timeout_s:.0f} s: missing "
                               f"{missing[:6]}{' ...' if len(missing) > 6 else ''}")
        watch.spin(0.25)
    return round(time.monotonic() - t_start, 2)


def _run_steps(sup: Supervisor, watch: GraphWatch, pl: Child, cfg: UpConfig) -> None:
    """Follow the placer's lockstep steps until it exits, printing progress; TimeoutError when a step stalls."""
    last, done, t_steps = time.monotonic(), 0, time.monotonic()
    cr, end = ("\r", "") if sys.stdout.isatty() else ("", "\n")
    lead = "\n" if cr else ""  # off the progress line
    while pl.proc.poll() is None:
        sup.check()
        watch.spin(0.2)
        for name, level, message in watch.take_changes():  # a node warns, fails or is well again
            print(f"{lead}[up] {name}: {level.name} {message}", flush=True)
        if (now_done := watch.steps_done()) != done:
            done, last = now_done, time.monotonic()
            rate = done / (last - t_steps)
            print(f"{cr}[up] step {done}/{cfg.frames} ({rate:.2f} steps/s)", end=end, flush=True)
        elif time.monotonic() - last > cfg.step_timeout_s + 10.0:
            raise TimeoutError(f"no step finished for {cfg.step_timeout_s + 10:.0f} s (at step {done}); "
                               f"see the logs in {Path(cfg.out) / 'logs'}")
    sup.check()  # the placer ended: with status 0 only after its last step
    if cr:
        print("", flush=True)
    watch.spin(1.0)  # the recorder receives the last detections


@dataclass(frozen=True)
class ScorerRun:
    """The graph's scorer as ``up`` waits for it: each of its ``drones`` cameras' last ``window`` frames scored, a
    report every ``period_s``. Read from its parameter file with up's overrides, validated as the node validates
    them."""

    window: int
    period_s: float
    drones: int
    count_conf: float  # the zebras counted at it (the bag's summary counts at it too)

    @staticmethod
    def read(conf: Path, spec: NodeSpec) -> ScorerRun:
        """The settings of the graph's scorer ``spec`` (its name, parameter file and overrides, as ``up`` starts it)
        with the parameter files in ``conf`` (``ParameterError`` naming a bad value)."""
        from zebra_sim_ros.detection.config import ScorerConfig
        from zebra_sim_ros.graph.spec import node_config

        return ScorerRun.of(node_config(conf, spec.params_file, spec.fqn, spec.overrides, ScorerConfig))

    @staticmethod
    def of(sc: ScorerConfig) -> ScorerRun:
        """The run's view of the scorer's settings ``sc``."""
        return ScorerRun(sc.window, sc.diagnostics_period_s, len(sc.drones), sc.count_conf)

    def expected(self, steps: int) -> int:
        """The frames its report holds after ``steps`` steps: the last ``window`` steps' frames of every camera."""
        return min(steps, self.window) * self.drones

    def whole(self, steps: int) -> bool:
        """Whether that report holds every frame of a run of ``steps`` steps."""
        return steps <= self.window

    @property
    def wait_s(self) -> float:
        """How long its report may take after the last step: two of its periods and a second, 10 s at least."""
        return max(10.0, 2 * self.period_s + 1.0)


def _await_scores(sup: Supervisor, watch: GraphWatch, scorer: str, run: ScorerRun, steps: int) -> None:
    """Wait until the scorer reports the frames it should have scored after ``steps`` steps (each with its labels
    and detections), at most ``run.wait_s``."""
    end = time.monotonic() + run.wait_s
    while time.monotonic() < end:
        if int(watch.values.get(scorer, {}).get("frames scored", -1)) == run.expected(steps):
            return
        sup.check()
        watch.spin(0.1)


def _live_scores(values: dict[str, str], run: ScorerRun, steps: int) -> dict[str, Any]:
    """The scorer's last report after ``steps`` steps as numbers: ``frames`` scored, ``complete`` (they are every
    frame of the run: it was no longer than the scorer's window, and each camera's every step was scored), and per
    key (``all``, ``drone_0``, ...) mAP50, mAP50-95, precision, recall, and the count (``count``: ``counted``,
    ``true``, ``mae``)."""
    frames = int(values.get("frames scored", 0))
    expected = run.expected(steps)
    out: dict[str, Any] = {"frames": frames, "complete": run.whole(steps) and expected > 0 and frames == expected}
    for key, value in values.items():
        who, _, name = key.partition(" ")
        if name in ("mAP50", "mAP50-95", "precision", "recall"):
            out.setdefault(who, {})[name] = float(value)
        elif name == "count" and (m := re.fullmatch(r"(\d+)/(\d+)", value)):
            out.setdefault(who, {}).setdefault("count", {}).update(counted=int(m[1]), true=int(m[2]))
        elif name == "count MAE":
            out.setdefault(who, {}).setdefault("count", {})["mae"] = float(value)
    return out


def _print_summary(r: dict[str, Any], drones: tuple[str, ...]) -> None:
    from zebra_sim_ros.placement.config import CAMERA_POSE

    for d in drones:
        f = r["frames"].get(d, {})
        print(f"[up] {d}: {f.get('image_raw', 0)} images, {f.get('labels', 0)} labelled, "
              f"{f.get('detections', 0)} detected", flush=True)
    a = r["scores"].get("all")
    if a:
        print(f"[up] detector at imgsz {r['detect_imgsz']} against the live ground truth (all drones, "
              f"{a['images']} images, {a['instances']} zebras): P {a['precision']:.3f} R {a['recall']:.3f} "
              f"mAP50 {a['mAP50']:.3f} mAP50-95 {a['mAP50-95']:.3f}", flush=True)
        from zebra_sim_ros.detection.metrics import count_line

        print(f"[up] {count_line(a['count'])}", flush=True)
    if loc := r.get("located"):
        where = ""
        if loc["median_m"] is not None:  # the 90th percentile may be past every placed zebra (a step without any)
            p90 = f"{loc['p90_m']:.2f} m" if loc["p90_m"] is not None else "none placed near"
            where = (f", {loc['median_m']:.2f} m from the nearest placed zebra (median; 90th percentile {p90}), "
                     f"{loc['within_1_m']:.0%} within 1 m")
        elif not loc["frames_with_placed"]:
            where = " (no placed zebras in the bag to compare with: zebra_sim/zebras not recorded)"
        pose = loc.get("pose", CAMERA_POSE)  # a run placed from the drones' navigation says so
        print(f"[up] locator: {loc['detections']} zebra detections placed on the map in {loc['frames']} frames"
              f"{where}{f' (from <drone>/{pose})' if pose != CAMERA_POSE else ''}", flush=True)
    if cen := r.get("census"):
        from zebra_sim_ros.recording.census import census_line

        print(f"[up] census: {census_line(cen)}", flush=True)
    if geo := r.get("census_geojson"):
        print(f"[up] census on the Earth: {geo} (GeoJSON, WGS84, by the scenes' datum; for a GIS)", flush=True)
    elif r.get("census_geojson_error"):
        print(f"[up] warning: no census GeoJSON: {r['census_geojson_error']}", flush=True)
    ms = r["median_ms"]
    if r.get("steps_per_s"):
        print(f"[up] throughput: {r['steps']} steps in {r['seconds']:.1f} s = {r['steps_per_s']:.2f} steps/s, "
              f"{r['frames_per_s']:.2f} frames/s; median per step: render {ms['render']} ms, label {ms['label']} ms,"
              f" detect {ms['detect']} ms, scene to detections {ms['end_to_end']} ms", flush=True)
    more = r.get("bags", [])[1:]  # a split recording's later pieces
    print(f"[up] bag: {r['bag']}" + (f" and {len(more)} more piece(s) of it, the last {more[-1]}" if more else ""),
          flush=True)
    if "preview" in r:
        print(f"[up] preview (green: ground truth, red: detected): {r['preview']}", flush=True)
    for note in r["damaged"]:
        print(f"[up] bag damage: {note}", flush=True)
    if r["skipped"]:
        print(f"[up] skipped {len(r['skipped'])} unusable message(s) in the bag, first: {r['skipped'][0]}",
              flush=True)
