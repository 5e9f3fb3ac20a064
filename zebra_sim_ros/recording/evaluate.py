"""Scores from a bag: recorded detections against recorded labels, per drone, COCO-style mAP.

Labels (``/<drone>/labels``) and detections (``/<drone>/detections``) are std_msgs/String JSON of the typed
messages :class:`~zebra_sim_ros.messages.Labels` and :class:`~zebra_sim_ros.messages.Detections`; they are
matched by the stamp inside each message (the image's), so a replayed run's detections are scored against the
labels of the same frames. This module reads the bag (:mod:`~zebra_sim_ros.recording.cdr`) and hands typed
frames to :mod:`zebra_sim_ros.detection.scoring`, which knows nothing of bags; ``ImageDetector`` can run a
detector over the recorded images in the same pass.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from zebra_sim_ros.detection.scoring import COUNT_CONF, DroneFrames, score_drones
from zebra_sim_ros.errors import ZebraSimError
from zebra_sim_ros.messages import Detections, Labels
from zebra_sim_ros.recording.cdr import MALFORMED, cdr_detections, cdr_string
from zebra_sim_ros.recording.images import message_rgb
from zebra_sim_ros.recording.reader import CAMERA_IMAGES, BagMessage, BagReader, last_name, topic_owner


def skip_note(m: BagMessage, why: str | BaseException) -> str:
    """One line naming a message that was skipped, and why."""
    reason = f"{type(why).__name__}: {why}" if isinstance(why, BaseException) else why
    return f"{m.topic} at log time {m.log_time} ns: {reason}"


@dataclass
class Collected:
    """What :func:`collect` read from a bag: the typed frames per drone, when each stamp's labels and detections
    first arrived per drone (their publish times, wall clock, ns), and what could not be used."""

    drones: dict[str, DroneFrames] = field(default_factory=lambda: defaultdict(DroneFrames))
    arrivals: dict[str, dict[str, dict[int, int]]] = field(
        default_factory=lambda: defaultdict(lambda: {"labels": {}, "detections": {}}))
    damaged: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)


def collect(paths: list[str | Path] | str | Path, detections_suffix: str = "detections",
            each: Callable[[BagMessage], None] | None = None) -> Collected:
    """The labels and detections of a bag per drone and stamp; ``each`` sees every message of the same pass (so
    callers needing more from the bag do not read it twice).

    A labels or detections message that does not parse is skipped and noted in ``skipped``; damage to the file
    itself is in ``damaged``."""
    reader = BagReader.open(paths)
    out = Collected()
    kinds = ("labels", detections_suffix)
    for m in reader.messages():
        if each is not None:
            each(m)
        owner = topic_owner(m.topic, kinds)
        typed = m.type_name.endswith("/msg/Detection2DArray")
        if not owner or not (typed or m.type_name == "std_msgs/msg/String"):
            continue
        drone = last_name(owner[0])
        try:
            if owner[1] == "labels":
                kind, labels = "labels", Labels.from_json(cdr_string(m.data))
                t = labels.stamp.ns
                out.drones[drone].labels[t] = labels
            else:  # typed (Detection2DArray), or the JSON of bags recorded before it
                kind, dets = "detections", cdr_detections(m.data) if typed else Detections.from_json(cdr_string(m.data))
                t = dets.stamp.ns
                out.drones[drone].detections[t] = np.array(  # zebras only: a model may also find other animals
                    [[*x.box_xyxy, x.score] for x in dets.detections if x.class_name == "zebra"],
                    np.float64).reshape(-1, 5)
            out.arrivals[drone][kind].setdefault(t, m.publish_time)
        except (*MALFORMED, ZebraSimError) as exc:
            out.skipped.append(skip_note(m, exc))
    out.damaged = reader.stopped
    return out


class ImageDetector:
    """A :func:`collect` visitor that runs a detector over every ``/<drone>/image_raw`` (rgb8 or bgr8) and
    ``/<drone>/image_raw/compressed`` (jpeg or png) in batches during the same pass; :meth:`apply` then puts its
    detections in place of the recorded ones. A drone's stamp recorded both ways is detected from ``image_raw`` (the
    pixels before compression); an image that comes again on the same topic (a second bag of the same stamps)
    replaces the first, as a second labels message does."""

    def __init__(self, weights: str | Path | None, device: str = "auto", batch: int = 8, conf: float = 0.001,
                 imgsz: int | None = None, scale: float = 0.0, verifier: str = "", amp: str = "off") -> None:
        from zebra_sim_ros.detection.checkpoint import load_model, select_device
        from zebra_sim_ros.detection.verify import load_verifier

        dev = select_device(device)
        self.model, _ = load_model(weights, dev, amp=amp)
        self.verifier = load_verifier(verifier, dev, "--verifier")[0] if verifier else None
        # as detect() takes them: imgsz None and scale 0 = the checkpoint's rule, imgsz -1 = native
        self.batch, self.conf, self.imgsz, self.scale = batch, conf, imgsz, scale
        self.detections: dict[str, dict[int, np.ndarray]] = defaultdict(dict)
        self.skipped: list[str] = []
        self._pending: dict[tuple[str, int], np.ndarray] = {}  # (drone, stamp): the RGB image to detect
        self._raw: set[tuple[str, int]] = set()  # (drone, stamp) detected or pending from image_raw

    def __call__(self, m: BagMessage) -> None:
        owner = topic_owner(m.topic, CAMERA_IMAGES)
        if not owner:
            return
        try:
            image = message_rgb(m.type_name, m.data)
        except MALFORMED as exc:
            self.skipped.append(skip_note(m, exc))
            return
        if image is None:
            self.skipped.append(skip_note(m, "not a colour image (rgb8 or bgr8; jpeg or png compressed)"))
            return
        key = (last_name(owner[0]), image[0])
        if owner[1] != "image_raw":  # image_raw/compressed
            if key in self._raw:  # the raw image of this frame is detected: not its compressed copy too
                return
        else:
            self._raw.add(key)
        self._pending[key] = image[1]  # a later image of a key replaces a waiting one; a detected one, in _flush
        if len(self._pending) >= self.batch:
            self._flush()

    def _flush(self) -> None:
        from zebra_sim_ros.detection.metrics import MAX_DETECTIONS
        from zebra_sim_ros.detection.model import ZEBRA
        from zebra_sim_ros.detection.predict import detect

        if not self._pending:
            return
        dets = detect(self.model, list(self._pending.values()), self.imgsz, conf=self.conf, max_det=MAX_DETECTIONS,
                      scale=self.scale, verifier=self.verifier)
        for (drone, t), det in zip(self._pending, dets, strict=True):
            self.detections[drone][t] = det[det[:, 5] == ZEBRA, :5].astype(np.float64)
        self._pending.clear()

    def apply(self, collected: Collected) -> Collected:
        """``collected`` with its detections replaced by this detector's (drones with images but no labels
        included) and the images it could not use added to ``skipped``."""
        self._flush()
        for frames in collected.drones.values():
            frames.detections = {}
        for drone, dets in self.detections.items():
            collected.drones[drone].detections = dict(dets)
        collected.skipped += self.skipped
        return collected


def score(collected: Collected, count_conf: float = COUNT_CONF) -> dict[str, Any]:
    """mAP50 and mAP50-95 per drone and over all drones, and the zebras counted with the detections at
    ``count_conf`` or above (:func:`~zebra_sim_ros.detection.scoring.score_drones`), with what was damaged or
    skipped."""
    return {**score_drones(collected.drones, count_conf=count_conf), "damaged": collected.damaged,
            "skipped": collected.skipped}
