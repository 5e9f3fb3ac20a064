"""The census of a recorded run, counted again (``zebra-sim bag census``): each step's detections placed on the map
by the locator (``<drone>/detections/located``, or the ``output`` its file names, and ``<drone>/camera/pose``, or
the ``pose`` it placed them from, recorded by ``up --locate``) joined
across the cameras with census parameters given here, or else the bag's locator's as it reported them on
/diagnostics (:func:`zebra_sim_ros.geometry.census.join_views`, the locator node's rule, in its ``drones`` order),
against the distinct zebras the cameras' labels keep where the bag
has labels; beside it the census the locator recorded (``census/animals``, or its ``census_output``), where it
did. A run recorded once can
so be counted again with other parameters, and a change to the rule measured on the same detections.
"""

from __future__ import annotations

import json
import re
from collections import defaultdict
from collections.abc import Mapping, Sequence
from dataclasses import astuple
from pathlib import Path
from typing import Any

import numpy as np

from zebra_sim_ros.detection.config import CENSUS_READS, CENSUS_RULE, LocatorConfig
from zebra_sim_ros.detection.scoring import DroneFrames
from zebra_sim_ros.errors import ParameterError, ZebraSimError
from zebra_sim_ros.geometry.geodesy import enu_to_geodetic
from zebra_sim_ros.geometry.locate import positions_at
from zebra_sim_ros.messages import Datum, Scene
from zebra_sim_ros.params import spec_of, validate
from zebra_sim_ros.placement.config import SCENE_TOPIC
from zebra_sim_ros.recording.cdr import (
    MALFORMED,
    Placed3D,
    cdr_detections3d,
    cdr_diagnostics,
    cdr_pose_position,
    cdr_string,
)
from zebra_sim_ros.recording.evaluate import collect, skip_note
from zebra_sim_ros.recording.reader import BagMessage, last_name, topic_owner, under_any_namespace
from zebra_sim_ros.recording.stamps import iso_time


def census_topic_re(locator: LocatorConfig) -> re.Pattern[str]:
    """The topic of ``locator``'s own census, under any graph's namespace."""
    return under_any_namespace(locator.census_output)


SCENE_TOPIC_RE = under_any_namespace(SCENE_TOPIC)  # the placer's scenes


def census_geojson(census: dict[int, list[Placed3D]], datum: Datum, about: dict[str, Any]) -> dict[str, Any]:
    """A census as a GeoJSON FeatureCollection (RFC 7946: WGS84 longitude, latitude and height above the
    ellipsoid), for a GIS: per stamp (``census``: its animals, each placed in ``map`` with ``id`` the detections it
    joins, ``camera:index``) and animal a Point, its id ``<stamp_ns>:<k>``, with scalar properties (they survive a
    shapefile or CSV export): its class, score, stamp (also :func:`iso_time`), how many cameras saw it, the
    detections it joins and its ``map`` position; ``datum`` puts ``map`` on the Earth; the datum, the animals per
    class and ``about`` (the source, the rule) go beside the features, under ``zebra_sim``."""
    rows = [(t, k, a) for t in sorted(census) for k, a in enumerate(census[t])]
    lla = enu_to_geodetic(np.array([a.center for _, _, a in rows], np.float64).reshape(-1, 3), datum)
    features = []
    for (t, k, a), (lat, lon, height) in zip(rows, lla.tolist(), strict=True):
        parts = [p for p in a.id.split(",") if p]
        x, y, z = (round(v, 3) for v in a.center)
        features.append({
            "type": "Feature", "id": f"{t}:{k}",
            "geometry": {"type": "Point", "coordinates": [round(lon, 8), round(lat, 8), round(height, 3)]},
            "properties": {"class": a.class_id, "score": round(a.score, 4), "stamp_ns": t, "time_s": t / 1e9,
                           "time": iso_time(t),
                           "views": len({p.rsplit(":", 1)[0] for p in parts}), "detections": ",".join(parts),
                           "map_x": x, "map_y": y, "map_z": z}})
    per_class: dict[str, int] = defaultdict(int)
    for _, _, a in rows:
        per_class[a.class_id] += 1
    return {"type": "FeatureCollection", "features": features,
            "zebra_sim": {"datum": datum.to_dict(), "animals": len(rows), "per_class": dict(per_class),
                          "stamps": len(census), **about}}


