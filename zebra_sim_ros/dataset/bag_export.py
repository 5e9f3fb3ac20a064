"""A recorded run as a YOLO dataset (``zebra-sim bag export BAG --out DIR``): each camera image of the bag with the
labeller's labels of the same frame, so that ``zebra-sim train`` and ``val`` read a live graph's run as they read
``generate``'s sets.

Pairs ``<drone>/image_raw`` (rgb8 or bgr8), or ``<drone>/image_raw/compressed`` (jpeg or png), with
``<drone>/labels`` by the image's stamp, and writes, as ``generate`` lays a set out::

    DIR/images/{train,val}/<bag>_<camera>_<stamp>.jpg   the image (see below)
    DIR/labels/{train,val}/<same>.txt                   YOLO lines of the kept zebras (visible boxes)
    DIR/ignore/{train,val}/<same>.txt                   the zebras seen but not kept: don't-care regions for val
    DIR/dataset.yaml                                    path, train, val, names (0: zebra)

``<camera>`` is the topic's namespace with ``/`` as ``_`` (``drone_0``, ``g1_drone_0``). A stamp older than the
last of its camera starts a new run in the bag (a restarted placer, a looping replay): its frames get ``_r<run>``,
so no run's labels pair with another's images; a step sent again replaces its frame. Raw images are written as jpg
(``jpeg_quality``) or png; compressed ones as recorded where the file reads back in the colours recorded (a codec
holding BGR or grey, the bytes a JPEG or PNG), else decoded and written as raw ones are.

Two passes over the bag: the labels (small) first, then each image written as it is read, so memory does not grow
with the bag. A step's frames go to one split, drawn from the step and ``seed`` (``val_fraction`` of the steps to
val, and at least one step to each split when there are two or more). Images without labels (and labels without an
image) are counted, not written; a message that does not parse, or an image whose size is not its labels', is noted
and skipped; a damaged bag gives what is intact. No COCO file: the masks are not in the bag.
"""

from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from zebra_sim_ros.dataset.coco import yolo_lines
from zebra_sim_ros.errors import ParameterError, ZebraSimError
from zebra_sim_ros.messages import Labels
from zebra_sim_ros.recording.cdr import MALFORMED, cdr_compressed_image, cdr_string, header_stamp_ns, rgb_image
from zebra_sim_ros.recording.evaluate import skip_note
from zebra_sim_ros.recording.images import COMPRESSED_TYPE, IMAGE_TYPE, decompress_rgb
from zebra_sim_ros.recording.reader import BagMessage, BagReader

_TOPIC = re.compile(r"^(?P<camera>(?:/[^/]+)*/[^/]+)/(?P<kind>image_raw(?:/compressed)?|labels)$")
FORMATS = ("jpg", "png")
_MAGIC = {"jpg": b"\xff\xd8\xff", "png": b"\x89PNG\r\n\x1a\n"}

Key = tuple[int, str, int, int]  # (bag index, camera, run, stamp ns)


@dataclass(frozen=True)
class ExportConfig:
    """Settings of an export."""

    bags: tuple[str, ...]
    out: str
    image_format: str = "jpg"  # how raw images are written (compressed ones as recorded where they can be)
    jpeg_quality: int = 95
    val_fraction: float = 0.2
    seed: int = 0

    def check(self) -> None:
        """Raise :class:`ParameterError` naming the first bad setting."""
        if not self.bags:
            raise ParameterError("BAG", "", "one or more bag files")
        if self.image_format not in FORMATS:
            raise ParameterError("--format", self.image_format, " or ".join(FORMATS))
        if not 1 <= self.jpeg_quality <= 100:
            raise ParameterError("--jpeg-quality", self.jpeg_quality, "1..100")
        if not 0.0 <= self.val_fraction < 1.0:
            raise ParameterError("--val-fraction", self.val_fraction, "0 <= f < 1")
        if self.seed < 0:
            raise ParameterError("--seed", self.seed, ">= 0")
        out = Path(self.out)
        if out.exists() and (not out.is_dir() or any(out.iterdir())):
            raise ParameterError("--out", self.out, "a new or empty folder (frames of another export would mix in)")


def step_draw(seed: int, step: tuple[int, int, int]) -> float:
    """A step's uniform draw in [0, 1) from ``seed`` and the step (bag index, run, stamp)."""
    return int.from_bytes(hashlib.sha256(f"{seed}:{step}".encode()).digest()[:8], "big") / 2**64


