"""The ``replay`` node: plays MCAP bags back as recorded (``ros2 run zebra_sim_ros replay``).

Publishes every message as recorded (raw CDR, no deserialisation) on its topic (plus ``remap_prefix``), with
the QoS its publishers offered when recorded (reliable and transient local only if they all were), keeping the
recorded spacing of log times divided by ``rate``. ``start_offset_s`` and ``duration_s`` select a window,
``topics``/``topic_regex`` select topics, ``loop`` plays again, ``clock`` publishes ``/clock`` with the bag's time
for ``use_sim_time`` consumers. A truncated or corrupt bag plays everything intact, then the node logs where and
why it stopped. The node exits when done (unless looping).
"""

from __future__ import annotations

import re
import threading
import time
from typing import Any

import yaml
from rclpy.node import Node
from rosgraph_msgs.msg import Clock

from zebra_sim_ros.nodes.ros_adapter import (
    declare_and_read,
    flush,
    help_text,
    message_class,
    qos,
    run_node,
    stamp,
)
from zebra_sim_ros.params import validate
from zebra_sim_ros.recording.config import REPLAY_PARAMS
from zebra_sim_ros.recording.qos import from_yaml, replay_profile
from zebra_sim_ros.recording.reader import BagReader


class ReplayNode(Node):
    """Plays bags from a thread of its own; the executor only serves the graph."""

    def __init__(self) -> None:
        super().__init__("replay")
        v = validate(REPLAY_PARAMS, declare_and_read(self, REPLAY_PARAMS))
        self.v = v
        self.bags = [b for b in v["bags"] if b]
        self.reader = BagReader.open(self.bags, name="bags")  # missing files stop the node here, naming them
        self.regex = re.compile(v["topic_regex"])  # checked by its ParamSpec
        self.topics = {t for t in v["topics"] if t}
        self.pubs: dict[str, Any] = {}
        self.clock_pub = self.create_publisher(Clock, "/clock", 10) if v["clock"] else None
        self.done = False
        self.exit_code = 0
        self.published = 0
        for topic, type_name, metadata in self.reader.channel_list():  # publishers up front: subscribers match
            self._publisher(topic, type_name, metadata)                    # before the first message is played
        self.get_logger().info(f"playing {[str(p) for p in self.reader.paths]} at rate {v['rate']}, "
                               f"offset {v['start_offset_s']} s, duration {v['duration_s'] or 'all'}, "
                               f"loop {v['loop']}, clock {v['clock']}, remap prefix '{v['remap_prefix']}'")
        self.thread = threading.Thread(target=self._play_all, name="replay", daemon=True)
        self.thread.start()

    def _wanted(self, topic: str) -> bool:
        return (not self.topics or topic in self.topics) and bool(self.regex.search(topic))

    def _publisher(self, topic: str, type_name: str, metadata: dict[str, str]) -> Any:
        """The topic's publisher with its recorded QoS, made once; None for a topic not played or not playable
        (type not installed, no schema, unreadable QoS metadata: logged once, and the rest of the bag plays)."""
        if topic in self.pubs:
            return self.pubs[topic]
        pub = None
        if self._wanted(topic):
            try:
                p = replay_profile(from_yaml(metadata.get("offered_qos_profiles", "")))
                q = qos(p["reliability"], int(p["depth"]), p["durability"] == "transient_local")
                pub = self.create_publisher(message_class(type_name), self.v["remap_prefix"] + topic, q)
            except (ImportError, AttributeError, ValueError, yaml.YAMLError) as exc:
                self.get_logger().error(f"cannot play {topic} ({type_name or 'no schema'}): {exc}; skipping it")
        self.pubs[topic] = pub
        return pub

    def _play_all(self) -> None:
        try:
            while True:
                self._play_once()
                if not self.v["loop"] or self.done:
                    break
                self.reader = BagReader.open(self.bags)
        except Exception as exc:  # noqa: BLE001 - reported, and the node ends with an error status
            self.get_logger().error(f"replay failed: {type(exc).__name__}: {exc}")
            self.exit_code = 1
        finally:
            self.done = True

    def _play_once(self) -> None:
        v = self.v
        wait_until = time.monotonic() + v["wait_for_subscribers_s"]
        t0_bag: int | None = None
        start_wall = 0.0
        offset_bag = 0.0
        last_clock = 0.0
        n = 0
        for m in self.reader.messages():
            if self.done:
                return
            if t0_bag is None:
                t0_bag = m.log_time
            rel = (m.log_time - t0_bag) / 1e9
            if rel < v["start_offset_s"]:
                continue
            if v["duration_s"] and rel > v["start_offset_s"] + v["duration_s"]:
                break
            pub = self._publisher(m.topic, m.type_name, m.metadata)
            if pub is None:
                continue
            if n == 0:  # every publisher known so far should have a subscriber (up to wait_for_subscribers_s)
                while time.monotonic() < wait_until and any(p is not None and p.get_subscription_count() == 0
                                                            for p in self.pubs.values()):
                    time.sleep(0.01)
                start_wall = time.monotonic()
                offset_bag = rel
            target = start_wall + (rel - offset_bag) / v["rate"]
            while True:  # sleep in slices, publishing /clock on the way
                now = time.monotonic()
                if self.clock_pub is not None and now - last_clock >= 1.0 / v["clock_rate_hz"]:
                    sim = t0_bag + int((offset_bag + (now - start_wall) * v["rate"]) * 1e9)
                    self.clock_pub.publish(Clock(clock=stamp(min(sim, m.log_time))))
                    last_clock = now
                if now >= target:
                    break
                time.sleep(min(target - now, 0.5 / v["clock_rate_hz"] if self.clock_pub else 0.05))
            if self.clock_pub is not None:
                self.clock_pub.publish(Clock(clock=stamp(m.log_time)))
            pub.publish(m.data)
            n += 1
            self.published += 1
        for note in self.reader.stopped:
            self.get_logger().warning(f"bag damaged, played everything intact: {note}")
        flush(self, [p for p in self.pubs.values() if p is not None])
        self.get_logger().info(f"played {n} messages")


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ros2 run zebra_sim_ros replay``; returns the exit status."""
    return run_node("replay", ReplayNode, argv, help_text("replay", __doc__ or "", REPLAY_PARAMS))


if __name__ == "__main__":
    raise SystemExit(main())
