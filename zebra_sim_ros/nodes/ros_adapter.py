"""What every node adapter shares: parameter declaration, QoS, stamps and a guarded ``main``.

Only modules under ``zebra_sim_ros.nodes`` import rclpy.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np
import rclpy
from builtin_interfaces.msg import Time
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Image
from std_msgs.msg import Header

from zebra_sim_ros.errors import ZebraSimError
from zebra_sim_ros.params import ParamSpec


def declare_and_read(node: Node, specs: Iterable[ParamSpec]) -> dict[str, Any]:
    """Declare every spec as a parameter (with its description and range) and return the raw values.

    Parameters are dynamically typed so that ``rate_hz: 2`` in YAML is accepted for a float; the
    core's validation then coerces and range-checks every value and names any bad one.
    """
    values: dict[str, Any] = {}
    for s in specs:
        desc = ParameterDescriptor(description=f"{s.description} (allowed: {s.allowed})", dynamic_typing=True)
        node.declare_parameter(s.name, s.default, desc)
        values[s.name] = node.get_parameter(s.name).value
    return values


def message_class(type_name: str) -> Any:
    """The Python class of ``pkg/msg/Type``."""
    pkg, kind, name = type_name.split("/")
    return getattr(importlib.import_module(f"{pkg}.{kind}"), name)


def qos(reliability: str = "reliable", depth: int = 10, transient_local: bool = False) -> QoSProfile:
    """A keep-last QoS profile from parameter values."""
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliability == "reliable" else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if transient_local else DurabilityPolicy.VOLATILE,
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


def stamp(ns: int) -> Time:
    """builtin_interfaces/Time from integer nanoseconds."""
    return Time(sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000))


def stamp_ns(t: Time) -> int:
    """Integer nanoseconds of a builtin_interfaces/Time."""
    return int(t.sec) * 1_000_000_000 + int(t.nanosec)


def help_text(executable: str, doc: str, specs: Iterable[ParamSpec]) -> str:
    """``--help`` text of a node: its docstring and a table of its parameters."""
    lines = [f"usage: ros2 run zebra_sim_ros {executable} [--ros-args -p name:=value ... "
             f"--params-file FILE]", "", doc.strip(), "", "parameters (name, default, meaning, allowed):"]
    for s in specs:
        lines.append(f"  {s.name} = {s.default!r}\n      {s.description}; allowed {s.allowed}")
    return "\n".join(lines)


def run_node(name: str, factory: Callable[[], Any], argv: list[str] | None = None, help: str = "") -> int:
    """Init rclpy, build the node, spin until it is done or interrupted, and shut down.

    ``-h``/``--help`` before ``--ros-args`` prints ``help`` and returns 0 without starting ROS. A
    :class:`ZebraSimError` at start-up (a bad parameter, a missing world) is logged as one line naming the
    problem and gives exit status 2. The node may expose ``done`` (bool) to end the spin by itself.
    """
    args = list(argv if argv is not None else sys.argv)
    own = args[1:args.index("--ros-args")] if "--ros-args" in args else args[1:]
    if "-h" in own or "--help" in own:
        print(help or f"usage: ros2 run zebra_sim_ros {name} [--ros-args ...]")
        return 0
    rclpy.init(args=args)
    node = None
    try:
        try:
            node = factory()
        except ZebraSimError as exc:
            rclpy.logging.get_logger(name).fatal(f"cannot start: {exc}")
            return 2
        while rclpy.ok() and getattr(node, "done", False) is not True:
            rclpy.spin_once(node, timeout_sec=0.1)
        return int(getattr(node, "exit_code", 0))
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    finally:
        if node is not None:
            close = getattr(node, "close", None)
            if callable(close):
                close()
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
