"""What a run of the whole graph did, read back from its bag: frames per drone, detection scores against the live
ground truth, throughput, time per stage and end-to-end latency, and a preview image.

Times are the recorder's receive times (each message's ``publish_time``, wall clock; log times are the simulated
stamps) of the messages of one step, matched by the scene's
stamp: render = scene -> last ``image_raw`` of the step, label = ``image_raw`` -> ``labels``, detect =
``image_raw`` -> ``detections`` (per drone), end to end = scene -> last ``detections`` of the step. A bag with
``image_raw/compressed`` instead (``up --bag-images jpeg``) times its images by that copy, which the camera
publishes after the raw image, depth, masks and its encoding: render reads longer, label and detect shorter.
"""

from __future__ import annotations

import re
from collections import defaultdict
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from zebra_sim_ros.detection.config import LocatorConfig
from zebra_sim_ros.detection.scoring import COUNT_CONF, DroneFrames
from zebra_sim_ros.errors import ParameterError, ZebraSimError
from zebra_sim_ros.geometry.locate import nearest_distances, placing_figures
from zebra_sim_ros.messages import Datum, Scene
from zebra_sim_ros.placement.config import ANIMALS_TOPIC
from zebra_sim_ros.recording.cdr import MALFORMED, Placed3D, cdr_detections3d, cdr_string, header_stamp_ns
from zebra_sim_ros.recording.census import (
    SCENE_TOPIC_RE,
    census_figures,
    census_geojson,
    census_topic_re,
    drone_order,
    run_datum,
    write_geojson,
    zebra_points,
)
from zebra_sim_ros.recording.evaluate import collect, score, skip_note
from zebra_sim_ros.recording.images import message_rgb
from zebra_sim_ros.recording.reader import CAMERA_IMAGES, BagMessage, last_name, topic_owner, under_any_namespace

_DRONE = re.compile(r"drone_\d+")  # a camera of the graph (up's drone_0 ... drone_N-1), under any namespace
_ANIMALS_TOPIC = under_any_namespace(ANIMALS_TOPIC)  # the placed animals (Detection3DArray)


PREVIEW_COLUMNS = 4  # drones per row of the preview (a row of 16 4K frames is past JPEG's 65535 px)


def _median_ms(values: list[float]) -> float | None:
    return round(float(np.median(values)) * 1e3, 1) if values else None


def _stage_seconds(scenes: dict[int, int], times: dict[str, dict[str, dict[int, int]]]) -> dict[str, list[float]]:
    """Per step, s: render (scene -> its last image), label and detect (image -> its labels, detections; per
    drone) and end to end (scene -> the last detections, where every drone's arrived), from log times by stamp."""
    drones = sorted(times, key=drone_order)
    out: dict[str, list[float]] = {"render": [], "label": [], "detect": [], "end_to_end": []}
    for s, t0 in scenes.items():
        imgs = [times[d]["image_raw"][s] for d in drones if s in times[d]["image_raw"]]
        if imgs:
            out["render"].append((max(imgs) - t0) / 1e9)
        for d in drones:
            ti = times[d]["image_raw"].get(s)
            for stage, kind in (("label", "labels"), ("detect", "detections")):
                if ti is not None and s in times[d][kind]:
                    out[stage].append((times[d][kind][s] - ti) / 1e9)
        dets = [times[d]["detections"][s] for d in drones if s in times[d]["detections"]]
        if len(dets) == len(drones) and dets:
            out["end_to_end"].append((max(dets) - t0) / 1e9)
    return out