def split_steps(steps: set[tuple[int, int, int]], seed: int, val_fraction: float) -> dict[tuple[int, int, int], str]:
    """Each step's split: val where its draw is under ``val_fraction``; with two steps or more and a fraction above
    0, the step of the lowest draw is val and the one of the highest train even if the draws put none there."""
    draws = sorted((step_draw(seed, s), s) for s in steps)
    out = {s: "val" if d < val_fraction else "train" for d, s in draws}
    if len(draws) >= 2 and val_fraction > 0:
        out[draws[0][1]], out[draws[-1][1]] = "val", "train"
    return out


@dataclass
class _Scan:
    """Pass one: the labels by frame, which frames have a raw image, and what could not be read."""

    labels: dict[Key, Labels] = field(default_factory=dict)
    raw: set[Key] = field(default_factory=set)
    images: set[Key] = field(default_factory=set)
    skipped: list[str] = field(default_factory=list)
    damaged: list[str] = field(default_factory=list)


class _Runs:
    """Which run of its camera a stamp belongs to: a new one each time a topic's stamp goes back."""

    def __init__(self) -> None:
        self.last: dict[tuple[int, str, str], int] = {}
        self.run: dict[tuple[int, str, str], int] = {}

    def key(self, bag: int, camera: str, kind: str, stamp: int) -> Key:
        topic = (bag, camera, kind)
        if stamp < self.last.get(topic, stamp):
            self.run[topic] = self.run.get(topic, 0) + 1
        self.last[topic] = stamp
        return bag, camera, self.run.get(topic, 0), stamp


def _messages(cfg: ExportConfig, i: int, into: list[str]) -> Iterator[BagMessage]:
    """Bag ``i``'s messages; its damage goes ``into`` the list at the end."""
    reader = BagReader.open([cfg.bags[i]], name="BAG")
    yield from reader.messages()
    into.extend(reader.stopped)


def _scan(cfg: ExportConfig) -> _Scan:
    scan, runs = _Scan(), _Runs()
    for i in range(len(cfg.bags)):
        for m in _messages(cfg, i, scan.damaged):
            match = _TOPIC.match(m.topic)
            if not match:
                continue
            camera, kind = match.group("camera"), match.group("kind")
            try:
                if kind == "labels" and m.type_name == "std_msgs/msg/String":
                    lab = Labels.from_json(cdr_string(m.data))
                    scan.labels[runs.key(i, camera, kind, lab.stamp.ns)] = lab
                elif (kind, m.type_name) in (("image_raw", IMAGE_TYPE), ("image_raw/compressed", COMPRESSED_TYPE)):
                    key = runs.key(i, camera, kind, header_stamp_ns(m.data))
                    scan.images.add(key)
                    if m.type_name == IMAGE_TYPE:
                        scan.raw.add(key)
            except (*MALFORMED, ZebraSimError) as exc:
                scan.skipped.append(skip_note(m, exc))
    return scan


