"""Scores from a bag: recorded detections against recorded labels, per drone, COCO-style mAP.

Labels (``/<drone>/labels``) and detections (``/<drone>/detections``) are std_msgs/String JSON; they are
matched by the stamp inside each message (the image's), so a replayed run's detections are scored against
the labels of the same frames. Only kept labels count as ground truth, as in the datasets; zebras the labeller
saw but dropped are don't-care regions (a detection on one is neither right nor wrong), as in ``zebra-sim val``.
"""

from __future__ import annotations

import json
import re
import struct
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from zebra_sim_ros.dataset.coco import is_dont_care
from zebra_sim_ros.detection.metrics import evaluate_detections
from zebra_sim_ros.recording.reader import BagMessage, BagReader


def cdr_string(data: bytes) -> str:
    """The ``data`` field of a CDR-serialized std_msgs/String (little- or big-endian encapsulation)."""
    little = data[1] == 1
    (n,) = struct.unpack("<I" if little else ">I", data[4:8])
    return data[8:8 + n - 1].decode("utf-8")  # the length counts the terminating NUL


class _Cdr:
    """A minimal little/big-endian CDR reader (offsets aligned from the start of the payload)."""

    def __init__(self, data: bytes) -> None:
        self.data, self.pos = data, 4
        self.end = "<" if data[1] == 1 else ">"

    def _align(self, n: int) -> None:
        self.pos += (-(self.pos - 4)) % n

    def u32(self) -> int:
        self._align(4)
        (v,) = struct.unpack_from(self.end + "I", self.data, self.pos)
        self.pos += 4
        return int(v)

    def u8(self) -> int:
        v = self.data[self.pos]
        self.pos += 1
        return v

    def string(self) -> str:
        n = self.u32()
        v = self.data[self.pos:self.pos + n - 1].decode("utf-8")
        self.pos += n
        return v

    def blob(self) -> bytes:
        n = self.u32()
        v = self.data[self.pos:self.pos + n]
        self.pos += n
        return v


def _stamp_of(r: _Cdr) -> int:
    sec, nanosec = r.u32(), r.u32()
    if sec >= 2**31:
        sec -= 2**32
    return sec * 1_000_000_000 + nanosec


def header_stamp_ns(data: bytes) -> int:
    """The stamp of a CDR-serialized message that starts with a std_msgs/Header (Image, CameraInfo, ...), in ns,
    without touching the rest of it."""
    return _stamp_of(_Cdr(data))


def cdr_image(data: bytes) -> tuple[int, int, int, str, int, bytes]:
    """(stamp ns, height, width, encoding, step, pixel bytes) of a CDR-serialized sensor_msgs/Image."""
    r = _Cdr(data)
    t = _stamp_of(r)
    r.string()  # frame_id
    height, width = r.u32(), r.u32()
    encoding = r.string()
    r.u8()  # is_bigendian
    step = r.u32()
    return t, height, width, encoding, step, r.blob()


def rgb_image(data: bytes) -> tuple[int, np.ndarray] | None:
    """(stamp ns, H x W x 3 RGB array) of a CDR-serialized rgb8 or bgr8 sensor_msgs/Image; None for other
    encodings."""
    t, height, width, encoding, step, pixels = cdr_image(data)
    if encoding not in ("rgb8", "bgr8"):
        return None
    a = np.frombuffer(pixels, np.uint8).reshape(height, step)[:, : width * 3].reshape(height, width, 3)
    return t, np.ascontiguousarray(a[..., ::-1] if encoding == "bgr8" else a)


def json_stamp_ns(d: dict[str, Any]) -> int:
    """The ``{"stamp": {"sec", "nanosec"}}`` of a scene, labels or detections JSON, in ns."""
    return int(d["stamp"]["sec"]) * 1_000_000_000 + int(d["stamp"]["nanosec"])


# What reading a malformed message raises: broken CDR (struct.error, IndexError), bad UTF-8 or JSON (ValueError),
# missing or mistyped fields (KeyError, TypeError). Such a message is noted and skipped; the rest still counts.
MALFORMED = (ValueError, KeyError, TypeError, IndexError, struct.error)


def skip_note(m: BagMessage, why: str | BaseException) -> str:
    """One line naming a message that was skipped, and why."""
    reason = f"{type(why).__name__}: {why}" if isinstance(why, BaseException) else why
    return f"{m.topic} at log time {m.log_time} ns: {reason}"


def _no_frames() -> dict[str, Any]:
    """One drone's entry in :func:`collect`'s ``drones`` before any of its messages."""
    return {"labels": {}, "ignore": {}, "detections": {}, "log_times": {"labels": {}, "detections": {}}}


