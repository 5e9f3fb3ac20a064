"""Parameters of the recorder and replay nodes, each declared once."""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.params import ParamSpec, StageConfig, diagnostics_param, is_regex, param

MB = 1 << 20  # the recorder's sizes are in MiB
SUMMARY_RESERVE = 16384  # bytes a bag's summary and indexes may need beyond its chunks (16 KiB)


def least_cap(chunk_size: int) -> int:
    """The smallest size cap, in bytes, for a bag of chunks of ``chunk_size`` bytes: the room the writer keeps
    under its cap (two chunks and the summary; ``BagWriter`` and ``RecorderConfig`` both hold to it)."""
    return 2 * chunk_size + SUMMARY_RESERVE


def _str_list(v: object) -> bool:
    return isinstance(v, list) and all(isinstance(x, str) for x in v)


def _qos_overrides_param(applies: str) -> Any:
    """The ``qos_overrides_path`` field of the recorder and the replay (``recording.qos.load_overrides`` reads it)."""
    return param("", f"YAML file of QoS policies per topic (history, depth, reliability, durability) for the "
                 f"{applies} ('': none)", allowed="empty or a YAML file")


@dataclass(frozen=True)
class RecorderConfig(StageConfig):
    """Validated recorder parameters; the topic selection (``topics``, ``topic_regex``, ``exclude_regex``) and
    ``paused`` may change while it records."""

    output: str = param("bags/zebra_sim.mcap", "bag file to write (.mcap added to a name without it; files split "
                        "by size or duration get _0, _1, ... before .mcap; a bag split only by ~/split_bagfile keeps "
                        "its name for the first file and goes on in _1, _2, ...)",
                        allowed="a path", check=lambda v: len(v) > 0)
    topics: tuple[str, ...] = param(("",), "topics to record; [''] (empty) records every topic that matches "
                                    "topic_regex", allowed="a list of topic names", check=_str_list, runtime=True)
    topic_regex: str = param(".*", "record topics matching this regular expression (with topics empty)",
                             allowed="a regular expression", check=is_regex, runtime=True)
    exclude_regex: str = param("^/(rosout|parameter_events)$", "never record topics matching this",
                               allowed="a regular expression", check=is_regex, runtime=True)
    compression: str = param("zstd", "chunk compression", choices=("zstd", "lz4", "none"))
    chunk_size_mb: float = param(4.0, "chunk size", "MB", lo=0.01, hi=1024.0)
    split_size_mb: float = param(0.0, "start a new file after this size (0: never)", "MB", lo=0.0, hi=1e6)
    split_duration_s: float = param(0.0, "start a new file after this long (0: never)", "s", lo=0.0, hi=1e7)
    max_size_mb: float = param(0.0, "stop recording (with a finalised bag) at this total size (0: no cap)", "MB",
                               lo=0.0, hi=1e7)
    disk_reserve_mb: float = param(-1.0, "free disk space kept to finish the bag: recording stops (every message "
                                   "so far kept, the bag finalised) when less would be left (-1: the open chunk + 0.25 "
                                   "MB + 1% of the bag; 0: none)", "MB", lo=-1.0, hi=1e6)
    queue_size: int = param(2000, "messages waiting for the writer thread before drops are counted", lo=1,
                            hi=1_000_000)
    discovery_period_s: float = param(0.5, "how often new topics are looked for", "s", lo=0.05, hi=60.0)
    stats_period_s: float = param(10.0, "how often statistics are logged (0: never)", "s", lo=0.0, hi=3600.0)
    qos_depth: int = param(100, "history depth of the subscriptions", lo=1, hi=100000)
    qos_overrides_path: str = _qos_overrides_param("subscriptions, over what the publishers offer and qos_depth, as "
                                                   "ros2 bag record --qos-profile-overrides-path")
    snapshot_size_mb: float = param(0.0, "snapshot mode when more than 0, as ros2 bag record --snapshot-mode "
                                    "--max-cache-size: keep the newest messages, up to this size, in memory and "
                                    "write them only when ~/snapshot (rosbag2_interfaces/srv/Snapshot) is called, "
                                    "each snapshot into a file of its own (0: record everything)", "MB", lo=0.0,
                                    hi=1e5)
    snapshot_duration_s: float = param(0.0, "in snapshot mode, keep only the messages of this much log time before "
                                       "the newest (0: as many as snapshot_size_mb holds)", "s", lo=0.0, hi=1e6)
    paused: bool = param(False, "write nothing while true: what arrives is counted (paused_messages), not "
                         "written, as ros2 bag record's pause; ~/pause, ~/resume and ~/toggle_paused "
                         "(rosbag2_interfaces' services) set it; true at start: start paused", runtime=True)
    diagnostics_period_s: float = diagnostics_param()

    def check(self) -> None:
        """A size cap must leave room for two chunks (the writer keeps them) and the summary; a snapshot duration
        needs snapshot mode."""
        if 0 < self.snapshot_size_mb < 1 / 1024:
            raise ParameterError("snapshot_size_mb", self.snapshot_size_mb, "0 (record everything) or 1 KiB "
                                 "(0.0009765625 MB) or more")
        if self.snapshot_duration_s and not self.snapshot_size_mb:
            raise ParameterError("snapshot_duration_s", self.snapshot_duration_s, "0 unless snapshot_size_mb is "
                                 "more than 0 (it sets snapshot mode and the cache's size)")
        least = least_cap(int(self.chunk_size_mb * MB)) / MB
        if 0 < self.max_size_mb < least:
            raise ParameterError("max_size_mb", self.max_size_mb, f"0 or more than {least:.3f} (2 x chunk_size_mb "
                                 "+ 16 KiB for the summary)")

    @property
    def topic_list(self) -> list[str]:
        """The topics named (``['']`` and empty names dropped): empty means every topic the regexes select."""
        return [t for t in self.topics if t]

    def records(self, topic: str) -> bool:
        """Whether this selection records ``topic``: one of ``topics`` where it names any, else one that
        ``topic_regex`` finds in it and ``exclude_regex`` does not (the recorder node's rule; ``up`` waits for
        these)."""
        if self.topic_list:
            return topic in self.topic_list
        return bool(re.search(self.topic_regex, topic)) and not re.search(self.exclude_regex, topic)


