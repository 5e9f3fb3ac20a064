"""The ``recorder`` node: MCAP bags that ``ros2 bag``, Foxglove and ``rosbags`` read
(``ros2 run zebra_sim_ros recorder``).

Subscribes, as serialized messages (no deserialisation), to the topics in ``topics`` or, with ``topics`` empty, to
every topic matching ``topic_regex`` and not ``exclude_regex``, found again every ``discovery_period_s`` (topics that
appear later are recorded from then on). Each subscription takes the QoS its publishers offer (reliable and transient
local only if they all are), and the offered profiles go into the bag as rosbag2's ``offered_qos_profiles``;
``qos_overrides_path`` sets policies per topic over that choice (the depth ``qos_depth``), as ``ros2 bag record
--qos-profile-overrides-path``. Log times are the messages' header stamps where their type has one
(``recording.stamps``), else the node's clock: run with ``use_sim_time`` (``up`` does) and every log time is simulated
time, the stamps' time base. Each message's publish time is when it arrived (wall clock), which is what latencies are
measured from. Callbacks only queue the bytes; one thread writes. A full queue counts drops per topic; a full disk or
``max_size_mb`` ends the recording with a finalised bag and an error. ``paused`` (runtime; the ``~/pause``,
``~/resume`` and ``~/toggle_paused`` services set it, and ``~/is_paused`` gives it) writes nothing while true: what
arrives is counted per topic (``paused_messages`` on /diagnostics), neither written nor dropped, and topics are still
found and subscribed. ``~/split_bagfile`` finishes the open file after what is queued and goes on in the next
(``<stem>_1.mcap``, ... for a bag not split by size or duration). With ``snapshot_size_mb`` > 0 (snapshot mode, as
``ros2 bag record --snapshot-mode``) the newest messages are kept in memory instead, up to that size (and
``snapshot_duration_s`` of log time), and ``~/snapshot`` writes them into a file of their own, finished at once
(``output``, then ``<stem>_1.mcap``, ...; no file before the first snapshot; with a size or duration split
``<stem>_0.mcap``, ..., and a large snapshot may fill several); the log names it. The services are ``ros2 bag
record``'s, with rosbag2_interfaces' types (Jazzy's; ``~/toggle_paused`` as the player's), so its clients work
unchanged. SIGINT, SIGTERM and node shutdown finalise the bag (summary and indexes); after
SIGKILL use ``zebra-sim bag recover``.
"""

from __future__ import annotations

import time
from typing import Any

from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy
from rosbag2_interfaces.srv import Snapshot, SplitBagfile

from zebra_sim_ros.errors import ZebraSimError
from zebra_sim_ros.health import Activity
from zebra_sim_ros.nodes.ros_adapter import ZebraNode, describe_qos, help_text, message_class, profile_qos, run_node
from zebra_sim_ros.recording.config import MB, RECORDER_PARAMS, RecorderConfig
from zebra_sim_ros.recording.qos import load_overrides, overridden, profile_dict, replay_profile
from zebra_sim_ros.recording.recorder import RecorderCore
from zebra_sim_ros.recording.stamps import LogTimes
from zebra_sim_ros.recording.writer import BagWriter


def _profile_of(info: Any) -> dict[str, Any]:
    q = info.qos_profile
    return profile_dict("keep_last" if q.history != HistoryPolicy.KEEP_ALL else "keep_all", int(q.depth),
                        "reliable" if q.reliability == ReliabilityPolicy.RELIABLE else "best_effort",
                        "transient_local" if q.durability == DurabilityPolicy.TRANSIENT_LOCAL else "volatile")