def collect(paths: list[str | Path] | str | Path, detections_suffix: str = "detections",
            each: Callable[[BagMessage], None] | None = None) -> dict[str, Any]:
    """Per drone: ``{"labels": {stamp: gt boxes (n, 4)}, "ignore": {stamp: don't-care boxes (k, 4)},
    "detections": {stamp: (m, 5)}, "log_times": {"labels": {stamp: first log time}, "detections": {...}}}`` from a
    bag; ``each`` sees every message of the same pass (so
    callers needing more from the bag do not read it twice).

    A labels or detections message that does not parse is skipped and noted in ``"skipped"``; damage to the
    file itself is in ``"damaged"``."""
    reader = BagReader.open(paths)
    out: dict[str, dict[str, Any]] = defaultdict(_no_frames)
    skipped: list[str] = []
    pat = re.compile(rf"^/(?P<drone>[^/]+)/(?P<kind>labels|{re.escape(detections_suffix)})$")
    for m in reader.messages():
        if each is not None:
            each(m)
        match = pat.match(m.topic)
        if not match or m.type_name != "std_msgs/msg/String":
            continue
        drone = match.group("drone")
        try:
            d = json.loads(cdr_string(m.data))
            t = json_stamp_ns(d)
            if match.group("kind") == "labels":
                kind, rows = "labels", np.array([z["box_visible"] for z in d["zebras"] if z["kept"]], np.float64)
                ignore = np.array([z["box_visible"] for z in d["zebras"] if is_dont_care(z)], np.float64)
                out[drone][kind][t] = rows.reshape(-1, 4)
                out[drone]["ignore"][t] = ignore.reshape(-1, 4)
            else:
                kind, rows = "detections", np.array([[*x["box_xyxy"], x["score"]] for x in d["detections"]],
                                                    np.float64)
                out[drone][kind][t] = rows.reshape(-1, 5)
            out[drone]["log_times"][kind].setdefault(t, m.log_time)
        except MALFORMED as exc:
            skipped.append(skip_note(m, exc))
    return {"drones": dict(out), "damaged": reader.stopped, "skipped": skipped}


class ImageDetector:
    """A :func:`collect` visitor that runs a detector over every ``/<drone>/image_raw`` (rgb8 or bgr8) in batches
    during the same pass; :meth:`apply` then puts its detections in place of the recorded ones."""

    TOPIC = re.compile(r"^/(?P<drone>[^/]+)/image_raw$")

    def __init__(self, weights: str | Path | None, device: str = "auto", batch: int = 8, conf: float = 0.001,
                 imgsz: int | None = None, scale: float = 0.0) -> None:
        from zebra_sim_ros.detection.checkpoint import load_model, select_device

        self.model, _ = load_model(weights, select_device(device))
        # as detect() takes them: imgsz None and scale 0 = the checkpoint's rule, imgsz -1 = native
        self.batch, self.conf, self.imgsz, self.scale = batch, conf, imgsz, scale
        self.detections: dict[str, dict[int, np.ndarray]] = defaultdict(dict)
        self.skipped: list[str] = []
        self._pending: list[tuple[str, int, np.ndarray]] = []

    def __call__(self, m: BagMessage) -> None:
        match = self.TOPIC.match(m.topic)
        if not match:
            return
        try:
            image = rgb_image(m.data)
        except MALFORMED as exc:
            self.skipped.append(skip_note(m, exc))
            return
        if image is None:
            self.skipped.append(skip_note(m, "not rgb8 or bgr8"))
            return
        self._pending.append((match.group("drone"), *image))
        if len(self._pending) >= self.batch:
            self._flush()

    def _flush(self) -> None:
        from zebra_sim_ros.detection.predict import detect

        if not self._pending:
            return
        dets = detect(self.model, [p[2] for p in self._pending], self.imgsz, conf=self.conf, max_det=100,
                      scale=self.scale)
        for (drone, t, _), det in zip(self._pending, dets, strict=True):
            self.detections[drone][t] = det[:, :5].astype(np.float64)
        self._pending.clear()

    def apply(self, collected: dict[str, Any]) -> dict[str, Any]:
        """``collected`` with its detections replaced by this detector's (drones with images but no labels
        included) and the images it could not use added to ``"skipped"``."""
        self._flush()
        for d in collected["drones"].values():
            d["detections"] = {}
        for drone, dets in self.detections.items():
            collected["drones"].setdefault(drone, _no_frames())["detections"] = dict(dets)
        collected["skipped"] = collected.get("skipped", []) + self.skipped
        return collected


def score(collected: dict[str, Any]) -> dict[str, Any]:
    """mAP50 and mAP50-95 per drone and over all drones, on the frames that have both labels and detections."""
    result: dict[str, Any] = {}
    all_p, all_g, all_i = [], [], []
    for drone, d in sorted(collected["drones"].items()):
        stamps = sorted(set(d["labels"]) & set(d["detections"]))
        preds = [d["detections"][s] for s in stamps]
        gts = [d["labels"][s] for s in stamps]
        ignores = [d["ignore"][s] for s in stamps]  # collect writes a stamp's labels and don't-care boxes together
        all_p += preds
        all_g += gts
        all_i += ignores
        m = evaluate_detections(preds, gts, ignores=ignores)
        result[drone] = {"frames": len(stamps), "unmatched_labels": len(set(d["labels"]) - set(stamps)),
                         "unmatched_detections": len(set(d["detections"]) - set(stamps)), **m.to_dict()}
    result["all"] = evaluate_detections(all_p, all_g, ignores=all_i).to_dict() if all_g else None
    result["damaged"] = collected["damaged"]
    result["skipped"] = collected.get("skipped", [])
    return result
