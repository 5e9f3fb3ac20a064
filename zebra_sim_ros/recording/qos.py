"""QoS profiles as rosbag2 writes them in MCAP channel metadata (``offered_qos_profiles``, YAML).

A profile is a plain dict with the keys rosbag2 uses; durations are ``{sec, nsec}``. "Infinite" durations are
rosbag2's ``{sec: 2147483647, nsec: 4294967295}``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from zebra_sim_ros.errors import ParameterError

INFINITE = {"sec": 2147483647, "nsec": 4294967295}


def profile_dict(history: str = "keep_last", depth: int = 10, reliability: str = "reliable",
                 durability: str = "volatile") -> dict[str, Any]:
    """A QoS profile in rosbag2's field names (deadline, lifespan and lease infinite, liveliness automatic)."""
    return {"history": history, "depth": int(depth), "reliability": reliability, "durability": durability,
            "deadline": dict(INFINITE), "lifespan": dict(INFINITE), "liveliness": "automatic",
            "liveliness_lease_duration": dict(INFINITE), "avoid_ros_namespace_conventions": False}


def to_yaml(profiles: list[dict[str, Any]]) -> str:
    """The ``offered_qos_profiles`` metadata value."""
    return str(yaml.safe_dump(profiles, default_flow_style=False, sort_keys=False))


def from_yaml(text: str) -> list[dict[str, Any]]:
    """Parse ``offered_qos_profiles``; numbers for enum values (older rosbag2) are mapped to names."""
    data = yaml.safe_load(text) if text else []
    out = []
    names = {"history": {1: "keep_last", 2: "keep_all"}, "reliability": {1: "reliable", 2: "best_effort"},
             "durability": {1: "transient_local", 2: "volatile"}}
    for p in data or []:
        q = dict(p)
        for key, table in names.items():
            if isinstance(q.get(key), int):
                q[key] = table.get(q[key], "system_default")
        out.append(q)
    return out


def replay_profile(profiles: list[dict[str, Any]]) -> dict[str, Any]:
    """One profile to publish with when replaying: reliable and transient local only if every publisher was."""
    if not profiles:
        return profile_dict()
    reliable = all(p.get("reliability") == "reliable" for p in profiles)
    latched = all(p.get("durability") == "transient_local" for p in profiles)
    depth = max(int(p.get("depth", 10) or 10) for p in profiles)
    return profile_dict("keep_last", depth, "reliable" if reliable else "best_effort",
                        "transient_local" if latched else "volatile")


# What a QoS override may set, and the values each takes (rosbag2's names; depth: a whole number, 0 with keep_all)
OVERRIDES: dict[str, tuple[str, ...]] = {"history": ("keep_last", "keep_all"), "depth": (),
                                         "reliability": ("reliable", "best_effort"),
                                         "durability": ("volatile", "transient_local")}


def load_overrides(path: str | Path, name: str = "qos_overrides_path") -> dict[str, dict[str, Any]]:
    """The QoS overrides file of ``ros2 bag record|play --qos-profile-overrides-path``: a YAML mapping of topic names
    to the policies to use for them (``history``, ``depth``, ``reliability``, ``durability``), over what the node
    would choose itself; empty ``path``: none. Errors name the parameter ``name``, the topic and the key."""
    if not str(path):
        return {}
    try:
        data = yaml.safe_load(Path(path).read_text())
    except OSError as exc:
        raise ParameterError(name, str(path), f"a readable YAML file ({exc.strerror or exc})") from exc
    except yaml.YAMLError as exc:
        raise ParameterError(name, str(path), f"a YAML file ({type(exc).__name__}: {exc})") from exc
    if not isinstance(data, dict):
        raise ParameterError(name, str(path), "a YAML mapping of topic names to QoS policies")
    out: dict[str, dict[str, Any]] = {}
    for topic, policies in data.items():
        where = f"{path}: {topic}"
        if not isinstance(topic, str) or not topic.startswith("/"):
            raise ParameterError(name, where, "topic names starting with /")
        if not isinstance(policies, dict) or not policies:
            raise ParameterError(name, where, f"a mapping of some of {sorted(OVERRIDES)} to values")
        for key, value in policies.items():
            if key not in OVERRIDES:
                raise ParameterError(name, f"{where}: {key}", f"one of {sorted(OVERRIDES)} (the others are not set)")
            if key == "depth":
                if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 1_000_000:
                    raise ParameterError(name, f"{where}: depth {value!r}", "a whole number 0..1000000")
            elif value not in OVERRIDES[key]:
                raise ParameterError(name, f"{where}: {key} {value!r}", f"one of {list(OVERRIDES[key])}")
        if policies.get("history", "keep_last") == "keep_last" and policies.get("depth") == 0:
            raise ParameterError(name, f"{where}: depth 0", "1 or more with keep_last (0 only with keep_all)")
        out[topic] = dict(policies)
    return out


def overridden(profile: dict[str, Any], override: dict[str, Any] | None) -> dict[str, Any]:
    """``profile`` with the policies ``override`` sets (a copy; ``profile`` itself where there is none)."""
    return {**profile, **override} if override else profile
