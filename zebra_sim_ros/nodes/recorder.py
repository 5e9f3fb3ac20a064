"""The ``recorder`` node: MCAP bags that ``ros2 bag``, Foxglove and ``rosbags`` read
(``ros2 run zebra_sim_ros recorder``).

Subscribes, as serialized messages (no deserialisation), to the topics in ``topics`` or, with ``topics``
empty, to every topic matching ``topic_regex`` and not ``exclude_regex``, found again every
``discovery_period_s`` (topics that appear later are recorded from then on). Each subscription takes the
QoS its publishers offer (reliable and transient local only if they all are), and the offered profiles go
into the bag as rosbag2's ``offered_qos_profiles``. Callbacks only queue the bytes; one thread writes. A full
queue counts drops per topic; a full disk or ``max_size_mb`` ends the recording with a finalised bag and an
error. SIGINT, SIGTERM and node shutdown finalise the bag (summary and indexes); after SIGKILL use
``zebra-sim bag recover``.
"""

from __future__ import annotations

import re
import time
from typing import Any

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy

from zebra_sim_ros.errors import ParameterError, ZebraSimError
from zebra_sim_ros.nodes.ros_adapter import declare_and_read, describe_qos, help_text, message_class, qos, run_node
from zebra_sim_ros.params import validate
from zebra_sim_ros.recording.config import RECORDER_PARAMS
from zebra_sim_ros.recording.qos import profile_dict, replay_profile
from zebra_sim_ros.recording.recorder import RecorderCore
from zebra_sim_ros.recording.writer import BagWriter


def _profile_of(info: Any) -> dict[str, Any]:
    q = info.qos_profile
    return profile_dict("keep_last" if q.history != HistoryPolicy.KEEP_ALL else "keep_all", int(q.depth),
                        "reliable" if q.reliability == ReliabilityPolicy.RELIABLE else "best_effort",
                        "transient_local" if q.durability == DurabilityPolicy.TRANSIENT_LOCAL else "volatile")


class RecorderNode(Node):
    """Thin adapter around :class:`zebra_sim_ros.recording.recorder.RecorderCore`."""

    def __init__(self) -> None:
        super().__init__("recorder")
        v = validate(RECORDER_PARAMS, declare_and_read(self, RECORDER_PARAMS))
        self.topics = [t for t in v["topics"] if t]
        self.include, self.exclude = re.compile(v["topic_regex"]), re.compile(v["exclude_regex"])  # checked
        mb = 1 << 20
        least = 2 * v["chunk_size_mb"] + 0.016  # the writer keeps two chunks and the summary in reserve
        if 0 < v["max_size_mb"] < least:
            raise ParameterError("max_size_mb", v["max_size_mb"], f"0 or more than {least:.3f} (2 x chunk_size_mb "
                                 "+ 16 KiB for the summary)")
        self.writer = BagWriter(v["output"], v["compression"], int(v["chunk_size_mb"] * mb),
                                int(v["split_size_mb"] * mb), v["split_duration_s"], int(v["max_size_mb"] * mb))
        self.core = RecorderCore(self.writer, v["queue_size"])
        self.depth = v["qos_depth"]
        self.subs: dict[str, Any] = {}
        self.done = False
        self.exit_code = 0
        self.create_timer(v["discovery_period_s"], self._discover)
        if v["stats_period_s"] > 0:
            self.create_timer(v["stats_period_s"], self._log_stats)
        self.create_timer(0.2, self._check_error)
        self.get_logger().info(
            f"recording to {self.writer.path} ({v['compression']}, chunks {v['chunk_size_mb']} MB, split "
            f"{v['split_size_mb']} MB / {v['split_duration_s']} s, cap {v['max_size_mb']} MB); "
            f"topics {self.topics or 'matching ' + v['topic_regex']}")
        self._discover()

    def _wanted(self, topic: str) -> bool:
        if self.topics:
            return topic in self.topics
        return bool(self.include.search(topic)) and not self.exclude.search(topic)

    def _discover(self) -> None:
        for topic, types in self.get_topic_names_and_types():
            if topic in self.subs or not self._wanted(topic) or not types:
                continue
            infos = self.get_publishers_info_by_topic(topic)
            if not infos:
                continue
            type_name = types[0]
            try:
                cls = message_class(type_name)
                profiles = [_profile_of(i) for i in infos]
                self.writer.add_channel(topic, type_name, profiles)
            except (ImportError, AttributeError, ValueError, ZebraSimError) as exc:
                self.get_logger().error(f"cannot record {topic} ({type_name}): {exc}")
                self.subs[topic] = None
                continue
            p = replay_profile(profiles)  # reliable and transient local only if every publisher is
            q = qos(p["reliability"], self.depth, p["durability"] == "transient_local")
            self.subs[topic] = self.create_subscription(cls, topic, self._callback(topic), q, raw=True)
            self.get_logger().info(f"recording {topic} ({type_name}), QoS {describe_qos(q)}")

    def _callback(self, topic: str) -> Any:
        offer, clock = self.core.offer, self.get_clock()

        def on_message(data: bytes) -> None:
            offer(topic, data, clock.now().nanoseconds)
        return on_message

    def _log_stats(self) -> None:
        t = self.core.totals()
        self.get_logger().info(f"{t['messages']} messages written, {t['dropped']} dropped, {t['mb_per_s']} MB/s, "
                               f"queue {t['queue']}; per topic {t['topics']}")

    def _check_error(self) -> None:
        if self.core.error is not None and not self.done:
            self.get_logger().error(f"recording ended: {self.core.error}")
            self.done, self.exit_code = True, 1

    def close(self) -> None:
        """Finalise the bag and print the statistics."""
        t0 = time.perf_counter()
        files = self.core.close()
        t = self.core.totals()
        msg = (f"bag {files}: {t['messages']} messages, {t['dropped']} dropped; per topic {t['topics']}; "
               f"writer {t['write_mb_per_s']} MB/s while writing; finalised in {time.perf_counter() - t0:.2f} s")
        print(f"[recorder] {msg}" + (f"; error: {self.core.error}" if self.core.error else ""), flush=True)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ros2 run zebra_sim_ros recorder``; returns the exit status."""
    return run_node("recorder", RecorderNode, argv, help_text("recorder", __doc__ or "", RECORDER_PARAMS))


if __name__ == "__main__":
    raise SystemExit(main())