def summarize_run(bag: str | Path | list[str | Path], preview: str | Path | None = None, count_conf: float = COUNT_CONF,
                  geojson: str | Path | None = None, locator: LocatorConfig | None = None) -> dict[str, Any]:
    """Summary of the run recorded in ``bag`` (a file, or a split recording's files in order), the zebras counted
    at ``count_conf`` (the scorer's); writes ``preview`` (one tile per drone) when given, and ``geojson``, the
    locator's census on the Earth by the scenes' datum, when given and the run has a census (``census_geojson`` in
    the summary: its path). The placed detections and the census are read from ``locator``'s topics (the graph's
    locator; default: the locator's defaults)."""
    locator = locator or LocatorConfig()
    located_topics, census_topic = (locator.output,), census_topic_re(locator)
    scenes: dict[int, int] = {}  # stamp -> log time
    datums: set[Datum | None] = set()  # the scenes' (a run has one; None: scenes from before they carried it)
    times: dict[str, dict[str, dict[int, int]]] = defaultdict(lambda: defaultdict(dict))  # drone -> kind -> stamp
    latest: dict[str, tuple[int, str, bytes]] = {}  # drone -> (stamp, type, serialized image): decoded at the end

    unusable: list[str] = []  # scenes and images that do not parse (collect notes bad labels and detections)
    placed_raw: dict[int, BagMessage] = {}  # stamp -> the placed animals (zebra_sim/zebras), read with --locate only
    located: dict[tuple[str, int], np.ndarray] = {}  # (drone, stamp) -> its detections placed on the map
    census: dict[int, list[Placed3D]] = {}  # stamp -> the animals the locator's census counted in it

    def visit(m: BagMessage) -> None:  # scenes and images; collect itself parses labels and detections
        image = topic_owner(m.topic, CAMERA_IMAGES)
        drone = last_name(image[0]) if image else ""
        try:
            if SCENE_TOPIC_RE.match(m.topic):
                scene = Scene.from_json(cdr_string(m.data))
                scenes[scene.stamp.ns] = m.publish_time
                datums.add(scene.datum)
            elif _ANIMALS_TOPIC.match(m.topic):
                placed_raw[header_stamp_ns(m.data)] = m
            elif census_topic.match(m.topic):
                t, animals = cdr_detections3d(m.data)
                census[t] = animals
            elif owner := topic_owner(m.topic, located_topics):
                t, dets = cdr_detections3d(m.data)
                located[(last_name(owner[0]), t)] = zebra_points(dets)
            elif _DRONE.fullmatch(drone):
                t = header_stamp_ns(m.data)
                if t >= latest.get(drone, (-1, "", b""))[0]:
                    latest[drone] = (t, m.type_name, m.data)
                seen = times[drone]["image_raw"]
                seen[t] = min(seen.get(t, m.publish_time), m.publish_time)  # the earliest of a frame's copies
        except (*MALFORMED, ZebraSimError) as exc:
            unusable.append(skip_note(m, exc))

    sources = [str(b) for b in bag] if isinstance(bag, list) else [str(bag)]  # a split recording's pieces
    collected = collect(bag, each=visit)  # one pass over the bag for the scores and the timings
    for drone, log_times in collected.arrivals.items():
        times[drone].update(log_times)
    drones = sorted(times, key=drone_order)
    frames = {d: {k: len(times[d][k]) for k in ("image_raw", "labels", "detections")} for d in drones}
    stages = _stage_seconds(scenes, times)
    ends = [t for d in drones for t in times[d]["detections"].values()]
    span = (max(ends) - min(scenes.values())) / 1e9 if ends and scenes else 0.0
    images = sum(f["detections"] for f in frames.values())
    scores = score(collected, count_conf)
    out: dict[str, Any] = {
        "bag": sources[0], "bags": sources, "steps": len(scenes), "frames": frames,
        "scores": {k: v for k, v in scores.items() if k not in ("damaged", "skipped")}, "damaged": scores["damaged"],
        "skipped": unusable + scores["skipped"],
        "seconds": round(span, 3), "frames_per_s": round(images / span, 3) if span > 0 else None,
        "steps_per_s": round(len(scenes) / span, 3) if span > 0 else None,
        "median_ms": {k: _median_ms(v) for k, v in stages.items()},
    }
    images_rgb = {}
    for d, (_, type_name, data) in latest.items():
        try:
            if (rgb := message_rgb(type_name, data)) is not None:
                images_rgb[d] = rgb
        except (*MALFORMED, ValueError):
            pass  # its pixels are cut short, or do not decode: no tile for this drone
    if located:  # up --locate: each zebra detection on the map against the nearest zebra placed in its step
        placed: dict[int, np.ndarray] = {}  # stamp -> the placed zebras' box centres
        for t in sorted({t for _, t in located} & set(placed_raw)):
            try:
                placed[t] = zebra_points(cdr_detections3d(placed_raw[t].data)[1])
            except (*MALFORMED, ZebraSimError) as exc:
                out["skipped"].append(skip_note(placed_raw[t], exc))
        gaps = [nearest_distances(p, placed[t]) for (_, t), p in located.items() if t in placed]
        out["located"] = {"frames": len(located), "detections": sum(len(p) for p in located.values()),
                          "frames_with_placed": len(gaps), "pose": locator.pose,
                          **placing_figures(np.concatenate(gaps) if gaps else np.zeros(0))}
    if census:  # the zebras counted once across the drones against the distinct zebras labelled by any of them
        out["census"] = census_figures({t: len(zebra_points(a)) for t, a in census.items()}, collected.drones,
                                       located)
        if geojson is not None:
            try:
                out["census_geojson"] = str(write_geojson(geojson, census_geojson(
                    census, run_datum(datums), {"source": sources, "census": "the locator's, as published",
                                                "pose": locator.pose})))
            except ParameterError as exc:  # scenes without their datum: the figures still come
                out["census_geojson_error"] = str(exc)
            except OSError as exc:  # a full disk: the figures still come
                out["census_geojson_error"] = f"{exc.strerror or exc}: {geojson}"
    if preview is not None and images_rgb:
        out["preview"] = str(write_preview(preview, collected.drones, images_rgb))
    return out


