"""Scores from a bag: recorded detections against recorded labels, per drone, COCO-style mAP.

Labels (``/<drone>/labels``) and detections (``/<drone>/detections``) are std_msgs/String JSON; they are
matched by the stamp inside each message (the image's), so a replayed run's detections are scored against
the labels of the same frames. Only kept labels count as ground truth, as in the datasets.
"""

from __future__ import annotations

import json
import re
import struct
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from zebra_sim_ros.detection.metrics import evaluate_detections
from zebra_sim_ros.recording.reader import BagReader


def cdr_string(data: bytes) -> str:
    """The ``data`` field of a CDR-serialized std_msgs/String (little- or big-endian encapsulation)."""
    little = data[1] == 1
    (n,) = struct.unpack("<I" if little else ">I", data[4:8])
    return data[8:8 + n - 1].decode("utf-8")  # the length counts the terminating NUL


def _stamp(d: dict[str, Any]) -> int:
    return int(d["stamp"]["sec"]) * 1_000_000_000 + int(d["stamp"]["nanosec"])


def collect(paths: list[str | Path] | str | Path, detections_suffix: str = "detections") -> dict[str, Any]:
    """Per drone: ``{"labels": {stamp: gt boxes (n, 4)}, "detections": {stamp: (m, 5)}}`` from a bag."""
    reader = BagReader.open(paths)
    out: dict[str, dict[str, dict[int, np.ndarray]]] = defaultdict(lambda: {"labels": {}, "detections": {}})
    pat = re.compile(rf"^/(?P<drone>[^/]+)/(?P<kind>labels|{re.escape(detections_suffix)})$")
    for m in reader.messages():
        match = pat.match(m.topic)
        if not match or m.type_name != "std_msgs/msg/String":
            continue
        d = json.loads(cdr_string(m.data))
        drone = match.group("drone")
        if match.group("kind") == "labels":
            boxes = [z["box_visible"] for z in d["zebras"] if z["kept"]]
            out[drone]["labels"][_stamp(d)] = np.array(boxes, dtype=np.float64).reshape(-1, 4)
        else:
            dets = [[*x["box_xyxy"], x["score"]] for x in d["detections"]]
            out[drone]["detections"][_stamp(d)] = np.array(dets, dtype=np.float64).reshape(-1, 5)
    return {"drones": dict(out), "damaged": reader.stopped}


def detect_images(paths: list[str | Path] | str | Path, collected: dict[str, Any], weights: str | Path | None,
                  device: str = "auto", batch: int = 8, conf: float = 0.001) -> dict[str, Any]:
    """Replace recorded detections by running a detector over the bag's ``/<drone>/image_raw`` (rgb8 or bgr8).

    ``decode`` needs rclpy's serialization, imported here so the rest of this module stays ROS-free.
    """
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import Image

    from zebra_sim_ros.detection.checkpoint import load_model, select_device
    from zebra_sim_ros.detection.predict import detect

    model, _ = load_model(weights, select_device(device))
    pat = re.compile(r"^/(?P<drone>[^/]+)/image_raw$")
    for d in collected["drones"].values():
        d["detections"] = {}
    pending: list[tuple[str, int, np.ndarray]] = []

    def flush() -> None:
        dets = detect(model, [p[2] for p in pending], conf=conf, max_det=100)
        for (drone, t, _), det in zip(pending, dets, strict=True):
            collected["drones"].setdefault(drone, {"labels": {}, "detections": {}})["detections"][t] = \
                det[:, :5].astype(np.float64)
        pending.clear()

    reader = BagReader.open(paths)
    for m in reader.messages():
        match = pat.match(m.topic)
        if not match:
            continue
        img = deserialize_message(m.data, Image)
        if img.encoding not in ("rgb8", "bgr8"):
            continue
        a = np.frombuffer(bytes(img.data), np.uint8).reshape(img.height, img.step)[:, : img.width * 3]
        a = a.reshape(img.height, img.width, 3)
        a = np.ascontiguousarray(a[..., ::-1] if img.encoding == "bgr8" else a)
        pending.append((match.group("drone"), img.header.stamp.sec * 1_000_000_000 + img.header.stamp.nanosec, a))
        if len(pending) >= batch:
            flush()
    if pending:
        flush()
    collected["damaged"] = collected["damaged"] + reader.stopped
    return collected


def score(collected: dict[str, Any]) -> dict[str, Any]:
    """mAP50 and mAP50-95 per drone and over all drones, on the frames that have both labels and detections."""
    result: dict[str, Any] = {}
    all_p, all_g = [], []
    for drone, d in sorted(collected["drones"].items()):
        stamps = sorted(set(d["labels"]) & set(d["detections"]))
        preds = [d["detections"][s] for s in stamps]
        gts = [d["labels"][s] for s in stamps]
        all_p += preds
        all_g += gts
        m = evaluate_detections(preds, gts)
        result[drone] = {"frames": len(stamps), "unmatched_labels": len(set(d["labels"]) - set(stamps)),
                         "unmatched_detections": len(set(d["detections"]) - set(stamps)), **m.to_dict()}
    result["all"] = evaluate_detections(all_p, all_g).to_dict() if all_g else None
    result["damaged"] = collected["damaged"]
    return result