def write_geojson(path: str | Path, collection: dict[str, Any]) -> Path:
    """Write :func:`census_geojson`'s collection to ``path`` (its folder made); OSError if it cannot be."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(collection) + "\n")
    return out


def same_place(a: Datum, b: Datum) -> bool:
    """The same datum to within 1e-9 deg (0.1 mm) and 1 mm: one typed from another's printout is the same."""
    return (abs(a.latitude_deg - b.latitude_deg) <= 1e-9 and abs(a.longitude_deg - b.longitude_deg) <= 1e-9
            and abs(a.altitude_m - b.altitude_m) <= 1e-3)


def run_datum(datums: set[Datum | None]) -> Datum:
    """The one datum of a run's scenes (``datums``: each scene's, None for one from before scenes carried it);
    ParameterError naming ``datum`` when they hold none or disagree."""
    held = sorted({astuple(d) for d in datums if d is not None})
    if len(held) != 1:
        raise ParameterError("datum", held,
                             "one datum (map origin's latitude, longitude and height) in the bag's scenes, or one "
                             "given where they carry none (bag census --datum)")
    return Datum(*held[0])


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


def zebra_points(dets: list[Placed3D]) -> np.ndarray:
    """The zebras' points (N, 3) of a Detection3DArray read by :func:`~zebra_sim_ros.recording.cdr.cdr_detections3d`."""
    return np.array([d.center for d in dets if d.class_id == "zebra"], np.float64).reshape(-1, 3)


def _locator_settings(reports: Mapping[str, Mapping[str, str]],
                      given: Mapping[str, Any]) -> tuple[dict[str, Any], list[str]]:
    """The census settings the bag's locator reported (its latest /diagnostics values; :data:`CENSUS_RULE` and
    :data:`CENSUS_READS` not in ``given``, each one this version's parameter accepts: another is left to its
    default) and its cameras' order (last names); nothing where the bag holds no locator's reports, or two
    locators' (which would be two runs). A run that changed them while it ran is counted by the latest."""
    if len(reports) != 1:
        return {}, []
    (values,) = reports.values()
    out: dict[str, Any] = {}
    for key in (*CENSUS_RULE, *CENSUS_READS):
        if key in values and key not in given:
            try:
                value = float(values[key]) if isinstance(spec_of(LocatorConfig, key).default, float) else values[key]
                out[key] = validate([spec_of(LocatorConfig, key)], {key: value})[key]
            except (ValueError, ParameterError):
                continue  # not this version's: the default
    order = [last_name(d.strip()) for d in values.get("drones", "").split(",") if d.strip()]
    return out, order