def write_preview(path: str | Path, c: dict[str, DroneFrames], images: dict[str, tuple[int, np.ndarray]]) -> Path:
    """One tile per drone, :data:`PREVIEW_COLUMNS` to a row: its last RGB frame with ground-truth boxes (green) and
    detections (red, with score); ``c``: the frames per drone (:func:`~zebra_sim_ros.recording.evaluate.collect`)."""
    tiles = []
    for drone in sorted(images, key=drone_order):
        t, rgb = images[drone]
        bgr = np.ascontiguousarray(rgb[..., ::-1])
        font = max(0.3, bgr.shape[1] / 1280 * 0.5)
        scores = bgr.shape[1] >= 640  # scores would bury the boxes in small images
        frames = c.get(drone, DroneFrames())
        for x0, y0, x1, y1 in frames.truth(t)[0]:
            cv2.rectangle(bgr, (round(x0), round(y0)), (round(x1), round(y1)), (60, 220, 60), 1)
        for x0, y0, x1, y1, s in frames.detections.get(t, np.zeros((0, 5))):
            cv2.rectangle(bgr, (round(x0) - 1, round(y0) - 1), (round(x1) + 1, round(y1) + 1), (40, 40, 230), 1)
            if scores:
                cv2.putText(bgr, f"{s:.2f}", (round(x0), max(round(y0) - 3, 8)), cv2.FONT_HERSHEY_SIMPLEX,
                            0.7 * font, (40, 40, 230), 1, cv2.LINE_AA)
        legend = f"{drone}  green: ground truth  red: detected" if scores else drone
        cv2.putText(bgr, legend, (6, round(40 * font)), cv2.FONT_HERSHEY_SIMPLEX, font, (255, 255, 255), 1, cv2.LINE_AA)
        tiles.append(bgr)
    h = min(t.shape[0] for t in tiles)
    tiles = [cv2.resize(t, (round(t.shape[1] * h / t.shape[0]), h)) for t in tiles]
    rows = [tiles[k:k + PREVIEW_COLUMNS] for k in range(0, len(tiles), PREVIEW_COLUMNS)]  # 16 drones: 4 rows of 4
    width = max(sum(t.shape[1] for t in r) for r in rows)
    sheet = np.concatenate([np.pad(np.concatenate(r, axis=1), ((0, 0), (0, width - sum(t.shape[1] for t in r)), (0, 0)))
                            for r in rows], axis=0)
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(p), sheet):
        raise OSError(f"cannot write the preview {p}")
    return p
