"""The census of a recorded run, counted again (``zebra-sim bag census``): each step's detections placed on the map
by the locator (``<drone>/detections/located`` and ``<drone>/camera/pose``, recorded by ``up --locate``) joined
across the cameras with census parameters given here (:func:`zebra_sim_ros.geometry.census.join_views`, the
locator node's rule, in its ``drones`` order), against the distinct zebras the cameras' labels keep where the bag
has labels; beside it the census the locator recorded (``census/animals``), where it did. A run recorded once can
so be counted again with other parameters, and a change to the rule measured on the same detections.
"""

from __future__ import annotations

import re
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from zebra_sim_ros.detection.config import CENSUS_RULE, LOCATED_TOPICS, LocatorConfig
from zebra_sim_ros.detection.scoring import DroneFrames
from zebra_sim_ros.errors import ParameterError, ZebraSimError
from zebra_sim_ros.geometry.census import join_views
from zebra_sim_ros.recording.cdr import MALFORMED, cdr_detections3d, cdr_pose_position
from zebra_sim_ros.recording.evaluate import collect, skip_note
from zebra_sim_ros.recording.reader import BagMessage, last_name, topic_owner

_POSE = ("camera/pose",)  # a camera's optical frame in map (the placer's)
# the locator's own census, under the graph's namespace
CENSUS_TOPIC = re.compile(rf"^(?:/[^/]+)*/{re.escape(LocatorConfig().census_output)}$")


def census_figures(census: dict[int, int], drones: dict[str, DroneFrames],
                   located: dict[tuple[str, int], np.ndarray]) -> dict[str, Any]:
    """A census (zebras counted per stamp) against the truth: over the stamps every camera labelled, the zebras it
    counted (``animals``), the distinct zebras the cameras' labels keep (``true``: one seen by three drones is one),
    the zebra detections placed by all cameras (``summed``: the count without joining; ``located``: per camera and
    stamp, its placed zebra detections) and the relative errors. Where no camera has labels (a real flight), over
    every stamp of the census, with ``true`` and the errors None."""
    labelled = bool(drones) and any(d.labels for d in drones.values())
    stamps = [t for t in sorted(census) if not labelled or all(t in d.labels for d in drones.values())]
    true = sum(len({z.id for d in drones.values() for z in d.labels[t].kept}) for t in stamps) if labelled else None
    animals = sum(census[t] for t in stamps)
    kept = set(stamps)
    summed = sum(len(p) for (_, t), p in located.items() if t in kept)

    def error(n: int) -> float | None:
        return round((n - true) / true, 4) if true else None

    return {"steps": len(stamps), "animals": animals, "true": true, "error": error(animals), "summed": summed,
            "summed_error": error(summed)}


def census_line(f: dict[str, Any]) -> str:
    """One line of :func:`census_figures`: the zebras counted against the distinct labelled ones, or why not."""
    if f["true"] is None:
        return f"{f['animals']} zebras in {f['steps']} steps (no labels in the bag to compare with)"
    if not f["steps"]:
        return "no step that every camera labelled"
    if not f["true"]:
        return f"{f['animals']} zebras in {f['steps']} steps, where the labels keep none"
    return (f"{f['animals']} zebras counted once across the drones for {f['true']} distinct zebras labelled "
            f"({f['error']:+.1%}; summed over the drones {f['summed']}, {f['summed_error']:+.1%}) in {f['steps']} "
            "steps")


def drone_order(name: str) -> tuple[int, str]:
    """drone_2 before drone_10 (up's and the launch file's cameras, in the locator's ``drones`` order)."""
    return len(name), name


def zebra_points(dets: list[tuple[str, float, tuple[float, float, float]]]) -> np.ndarray:
    """The zebras' points (N, 3) of a Detection3DArray read by :func:`~zebra_sim_ros.recording.cdr.cdr_detections3d`."""
    return np.array([c for name, _, c in dets if name == "zebra"], np.float64).reshape(-1, 3)