class _Writer:
    def __init__(self, cfg: ExportConfig, scan: _Scan) -> None:
        self.cfg, self.out, self.scan = cfg, Path(cfg.out), scan
        steps = {(k[0], k[2], k[3]) for k in scan.labels if k in scan.images}
        self.splits = split_steps(steps, cfg.seed, cfg.val_fraction)
        stems = [re.sub(r"[^A-Za-z0-9_.-]", "_", Path(b).stem) for b in cfg.bags]
        self.prefixes = [s if stems.count(s) == 1 else f"{s}{i}" for i, s in enumerate(stems)]
        self.frames = {"train": 0, "val": 0}
        self.written: set[Key] = set()
        self.zebras = 0

    def write(self, key: Key, type_name: str, data: bytes) -> None:
        """One frame: its image (CDR bytes of ``type_name``) and its labels; ValueError for an image that cannot be
        written in its colours, or whose size is not its labels'."""
        labels = self.scan.labels[key]
        ext, blob, (w, h) = self._image(type_name, data)
        if (w, h) != (labels.width, labels.height):
            raise ValueError(f"an image of {w}x{h} px with labels of a {labels.width}x{labels.height} image")
        bag, camera, run, stamp = key
        split = self.splits[bag, run, stamp]
        name = f"{self.prefixes[bag]}_{camera.strip('/').replace('/', '_')}_{stamp}" + (f"_r{run}" if run else "")
        for folder in ("images", "labels"):
            (self.out / folder / split).mkdir(parents=True, exist_ok=True)
        (self.out / "images" / split / f"{name}.{ext}").write_bytes(blob)
        kept = yolo_lines(labels)
        (self.out / "labels" / split / f"{name}.txt").write_text("".join(f"{line}\n" for line in kept))
        if dont_care := yolo_lines(labels, dont_care=True):
            (self.out / "ignore" / split).mkdir(parents=True, exist_ok=True)
            (self.out / "ignore" / split / f"{name}.txt").write_text("".join(f"{line}\n" for line in dont_care))
        self.written.add(key)
        self.frames[split] += 1
        self.zebras += len(kept)

    def _image(self, type_name: str, data: bytes) -> tuple[str, bytes, tuple[int, int]]:
        """(extension, file bytes, (width, height)) of a recorded image."""
        if type_name == COMPRESSED_TYPE:
            _, fmt, blob = cdr_compressed_image(data)
            rgb = decompress_rgb(fmt, blob)  # ValueError for what our readers cannot take (depth, other codecs)
            size = (rgb.shape[1], rgb.shape[0])
            as_read = ";" not in fmt or re.search(r"compressed (bgr|mono)", fmt)  # the file's colours are ours
            for ext, magic in _MAGIC.items():
                if as_read and blob.startswith(magic):
                    return ext, blob, size
        else:
            got = rgb_image(data)
            if got is None:
                raise ValueError("an image of another encoding than rgb8 or bgr8")
            rgb = got[1]
            size = (rgb.shape[1], rgb.shape[0])
        params = [cv2.IMWRITE_JPEG_QUALITY, self.cfg.jpeg_quality] if self.cfg.image_format == "jpg" else []
        ok, buf = cv2.imencode(f".{self.cfg.image_format}", np.ascontiguousarray(rgb[..., ::-1]), params)
        if not ok:
            raise ValueError(f"OpenCV could not encode it as {self.cfg.image_format}")
        return self.cfg.image_format, buf.tobytes(), size


def export_bag(cfg: ExportConfig) -> dict[str, Any]:
    """Write the dataset (module docstring); returns what was written and what was not."""
    cfg.check()
    for b in cfg.bags:
        BagReader.open([b], name="BAG")  # a missing file stops here, before anything is written
    scan = _scan(cfg)
    writer = _Writer(cfg, scan)
    runs, skipped = _Runs(), list(scan.skipped)  # the image topics' runs, as the first pass found them
    ignored: list[str] = []
    for i in range(len(cfg.bags)):
        for m in _messages(cfg, i, ignored):  # its damage was noted by the first pass
            match = _TOPIC.match(m.topic)
            if not match:
                continue
            camera, kind = match.group("camera"), match.group("kind")
            if (kind, m.type_name) not in (("image_raw", IMAGE_TYPE), ("image_raw/compressed", COMPRESSED_TYPE)):
                continue
            try:
                key = runs.key(i, camera, kind, header_stamp_ns(m.data))
            except MALFORMED:
                continue  # noted by the first pass
            if key not in scan.labels or (m.type_name == COMPRESSED_TYPE and key in scan.raw):
                continue  # no labels; or a compressed copy of a frame whose raw image is written instead
            try:
                writer.write(key, m.type_name, m.data)
            except (*MALFORMED, ValueError) as exc:
                skipped.append(skip_note(m, exc))
    out = Path(cfg.out)
    out.mkdir(parents=True, exist_ok=True)
    val = "images/val" if writer.frames["val"] else "images/train"  # no val step: val is the train split
    quoted = json.dumps(str(out.resolve()))
    (out / "dataset.yaml").write_text(f"# zebra_sim_ros: frames of {', '.join(cfg.bags)} (YOLO format)"
                                      + ("" if writer.frames["val"] else "; no step drawn for val: val is train")
                                      + f"\npath: {quoted}\ntrain: images/train\nval: {val}\nnc: 1\nnames:\n"
                                      "  0: zebra\n")
    paired = {k for k in scan.labels if k in scan.images}
    return {"out": str(out), "frames": dict(writer.frames), "val_is_train": not writer.frames["val"],
            "zebras_labelled": writer.zebras, "images_without_labels": len(scan.images - set(scan.labels)),
            "labels_without_image": len(set(scan.labels) - scan.images), "skipped": skipped,
            "not_written": len(paired - writer.written), "damaged": scan.damaged}