def bag_census(paths: list[str | Path] | str | Path, settings: Mapping[str, Any] | None = None,
               drones: Sequence[str] | None = None, geojson: str | Path | None = None,
               datum: Datum | None = None) -> dict[str, Any]:
    """The census of the bag ``paths`` counted again by the locator's :data:`CENSUS_RULE` parameters, read from its
    topics (``output``, ``census_output``, ``pose``) as it read them (``pose_max_gap_s``: the camera's position
    interpolated between the poses about each image; :data:`CENSUS_READS`), the cameras joined in its ``drones``'
    order. Each of these is, in this order: given in ``settings``; else the bag's locator's, as it reported them on
    ``/diagnostics`` (:meth:`~zebra_sim_ros.nodes.locator.LocatorNode.activity`; ``followed`` in the result names
    them), so a recount of a run made with other settings (``up --set locator.pose=camera/pose_nav``) counts as
    it did; else the parameter's default (the cameras: those found, ``drone_2`` before ``drone_10``, as up and the
    launch file have them). ``drones`` given are last names, in the order to join; the locator's order is followed
    only where it names the bag's cameras. ParameterError naming a ``settings`` key that is none of these, and a
    value that the followed ones make invalid (the message says what was followed).

    Per stamp that every camera has placed and posed, its zebras are joined across the cameras and scored by
    :func:`census_figures`. ``recorded``: the locator's recorded census, scored on the same stamps (None where the
    bag has none). ParameterError when the bag holds no placed detections (recorded without ``up --locate``) or no
    camera poses, holds more than one graph's (two namespaces), or ``drones`` are not its cameras.

    ``geojson``: the recounted animals are written there (:func:`census_geojson`), put on the Earth by the datum of
    the bag's scenes, or by ``datum`` where they carry none; ParameterError naming ``datum`` when there is neither,
    when the scenes disagree, or when ``datum`` differs from theirs, and naming ``geojson`` when it cannot be
    written."""
    if datum is not None and geojson is None:
        raise ParameterError("datum", astuple(datum), "only with geojson (the census is placed on the Earth for it)")
    given = dict(settings or {})
    if unknown := sorted(set(given) - set(CENSUS_RULE) - set(CENSUS_READS)):
        raise ParameterError("settings", unknown, f"the locator's {', '.join((*CENSUS_RULE, *CENSUS_READS))}")
    placed: dict[str, dict[int, list[Placed3D]]] = defaultdict(dict)  # every Detection3DArray topic, by stamp
    posed: dict[str, dict[int, tuple[float, float, float]]] = defaultdict(dict)  # every PoseStamped topic
    datums: set[Datum | None] = set()  # the scenes' (a run has one)
    reports: dict[str, tuple[int, dict[str, str]]] = {}  # each locator's latest /diagnostics values, by status name
    unusable: list[str] = []

    def visit(m: BagMessage) -> None:
        try:
            if m.type_name.endswith("/Detection3DArray"):
                t, dets = cdr_detections3d(m.data)
                placed[m.topic][t] = dets
            elif m.type_name.endswith("/PoseStamped"):
                t, position = cdr_pose_position(m.data)
                posed[m.topic][t] = position
            elif m.type_name.endswith("/DiagnosticArray"):
                for name, values in cdr_diagnostics(m.data):
                    if name.endswith(": locator") and m.log_time >= reports.get(name, (m.log_time, {}))[0]:
                        reports[name] = (m.log_time, values)
            elif geojson is not None and SCENE_TOPIC_RE.match(m.topic):
                datums.add(Scene.from_json(cdr_string(m.data)).datum)
        except (*MALFORMED, ZebraSimError) as exc:
            unusable.append(skip_note(m, exc))

    collected = collect(paths, each=visit)
    followed, order = _locator_settings({name: values for name, (_, values) in reports.items()}, given)
    try:
        rule = LocatorConfig.from_params({**followed, **given})
    except ParameterError as exc:  # each followed value is valid alone: together, or with those given, they are not
        raise ParameterError(exc.name, exc.value, f"{exc.allowed} (with {followed}, followed from the bag's "
                             "locator's /diagnostics: give them to override)") from None
    census_topic = census_topic_re(rule)
    located: dict[tuple[str, int], list[Placed3D]] = {}
    poses: dict[tuple[str, int], tuple[float, float, float]] = {}
    recorded: dict[int, int] = {}
    graphs: set[str] = set()  # the namespaces the cameras are in
    for topic, placed_by_stamp in placed.items():
        if owner := topic_owner(topic, (rule.output,)):
            located.update(((last_name(owner[0]), t), dets) for t, dets in placed_by_stamp.items())
            graphs.add(owner[0].rsplit("/", 1)[0])
        elif census_topic.match(topic):
            recorded.update((t, len(zebra_points(animals))) for t, animals in placed_by_stamp.items())
    for topic, posed_by_stamp in posed.items():
        if not (owner := topic_owner(topic, (rule.pose,))):
            continue
        # each image's camera position: its pose's, or with poses at their own rate (pose_max_gap_s) between the two
        # about it
        drone = last_name(owner[0])
        stamps, images = sorted(posed_by_stamp), [t for d, t in located if d == drone]
        at = positions_at(stamps, np.array([posed_by_stamp[t] for t in stamps], np.float64).reshape(-1, 3), images,
                          rule.pose_max_gap_ns)
        poses.update(((drone, t), (x, y, z)) for t, (x, y, z) in zip(images, at.tolist(), strict=True)
                     if np.isfinite(x))
    bag = [str(p) for p in (paths if isinstance(paths, list) else [paths])]
    if not located:
        raise ParameterError("bag", bag, f"a bag with placed detections (<drone>/{rule.output}: recorded by up "
                             "--locate)")
    if len(graphs) > 1:
        raise ParameterError("bag", bag, f"one graph's run (its cameras are in {len(graphs)} namespaces: "
                             f"{', '.join(sorted(g or '/' for g in graphs))})")
    found = sorted({d for d, _ in located}, key=drone_order)
    if not drones and order and sorted(order, key=drone_order) == found:  # the locator's, where it names these
        drones, followed["drones"] = order, order
    cameras = list(drones) if drones else found
    if sorted(cameras) != sorted(found):
        raise ParameterError("drones", cameras, f"the bag's cameras, each once, in any order: {found}")
    by_stamp: dict[int, set[str]] = defaultdict(set)
    for d, t in located:
        if (d, t) in poses:
            by_stamp[t].add(d)
    if not by_stamp:
        raise ParameterError("bag", bag, f"a bag with the cameras' poses (<drone>/{rule.pose}, recorded by up "
                             "--locate) beside their placed detections")
    counts: dict[int, int] = {}
    animals: dict[int, list[Placed3D]] = {}  # stamp -> the animals counted, in map
    zebras = {key: zebra_points(dets) for key, dets in located.items()}
    for t, have in sorted(by_stamp.items()):
        if have != set(cameras):
            continue
        # each camera's zebras, named by their id (the locator's: the detection's index in its image's detections)
        # or, without one, their index in the placed message
        kept = [[(x.id or str(i), x) for i, x in enumerate(located[(d, t)]) if x.class_id == "zebra"]
                for d in cameras]
        scores = [np.array([x.score for _, x in k], np.float64) for k in kept]
        census = rule.census_join([zebras[(d, t)] for d in cameras], [np.array(poses[(d, t)]) for d in cameras],
                                  scores)
        counts[t] = census.count
        if geojson is None:  # the animals themselves only for the map
            continue
        animals[t] = []
        for a, (x, y, z) in enumerate(census.positions.tolist()):
            parts = [(cameras[v], *kept[v][j]) for v, j in census.points_of(a)]
            animals[t].append(Placed3D("zebra", max(p.score for _, _, p in parts), (x, y, z),
                                       ",".join(f"{d}:{name}" for d, name, _ in parts)))
    both = {t: recorded[t] for t in counts if t in recorded}
    rule_values = {k: getattr(rule, k) for k in CENSUS_RULE}
    about: dict[str, Any] = {}
    if geojson is not None:
        if datum is None:
            datum = run_datum(datums)
        elif held := [astuple(d) for d in datums if d is not None and not same_place(datum, d)]:
            raise ParameterError("datum", astuple(datum), f"no datum of its own for a bag whose scenes carry one "
                                 f"({', '.join(map(str, held))}): give it only where they carry none")
        collection = census_geojson(animals, datum, {"source": bag, "census": "recounted", "rule": rule_values,
                                                     "cameras": cameras, "pose": rule.pose})
        try:
            about = {"geojson": str(write_geojson(geojson, collection)), "datum": datum.to_dict()}
        except OSError as exc:
            why = exc.strerror or exc
            raise ParameterError("geojson", str(geojson), f"a file that can be written ({why})") from exc
    return {**about, "rule": rule_values, "cameras": cameras, "pose": rule.pose, "census_output": rule.census_output,
            "followed": followed,
            "stamps_placed": len({t for _, t in located}), "stamps_counted": len(counts),
            "recounted": census_figures(counts, collected.drones, zebras),
            "recorded": census_figures(both, collected.drones, zebras) if recorded else None,
            "recorded_stamps": len(recorded), "skipped": unusable + collected.skipped, "damaged": collected.damaged}