@dataclass(frozen=True)
class ReplayConfig(StageConfig):
    """Validated replay parameters; ``rate`` and ``paused`` may change while it plays, and ``start_offset_s``
    seeks."""

    bags: tuple[str, ...] = param(("",), "bag files (or folders of split files) to play, in order",
                                  allowed="a non-empty list of paths", check=lambda v: _str_list(v) and any(v))
    rate: float = param(1.0, "playback speed (2: twice as fast)", lo=0.01, hi=1000.0, runtime=True)
    paused: bool = param(False, "hold playback where it is while true (/clock stays at the bag time reached), as ros2 "
                         "bag play's pause; ~/pause, ~/resume and ~/toggle_paused (rosbag2_interfaces' services) "
                         "set it; true at start: start paused", runtime=True)
    loop: bool = param(False, "play again from start_offset_s (where the last seek went) when done")
    start_offset_s: float = param(0.0, "skip this much of the bag's start (its first message played: topics not "
                                  "played do not count); set while playing, it seeks there, back or forth (as ros2 "
                                  "bag play's seek; the same value again seeks again), and duration_s counts from it; "
                                  "past the bags' last message (where their summaries give it) refused, at start too",
                                  "s", lo=0.0, hi=1e9, runtime=True)
    duration_s: float = param(0.0, "play only this much of the bag (0: to the end)", "s", lo=0.0, hi=1e9)
    topics: tuple[str, ...] = param(("",), "play only these topics ([''] = all matching topic_regex)",
                                    allowed="a list of topic names", check=_str_list)
    topic_regex: str = param(".*", "play topics matching this regular expression", allowed="a regular expression",
                             check=is_regex)
    exclude_regex: str = param("", "never play topics matching this regular expression ('': none; as ros2 bag "
                               "play --exclude-regex)", allowed="a regular expression or empty", check=is_regex)
    remap_prefix: str = param("", "prefix added to every topic name (e.g. /replay)",
                              allowed="empty, or starting and not ending with /",
                              check=lambda v: v == "" or (v.startswith("/") and not v.endswith("/")))
    clock: bool = param(False, "publish /clock (rosgraph_msgs/Clock) with the bag's time, for use_sim_time")
    clock_rate_hz: float = param(100.0, "how often /clock is published between messages", "Hz", lo=1.0, hi=10000.0)
    qos_overrides_path: str = _qos_overrides_param("publishers, over what was recorded, as ros2 bag play "
                                                   "--qos-profile-overrides-path")
    wait_for_subscribers_s: float = param(0.0, "wait up to this long, before playing, for every played topic to "
                                          "have a subscriber (after a wait, 0.3 s more: the new subscribers' side "
                                          "of the match)", "s", lo=0.0, hi=3600.0)
    diagnostics_period_s: float = diagnostics_param()


RECORDER_PARAMS: tuple[ParamSpec, ...] = RecorderConfig.specs()
REPLAY_PARAMS: tuple[ParamSpec, ...] = ReplayConfig.specs()
