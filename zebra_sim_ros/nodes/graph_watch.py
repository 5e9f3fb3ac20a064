"""A small rclpy observer for ``zebra-sim up``: is every node of the graph ready, and how far are the steps?

Not an executable: the supervisor (``zebra_sim_ros.graph``) stays free of rclpy and asks this observer.
Ready means: every expected topic has a publisher (nodes create their publishers last, after loading
worlds, assets and weights), and the nodes that read them (the recorder, the scorer) subscribe to them.
Progress is read from the acknowledgements on ``zebra_sim/frame_done``; the nodes' health from ``/diagnostics``.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Iterable, Mapping
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import Header

from zebra_sim_ros.health import Level
from zebra_sim_ros.nodes.ros_adapter import ACK_TOPIC, DIAGNOSTICS_TOPIC, qos, stamp_ns


class GraphWatch:
    """Own context, node and executor; call :meth:`close` (or use as a context manager)."""

    def __init__(self, ackers: Iterable[str] = (), domain_id: int | None = None, namespace: str = "",
                 statuses: Iterable[str] = ()) -> None:
        self.context = Context()
        rclpy.init(context=self.context, args=[], domain_id=domain_id,  # Ctrl-C stays the supervisor's
                   signal_handler_options=SignalHandlerOptions.NO)
        self.node = Node("zebra_sim_up", context=self.context, namespace=namespace or None)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.ackers = set(ackers)
        self.acks: dict[int, set[str]] = {}  # scene stamp -> ackers
        self.node.create_subscription(Header, ACK_TOPIC, self._on_ack, qos("reliable", 100))
        self.statuses = set(statuses)  # the /diagnostics status names of this graph's nodes (others are ignored)
        self.health: dict[str, dict[str, Any]] = {}  # name: level and message of the last report; reports by level
        self.values: dict[str, dict[str, str]] = {}  # name: the key-value pairs of its last report
        self.changes: list[tuple[str, Level, str]] = []  # (name, new level, message) since take_changes()
        self.node.create_subscription(DiagnosticArray, DIAGNOSTICS_TOPIC, self._on_diagnostics, qos("reliable", 50))

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for s in msg.status:
            if s.name not in self.statuses:
                continue
            level = Level(s.level[0] if isinstance(s.level, bytes) else int(s.level))
            rec = self.health.setdefault(s.name, {"level": Level.OK.name, "message": "", "reports": {}})
            if level.name != rec["level"]:
                self.changes.append((s.name, level, s.message))
            rec["level"], rec["message"] = level.name, s.message
            rec["reports"][level.name] = rec["reports"].get(level.name, 0) + 1
            self.values[s.name] = {kv.key: kv.value for kv in s.values}

    def take_changes(self) -> list[tuple[str, Level, str]]:
        """The changes of level since the last call: (status name, new level, its message)."""
        out, self.changes = self.changes, []
        return out

    def _on_ack(self, msg: Header) -> None:
        self.acks.setdefault(stamp_ns(msg.stamp), set()).add(msg.frame_id)

    def steps_done(self) -> int:
        """Steps that every acker has acknowledged."""
        return sum(1 for a in self.acks.values() if self.ackers <= a)

    def spin(self, seconds: float) -> None:
        """Process callbacks for about ``seconds``."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=min(0.05, max(end - time.monotonic(), 0.0)))

    def missing(self, topics: Iterable[str], readers: Mapping[str, Iterable[str]] | None = None) -> list[str]:
        """Topics not yet published, then topics a reader (node name: the topics it must subscribe) does not
        subscribe yet although they are published, as readable notes."""
        published = functools.cache(lambda t: bool(self.node.get_publishers_info_by_topic(t)))  # once a topic
        out = [f"{t} (no publisher)" for t in topics if not published(t)]
        for reader, wanted in (readers or {}).items():
            for t in wanted:
                if published(t) and not any(
                        i.node_name == reader for i in self.node.get_subscriptions_info_by_topic(t)):
                    out.append(f"{t} (not subscribed by the {reader} yet)")
        return out

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)

    def __enter__(self) -> GraphWatch:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
