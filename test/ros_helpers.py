"""Helpers for integration tests: real node processes over real DDS, on a private ROS domain.

Every test gets its own ``ROS_DOMAIN_ID`` (from the pytest process id and a counter), processes run in
their own process group with a timeout, and are always killed at the end, even when a test fails.
"""

from __future__ import annotations

import itertools
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

_counter = itertools.count()


def fresh_domain_id() -> int:
    """A ROS domain id no other test of this run uses (and unlikely to clash with another run)."""
    return 100 + (os.getpid() * 7 + next(_counter)) % 120


def ros_env(domain: int) -> dict[str, str]:
    """Environment for a node process on ``domain``, localhost only."""
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(domain)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["PYTHONUNBUFFERED"] = "1"
    env.setdefault("RCUTILS_COLORIZED_OUTPUT", "0")
    return env


def param_args(params: dict[str, Any]) -> list[str]:
    """``--ros-args -p name:=value ...`` with YAML-formatted values."""
    from zebra_sim_ros.graph.spec import ros_value

    out = ["--ros-args"]
    for k, v in params.items():
        out += ["-p", f"{k}:={ros_value(v)}"]
    return out


def run_node_once(executable: str, params: dict[str, Any], domain: int | None = None,
                  timeout: float = 60) -> subprocess.CompletedProcess[str]:
    """Run a node with ``params`` to its end (a node that refuses its parameters exits at once)."""
    return subprocess.run([sys.executable, "-m", f"zebra_sim_ros.nodes.{executable}", *param_args(params)],
                          env=ros_env(fresh_domain_id() if domain is None else domain), capture_output=True,
                          text=True, timeout=timeout)


@contextmanager
def node_process(module: str, params: dict[str, Any], domain: int, log: Path,
                 ns: str | None = None, name: str | None = None) -> Iterator[subprocess.Popen[bytes]]:
    """Run ``python -m zebra_sim_ros.nodes.<module>`` with parameters (and a namespace, a node name); always killed
    at the end, and by the parent-death signal when the test process itself is killed outright."""
    from zebra_sim_ros.graph.supervisor import child_setup

    args = param_args(params) + (["-r", f"__ns:={ns}"] if ns else []) + (["-r", f"__node:={name}"] if name else [])
    with open(log, "wb") as out:
        proc = subprocess.Popen([sys.executable, "-m", f"zebra_sim_ros.nodes.{module}", *args],
                                env=ros_env(domain), stdout=out, stderr=subprocess.STDOUT, start_new_session=True,
                                preexec_fn=child_setup)
        try:
            yield proc
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGINT)
                try:
                    proc.wait(timeout=5)
                except subprocess.TimeoutExpired:
                    os.killpg(proc.pid, signal.SIGKILL)
                    proc.wait(timeout=5)


def spin_until(node: Any, executor: Any, cond: Callable[[], bool], timeout: float) -> bool:
    """Spin ``executor`` until ``cond()`` or ``timeout`` seconds; returns ``cond()``."""
    end = time.monotonic() + timeout
    while time.monotonic() < end and not cond():
        executor.spin_once(timeout_sec=0.05)
    return cond()


class Peer:
    """The test's own node on a private domain, with its own context and executor; ``close()`` always."""

    def __init__(self, domain: int, name: str = "test_peer") -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx, domain_id=domain)
        self.node = rclpy.create_node(name, context=self.ctx)
        self.ex = SingleThreadedExecutor(context=self.ctx)
        self.ex.add_node(self.node)

    def spin(self, cond: Callable[[], bool], timeout: float) -> bool:
        """Spin until ``cond()`` or ``timeout`` seconds."""
        return spin_until(self.node, self.ex, cond, timeout)

    def close(self) -> None:
        import rclpy

        self.ex.shutdown()
        self.node.destroy_node()
        rclpy.shutdown(context=self.ctx)


def call_service(peer: Peer, srv_type: Any, name: str, request: Any, timeout: float = 30.0) -> Any:
    """Call service ``name`` from ``peer`` (waiting for it up to ``timeout``) and return its answer."""
    client = peer.node.create_client(srv_type, name)
    try:
        assert client.wait_for_service(timeout_sec=timeout), f"no service {name}"
        future = client.call_async(request)
        assert peer.spin(future.done, timeout), f"no answer from {name}"
        return future.result()
    finally:
        peer.node.destroy_client(client)


def set_parameter(peer: Peer, node: str, name: str, value: Any) -> Any:
    """Set parameter ``name`` of ``node`` (``/replay``, say) through its set_parameters service; returns the
    SetParametersResult. ``value``'s Python type gives the parameter type (a float for a double)."""
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter

    request = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
    return call_service(peer, SetParameters, f"{node}/set_parameters", request).results[0]


def detection_array_class() -> Any:
    """The Detection2DArray class the detector publishes (vision_msgs where installed, else zebra_sim_msgs)."""
    from zebra_sim_ros.nodes.ros_adapter import detection_array_type, message_class

    return message_class(detection_array_type())


def detections_dict(msg: Any) -> dict[str, Any]:
    """A Detection2DArray as {stamp, frame_id, detections: [{box_xyxy, score, class_name, id}]} for assertions."""
    out = []
    for d in msg.detections:
        cx, cy, w, h = d.bbox.center.position.x, d.bbox.center.position.y, d.bbox.size_x, d.bbox.size_y
        hyp = d.results[0].hypothesis
        out.append({"box_xyxy": [cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2], "score": hyp.score,
                    "class_name": hyp.class_id, "id": d.id, "frame_id": d.header.frame_id})
    return {"stamp": {"sec": msg.header.stamp.sec, "nanosec": msg.header.stamp.nanosec},
            "frame_id": msg.header.frame_id, "detections": out}


def collect_diagnostics(node: Any, name: str) -> list[dict[str, Any]]:
    """Subscribe ``node`` to /diagnostics; the returned list fills, as it spins, with the statuses named ``name``
    (``<node>: <executable>``) as {level (int), message, hardware_id, values (dict)}."""
    from diagnostic_msgs.msg import DiagnosticArray

    got: list[dict[str, Any]] = []

    def on_array(msg: DiagnosticArray) -> None:
        for s in msg.status:
            if s.name == name:
                level = s.level[0] if isinstance(s.level, bytes) else int(s.level)
                got.append({"level": level, "message": s.message, "hardware_id": s.hardware_id,
                            "values": {kv.key: kv.value for kv in s.values}})
    node.create_subscription(DiagnosticArray, "/diagnostics", on_array, 50)
    return got
