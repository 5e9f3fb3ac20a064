"""QoS profiles as rosbag2 writes them in MCAP channel metadata (``offered_qos_profiles``, YAML).

A profile is a plain dict with the keys rosbag2 uses; durations are ``{sec, nsec}``. "Infinite" durations are
rosbag2's ``{sec: 2147483647, nsec: 4294967295}``.
"""

from __future__ import annotations

from typing import Any

import yaml

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
