"""The census of a recorded run, counted again (``zebra-sim bag census``): each step's detections placed on the map
by the locator (``<drone>/detections/located``, recorded by ``up --locate``) joined across the drones with census
parameters given here (:func:`zebra_sim_ros.geometry.census.join_views`, the locator node's rule), against the
distinct zebras the drones' labels keep; beside it the census the locator recorded (``census/animals``), where it
did. A survey flown once can so be counted again with other parameters, and a change to the rule measured on the
same detections.
"""

from __future__ import annotations

import re
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from zebra_sim_ros.detection.config import LocatorConfig
from zebra_sim_ros.detection.scoring import DroneFrames
from zebra_sim_ros.errors import ParameterError, ZebraSimError
from zebra_sim_ros.geometry.census import join_views
from zebra_sim_ros.recording.cdr import MALFORMED, cdr_detections3d, cdr_pose_position
from zebra_sim_ros.recording.evaluate import collect, skip_note
from zebra_sim_ros.recording.reader import BagMessage, last_name, topic_owner

_LOCATED = (LocatorConfig().output,)  # a camera's detections placed on the map
_POSE = ("camera/pose",)  # a camera's optical frame in map (the placer's)
# the locator's own census, under the graph's namespace
CENSUS_TOPIC = re.compile(rf"^(?:/[^/]+)*/{re.escape(LocatorConfig().census_output)}$")


def census_figures(census: dict[int, int], drones: dict[str, DroneFrames],
                   located: dict[tuple[str, int], np.ndarray]) -> dict[str, Any]:
    """A census (zebras counted per stamp) against the truth, over the stamps every camera labelled: the zebras it
    counted (``animals``), the distinct zebras the cameras' labels keep (``true``: one seen by three drones is one),
    the zebra detections placed by all cameras (``summed``: the count without joining; ``located``: per camera and
    stamp, its placed zebra detections), and the relative errors."""
    stamps = [t for t in sorted(census) if drones and all(t in d.labels for d in drones.values())]
    true = sum(len({z.id for d in drones.values() for z in d.labels[t].kept}) for t in stamps)
    animals = sum(census[t] for t in stamps)
    kept = set(stamps)
    summed = sum(len(p) for (_, t), p in located.items() if t in kept)

    def error(n: int) -> float | None:
        return round((n - true) / true, 4) if true else None

    return {"steps": len(stamps), "animals": animals, "true": true, "error": error(animals), "summed": summed,
            "summed_error": error(summed)}


def _drone_order(name: str) -> tuple[int, str]:
    """drone_2 before drone_10 (the graph's order, the locator's ``drones``)."""
    return len(name), name


CENSUS_RULE = ("census_along", "census_across", "census_gate", "census_separation")  # the locator's parameters


def bag_census(paths: list[str | Path] | str | Path, rule: LocatorConfig | None = None) -> dict[str, Any]:
    """The census of the bag ``paths`` counted again by ``rule``'s :data:`CENSUS_RULE` parameters (the locator's;
    default: its defaults; module docstring): per stamp that every camera with placed detections has placed and
    posed, its zebras joined across the cameras (in drone order) and scored by :func:`census_figures`;
    ``recorded``: the locator's recorded census scored the same way (None where the bag has none). ParameterError
    when the bag holds no placed detections (recorded without ``up --locate``)."""
    rule = rule or LocatorConfig()
    located: dict[tuple[str, int], list[tuple[str, float, tuple[float, float, float]]]] = {}
    poses: dict[tuple[str, int], tuple[float, float, float]] = {}
    recorded: dict[int, int] = {}
    unusable: list[str] = []

    def visit(m: BagMessage) -> None:
        try:
            if owner := topic_owner(m.topic, _LOCATED):
                t, dets = cdr_detections3d(m.data)
                located[(last_name(owner[0]), t)] = dets
            elif (owner := topic_owner(m.topic, _POSE)) and m.type_name.endswith("/PoseStamped"):
                t, position = cdr_pose_position(m.data)
                poses[(last_name(owner[0]), t)] = position
            elif CENSUS_TOPIC.match(m.topic):
                t, animals = cdr_detections3d(m.data)
                recorded[t] = sum(1 for name, _, _ in animals if name == "zebra")
        except (*MALFORMED, ZebraSimError) as exc:
            unusable.append(skip_note(m, exc))

    collected = collect(paths, each=visit)
    if not located:
        raise ParameterError("bag", [str(p) for p in (paths if isinstance(paths, list) else [paths])],
                             f"a bag with placed detections (<drone>/{_LOCATED[0]}: recorded by up --locate)")
    cameras = sorted({d for d, _ in located}, key=_drone_order)
    by_stamp: dict[int, set[str]] = defaultdict(set)
    for d, t in located:
        if (d, t) in poses:
            by_stamp[t].add(d)
    counts: dict[int, int] = {}
    zebras = {key: np.array([c for name, _, c in dets if name == "zebra"], np.float64).reshape(-1, 3)
              for key, dets in located.items()}
    for t, have in sorted(by_stamp.items()):
        if have != set(cameras):
            continue
        scores = [np.array([s for name, s, _ in located[(d, t)] if name == "zebra"], np.float64) for d in cameras]
        census = join_views([zebras[(d, t)] for d in cameras], [np.array(poses[(d, t)]) for d in cameras],
                            rule.census_along, rule.census_across, rule.census_gate, rule.census_separation, scores)
        counts[t] = census.count
    return {"rule": {k: getattr(rule, k) for k in CENSUS_RULE}, "cameras": cameras, "stamps_placed": len(by_stamp),
            "stamps_counted": len(counts), "recounted": census_figures(counts, collected.drones, zebras),
            "recorded": census_figures(recorded, collected.drones, zebras) if recorded else None,
            "skipped": unusable + collected.skipped, "damaged": collected.damaged}