def bag_census(paths: list[str | Path] | str | Path, rule: LocatorConfig | None = None,
               drones: Sequence[str] | None = None) -> dict[str, Any]:
    """The census of the bag ``paths`` counted again by ``rule``'s :data:`CENSUS_RULE` parameters (the locator's;
    default: its defaults; module docstring), the cameras joined in ``drones``' order (the locator's ``drones``,
    last names; default: the cameras found, ``drone_2`` before ``drone_10``, as up and the launch file have them):
    per stamp that every camera has placed and posed, its zebras joined across the cameras and scored by
    :func:`census_figures`. ``recorded``: the locator's recorded census, scored on the same stamps (None where the
    bag has none). ParameterError when the bag holds no placed detections (recorded without ``up --locate``) or no
    camera poses, holds more than one graph's (two namespaces), or ``drones`` are not its cameras."""
    rule = rule or LocatorConfig()
    located: dict[tuple[str, int], list[tuple[str, float, tuple[float, float, float]]]] = {}
    poses: dict[tuple[str, int], tuple[float, float, float]] = {}
    recorded: dict[int, int] = {}
    graphs: set[str] = set()  # the namespaces the cameras are in
    unusable: list[str] = []

    def visit(m: BagMessage) -> None:
        try:
            if owner := topic_owner(m.topic, LOCATED_TOPICS):
                t, dets = cdr_detections3d(m.data)
                located[(last_name(owner[0]), t)] = dets
                graphs.add(owner[0].rsplit("/", 1)[0])
            elif (owner := topic_owner(m.topic, _POSE)) and m.type_name.endswith("/PoseStamped"):
                t, position = cdr_pose_position(m.data)
                poses[(last_name(owner[0]), t)] = position
            elif CENSUS_TOPIC.match(m.topic):
                t, animals = cdr_detections3d(m.data)
                recorded[t] = len(zebra_points(animals))
        except (*MALFORMED, ZebraSimError) as exc:
            unusable.append(skip_note(m, exc))

    collected = collect(paths, each=visit)
    bag = [str(p) for p in (paths if isinstance(paths, list) else [paths])]
    if not located:
        raise ParameterError("bag", bag, f"a bag with placed detections (<drone>/{LOCATED_TOPICS[0]}: recorded by up "
                             "--locate)")
    if len(graphs) > 1:
        raise ParameterError("bag", bag, f"one graph's run (its cameras are in {len(graphs)} namespaces: "
                             f"{', '.join(sorted(g or '/' for g in graphs))})")
    found = sorted({d for d, _ in located}, key=drone_order)
    cameras = list(drones) if drones else found
    if sorted(cameras) != sorted(found):
        raise ParameterError("drones", cameras, f"the bag's cameras, each once, in any order: {found}")
    by_stamp: dict[int, set[str]] = defaultdict(set)
    for d, t in located:
        if (d, t) in poses:
            by_stamp[t].add(d)
    if not by_stamp:
        raise ParameterError("bag", bag, "a bag with the cameras' poses (<drone>/camera/pose, recorded by up "
                             "--locate) beside their placed detections")
    counts: dict[int, int] = {}
    zebras = {key: zebra_points(dets) for key, dets in located.items()}
    for t, have in sorted(by_stamp.items()):
        if have != set(cameras):
            continue
        scores = [np.array([s for name, s, _ in located[(d, t)] if name == "zebra"], np.float64) for d in cameras]
        census = join_views([zebras[(d, t)] for d in cameras], [np.array(poses[(d, t)]) for d in cameras],
                            rule.census_along, rule.census_across, rule.census_gate, rule.census_separation, scores)
        counts[t] = census.count
    both = {t: recorded[t] for t in counts if t in recorded}
    return {"rule": {k: getattr(rule, k) for k in CENSUS_RULE}, "cameras": cameras,
            "stamps_placed": len({t for _, t in located}), "stamps_counted": len(counts),
            "recounted": census_figures(counts, collected.drones, zebras),
            "recorded": census_figures(both, collected.drones, zebras) if recorded else None,
            "recorded_stamps": len(recorded), "skipped": unusable + collected.skipped, "damaged": collected.damaged}
