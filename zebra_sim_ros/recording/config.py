"""Parameters of the recorder and replay nodes."""

from __future__ import annotations

from zebra_sim_ros.params import ParamSpec, in_range, is_regex, one_of


def _str_list(v: object) -> bool:
    return isinstance(v, list) and all(isinstance(x, str) for x in v)


RECORDER_PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec("output", "bags/zebra_sim.mcap", "bag file to write (split files get _0, _1, ... before .mcap)",
              "a path", lambda v: isinstance(v, str) and len(v) > 0),
    ParamSpec("topics", [""], "topics to record; [''] (empty) records every topic that matches topic_regex",
              "a list of topic names", _str_list),
    ParamSpec("topic_regex", ".*", "record topics matching this regular expression (with topics empty)",
              "a regular expression", is_regex),
    ParamSpec("exclude_regex", "^/(rosout|parameter_events)$", "never record topics matching this",
              "a regular expression", is_regex),
    ParamSpec("compression", "zstd", "chunk compression", "zstd, lz4 or none", one_of("zstd", "lz4", "none")),
    ParamSpec("chunk_size_mb", 4.0, "chunk size, MB", "0.01..1024", in_range(0.01, 1024.0)),
    ParamSpec("split_size_mb", 0.0, "start a new file after this many MB (0: never)", "0..1e6", in_range(0.0, 1e6)),
    ParamSpec("split_duration_s", 0.0, "start a new file after this many seconds (0: never)", "0..1e7",
              in_range(0.0, 1e7)),
    ParamSpec("max_size_mb", 0.0, "stop recording (with a finalised bag) at this total size, MB (0: no cap)",
              "0..1e7", in_range(0.0, 1e7)),
    ParamSpec("queue_size", 2000, "messages waiting for the writer thread before drops are counted", "1..1e6",
              in_range(1, 1_000_000)),
    ParamSpec("discovery_period_s", 0.5, "how often new topics are looked for, s", "0.05..60", in_range(0.05, 60.0)),
    ParamSpec("stats_period_s", 10.0, "how often statistics are logged, s (0: never)", "0..3600",
              in_range(0.0, 3600.0)),
    ParamSpec("qos_depth", 100, "history depth of the subscriptions", "1..100000", in_range(1, 100000)),
)

REPLAY_PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec("bags", [""], "bag files (or folders of split files) to play, in order", "a non-empty list of paths",
              lambda v: _str_list(v) and any(x for x in v)),
    ParamSpec("rate", 1.0, "playback speed (2: twice as fast)", "0.01..1000", in_range(0.01, 1000.0)),
    ParamSpec("loop", False, "play again from the start when done", "true or false", lambda v: isinstance(v, bool)),
    ParamSpec("start_offset_s", 0.0, "skip this many seconds of the bag", "0..1e9", in_range(0.0, 1e9)),
    ParamSpec("duration_s", 0.0, "play only this many seconds of the bag (0: to the end)", "0..1e9",
              in_range(0.0, 1e9)),
    ParamSpec("topics", [""], "play only these topics ([''] = all matching topic_regex)", "a list of topic names",
              _str_list),
    ParamSpec("topic_regex", ".*", "play topics matching this regular expression", "a regular expression",
              is_regex),
    ParamSpec("remap_prefix", "", "prefix added to every topic name (e.g. /replay)",
              "empty, or starting and not ending with /",
              lambda v: isinstance(v, str) and (v == "" or (v.startswith("/") and not v.endswith("/")))),
    ParamSpec("clock", False, "publish /clock (rosgraph_msgs/Clock) with the bag's time, for use_sim_time",
              "true or false", lambda v: isinstance(v, bool)),
    ParamSpec("clock_rate_hz", 100.0, "how often /clock is published between messages", "1..10000",
              in_range(1.0, 10000.0)),
    ParamSpec("wait_for_subscribers_s", 0.0,
              "wait up to this long, before playing, for every played topic to have a subscriber, s", "0..3600",
              in_range(0.0, 3600.0)),
)