class RecorderNode(ZebraNode[RecorderConfig]):
    """Thin adapter around :class:`zebra_sim_ros.recording.recorder.RecorderCore`; the topic selection (``topics``,
    ``topic_regex``, ``exclude_regex``) and ``paused`` may change while it records."""

    def __init__(self) -> None:
        super().__init__("recorder", RecorderConfig)

    def start(self) -> None:
        """Open the bag; subscribe the topics to record now and look for new ones every discovery_period_s."""
        c = self.cfg
        self.overrides = load_overrides(c.qos_overrides_path)  # a bad file stops the node here, naming it
        reserve = -1 if c.disk_reserve_mb < 0 else int(c.disk_reserve_mb * MB)
        self.writer = BagWriter(c.output, c.compression, int(c.chunk_size_mb * MB),
                                int(c.split_size_mb * MB), c.split_duration_s, int(c.max_size_mb * MB), reserve,
                                defer_open=c.snapshot_size_mb > 0)  # snapshot mode: a file per snapshot, none before
        cache, span = int(c.snapshot_size_mb * MB), int(c.snapshot_duration_s * 1e9)  # snapshot mode where > 0
        self.core = RecorderCore(self.writer, c.queue_size, paused=c.paused, snapshot_bytes=cache, snapshot_ns=span)
        self.serve_pause()
        self.create_service(SplitBagfile, "~/split_bagfile", self._on_split)
        self.create_service(Snapshot, "~/snapshot", self._on_snapshot)
        self.depth = c.qos_depth
        self.log_times = LogTimes()  # each message's log time: its stamp, reports at the latest one
        self.subs: dict[str, Any] = {}
        self.wall_timer(c.discovery_period_s, self._discover)
        if c.stats_period_s > 0:
            self.wall_timer(c.stats_period_s, self._log_stats)
        self.wall_timer(0.2, self._check_error)
        self.get_logger().info(
            f"recording to {self.writer.path} ({c.compression}, chunks {c.chunk_size_mb} MB, split "
            f"{c.split_size_mb} MB / {c.split_duration_s} s, cap {c.max_size_mb} MB); "
            f"topics {c.topic_list or 'matching ' + c.topic_regex}"
            + (f"; snapshot mode: the last {c.snapshot_size_mb} MB" + (f" / {c.snapshot_duration_s} s" if
                                                                        c.snapshot_duration_s else "")
               + " kept in memory, written on ~/snapshot" if c.snapshot_size_mb else "")
            + (" (paused: ~/resume records)" if c.paused else ""))
        self._discover()

    def on_config(self, cfg: RecorderConfig) -> None:
        """Record the new selection: topics it adds are subscribed at once, topics it drops are no longer recorded;
        a pause or its end applies to the next message that arrives."""
        if cfg.paused != self.core.paused:
            self.core.paused = cfg.paused
            self.get_logger().info("paused: what arrives is counted, not written" if cfg.paused else "recording again")
        selection = (cfg.topics, cfg.topic_regex, cfg.exclude_regex) != (self.cfg.topics, self.cfg.topic_regex,
                                                                          self.cfg.exclude_regex)
        self.cfg = cfg
        if not selection:
            return
        for topic in [t for t in self.subs if not cfg.records(t)]:
            sub = self.subs.pop(topic)
            if sub is not None:
                self.destroy_subscription(sub)
                self.get_logger().info(f"no longer recording {topic}")
        self.get_logger().info(f"topics {cfg.topic_list or 'matching ' + cfg.topic_regex}")
        self._discover()

    def _discover(self) -> None:
        for topic, types in self.get_topic_names_and_types():
            if topic in self.subs or not self.cfg.records(topic) or not types:
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
            p = replay_profile(profiles) | {"depth": self.depth}  # reliable, transient local only if every one is
            q = profile_qos(overridden(p, self.overrides.get(topic)))
            self.subs[topic] = self.create_subscription(cls, topic, self._callback(topic, type_name), q, raw=True)
            self.get_logger().info(f"recording {topic} ({type_name}), QoS {describe_qos(q)}"
                                   + (" (qos_overrides_path)" if topic in self.overrides else ""))

    def _callback(self, topic: str, type_name: str) -> Any:
        """Queue each message with its log time (:class:`~zebra_sim_ros.recording.stamps.LogTimes`: its header
        stamp, a /diagnostics report at the latest stamp logged, anything else at the node's clock: simulated time
        under use_sim_time, as ``up`` runs it)."""
        offer, log_time, clock = self.core.offer, self.log_times, self.get_clock()

        def now() -> int:
            return int(clock.now().nanoseconds)

        def on_message(data: bytes) -> None:
            offer(topic, data, log_time(type_name, data, now), time.time_ns())
        return on_message

    def _on_split(self, request: Any, response: Any) -> Any:
        """``~/split_bagfile`` (rosbag2_interfaces/srv/SplitBagfile, whose answer is empty): the open file is
        finished after what is queued, and the bag goes on in the next; the log names it (or says how far behind
        the writer is), or says why it was refused: once the recording has ended, and in snapshot mode (each
        snapshot is a file of its own)."""
        self.log_service("~/split_bagfile", *self.core.split())
        return response

    def _on_snapshot(self, request: Any, response: Any) -> Any:
        """``~/snapshot`` (rosbag2_interfaces/srv/Snapshot), in snapshot mode: what the cache holds is written into a
        file of its own, finished at once, and the cache starts again empty; ``success``, and the log names the
        file (or what is being written, where that takes more than half a second); refused outside snapshot mode
        (``snapshot_size_mb`` 0) or once the recording has ended."""
        ok, message = self.core.snapshot()
        if not self.cfg.snapshot_size_mb:
            message += ": snapshot_size_mb is 0, so everything is written as it arrives"
        response.success = self.log_service("~/snapshot", ok, message)
        return response

    def _log_stats(self) -> None:
        t = self.core.totals()
        snap = self.cfg.snapshot_size_mb
        cache = f"{t['cached']} in the snapshot cache, {t['expired']} expired from it, " if snap else ""
        self.get_logger().info(f"{t['messages']} messages written, {t['dropped']} dropped, {t['paused']} while paused, "
                               f"{cache}{t['mb_per_s']} MB/s, queue {t['queue']}; per topic {t['topics']}")

    def _check_error(self) -> None:
        if self.core.error is not None and not self.done:
            self.get_logger().error(f"recording ended: {self.core.error}")
            self.done, self.exit_code = True, 1

    def activity(self) -> Activity:
        """Messages written and dropped (the writer fell behind by ``queue_size``); an error ends the recording."""
        t = self.core.totals()
        counts = {"messages": t["messages"], "dropped": t["dropped"], "paused_messages": t["paused"],
                  "topics": sum(s is not None for s in self.subs.values())}
        snapshot = self.cfg.snapshot_size_mb > 0
        if snapshot:  # what arrives, what goes into the cache (not while paused), what it holds now, what it let go
            # before a snapshot took it, the files written
            counts |= {"received": t["received"], "taken": t["taken"], "cached": t["cached"],
                       "expired": t["expired"], "snapshots": t["snapshots"]}
        # in snapshot mode the work is taking messages into the cache (paused, none is): writing waits for ~/snapshot
        return Activity(counts, "taken" if snapshot else "messages", ("dropped",),
                        error=f"recording ended: {t['error']}" if t["error"] is not None else "",
                        waiting="paused" if self.core.paused else "",
                        info={"output": str(self.writer.path), "files": str(len(self.writer.files)),
                              "queue": str(t["queue"]), "MB/s": f"{t['mb_per_s']:g}"})

    def stop(self) -> None:
        """Finalise the bag and print the statistics."""
        t0 = time.perf_counter()
        files = self.core.close()
        t = self.core.totals()
        cache = (f", {t['cached']} in the snapshot cache not written, {t['expired']} expired from it"
                 if self.cfg.snapshot_size_mb else "")
        where = f"bag {files}" if files else f"no bag written (no snapshot taken; {self.writer.path} not made)"
        msg = (f"{where}: {t['messages']} messages, {t['dropped']} dropped, {t['paused']} while paused{cache}; "
               f"per topic {t['topics']}; "
               f"writer {t['write_mb_per_s']} MB/s while writing; finalised in {time.perf_counter() - t0:.2f} s")
        print(f"[recorder] {msg}" + (f"; error: {self.core.error}" if self.core.error else ""), flush=True)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ros2 run zebra_sim_ros recorder``; returns the exit status."""
    return run_node("recorder", RecorderNode, argv, help_text("recorder", __doc__ or "", RECORDER_PARAMS))


if __name__ == "__main__":
    raise SystemExit(main())
