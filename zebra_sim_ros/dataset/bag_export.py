"""A recorded run as a YOLO dataset (``zebra-sim bag export BAG --out DIR``): each camera image of the bag with the
labeller's labels of the same frame, so that ``zebra-sim train`` and ``val`` read a live graph's run as they read
``generate``'s sets.

Pairs ``<drone>/image_raw`` (rgb8 or bgr8), or ``<drone>/image_raw/compressed`` (jpeg or png), with
``<drone>/labels`` by the image's stamp, and writes, as ``generate`` lays a set out::

    DIR/images/{train,val}/<bag>_<drone>_<stamp>.jpg   the image (raw ones encoded; compressed ones as recorded)
    DIR/labels/{train,val}/<same>.txt                  YOLO lines of the kept zebras (visible boxes)
    DIR/ignore/{train,val}/<same>.txt                  the zebras seen but not kept: don't-care regions for val
    DIR/dataset.yaml                                   path, train, val, names (0: zebra)

A step's frames go to one split together, drawn from its stamp and ``seed`` (``val_fraction`` of the steps to
val). Images without labels (and labels without an image) are counted, not written; a message that does not parse
is noted and skipped, and a damaged bag gives what is intact. No COCO file: the masks are not in the bag.
"""

from __future__ import annotations

import hashlib
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2

from zebra_sim_ros.dataset.coco import yolo_lines
from zebra_sim_ros.errors import ParameterError, ZebraSimError
from zebra_sim_ros.messages import Labels
from zebra_sim_ros.recording.cdr import MALFORMED, cdr_compressed_image, cdr_string, header_stamp_ns, rgb_image
from zebra_sim_ros.recording.evaluate import skip_note
from zebra_sim_ros.recording.images import COMPRESSED_TYPE, IMAGE_TYPE, is_colour
from zebra_sim_ros.recording.reader import BagMessage, BagReader

_TOPIC = re.compile(r"^(?:/[^/]+)*/(?P<drone>[^/]+)/(?P<kind>image_raw(?:/compressed)?|labels)$")
FORMATS = ("jpg", "png")


@dataclass(frozen=True)
class ExportConfig:
    """Settings of an export."""

    bags: tuple[str, ...]
    out: str
    image_format: str = "jpg"  # how raw images are written (compressed ones keep their own)
    jpeg_quality: int = 95
    val_fraction: float = 0.2
    seed: int = 0

    def check(self) -> None:
        """Raise :class:`ParameterError` naming the first bad setting."""
        if self.image_format not in FORMATS:
            raise ParameterError("--format", self.image_format, " or ".join(FORMATS))
        if not 1 <= self.jpeg_quality <= 100:
            raise ParameterError("--jpeg-quality", self.jpeg_quality, "1..100")
        if not 0.0 <= self.val_fraction < 1.0:
            raise ParameterError("--val-fraction", self.val_fraction, "0 <= f < 1")
        if self.seed < 0:
            raise ParameterError("--seed", self.seed, ">= 0")


def step_split(stamp: int, seed: int, val_fraction: float) -> str:
    """``val`` for ``val_fraction`` of the steps, drawn from the step's stamp (ns) and ``seed``; else ``train``."""
    h = int.from_bytes(hashlib.sha256(f"{seed}:{stamp}".encode()).digest()[:8], "big") / 2**64
    return "val" if h < val_fraction else "train"


class _Writer:
    def __init__(self, cfg: ExportConfig) -> None:
        self.cfg, self.out = cfg, Path(cfg.out)
        self.frames = {"train": 0, "val": 0}
        self.zebras = 0

    def write(self, prefix: str, drone: str, stamp: int, image: tuple[str, bytes], labels: Labels) -> None:
        """One frame: its image (``(type, CDR bytes)``) and labels; ValueError for an image that is not colour."""
        ext, data = self._image_bytes(*image)
        split = step_split(stamp, self.cfg.seed, self.cfg.val_fraction)
        name = f"{prefix}_{drone}_{stamp}"
        for folder in ("images", "labels"):
            (self.out / folder / split).mkdir(parents=True, exist_ok=True)
        (self.out / "images" / split / f"{name}.{ext}").write_bytes(data)
        kept = yolo_lines(labels)
        (self.out / "labels" / split / f"{name}.txt").write_text("".join(f"{line}\n" for line in kept))
        if dont_care := yolo_lines(labels, dont_care=True):
            (self.out / "ignore" / split).mkdir(parents=True, exist_ok=True)
            (self.out / "ignore" / split / f"{name}.txt").write_text("".join(f"{line}\n" for line in dont_care))
        self.frames[split] += 1
        self.zebras += len(kept)

    def _image_bytes(self, type_name: str, data: bytes) -> tuple[str, bytes]:
        if type_name == COMPRESSED_TYPE:
            _, fmt, blob = cdr_compressed_image(data)
            codec = fmt.split(";", 1)[1] if ";" in fmt else fmt
            if not is_colour(fmt) or not re.search(r"\b(jpeg|png)\b", codec):
                raise ValueError(f"a compressed image of format {fmt!r}: want a jpeg or png colour image")
            return ("png" if "png" in codec else "jpg"), blob
        got = rgb_image(data)
        if got is None:
            raise ValueError("an image of another encoding than rgb8 or bgr8")
        bgr = got[1][..., ::-1]
        params = [cv2.IMWRITE_JPEG_QUALITY, self.cfg.jpeg_quality] if self.cfg.image_format == "jpg" else []
        ok, buf = cv2.imencode(f".{self.cfg.image_format}", bgr, params)
        if not ok:
            raise ValueError(f"OpenCV could not encode it as {self.cfg.image_format}")
        return self.cfg.image_format, buf.tobytes()


def export_bag(cfg: ExportConfig) -> dict[str, Any]:
    """Write the dataset (module docstring); returns what was written and what was not."""
    cfg.check()
    reader = BagReader.open(list(cfg.bags), name="BAG")
    prefix = re.sub(r"[^A-Za-z0-9_.-]", "_", Path(cfg.bags[0]).stem)
    writer = _Writer(cfg)
    images: dict[tuple[str, int], tuple[str, bytes]] = {}  # waiting for their labels
    labels: dict[tuple[str, int], Labels] = {}  # waiting for their image
    skipped: list[str] = []

    def pair(m: BagMessage, key: tuple[str, int]) -> None:
        if key in images and key in labels:
            try:
                writer.write(prefix, key[0], key[1], images.pop(key), labels.pop(key))
            except (*MALFORMED, ValueError) as exc:
                skipped.append(skip_note(m, exc))

    for m in reader.messages():
        match = _TOPIC.match(m.topic)
        if not match:
            continue
        drone, kind = match.group("drone"), match.group("kind")
        try:
            if kind == "labels" and m.type_name == "std_msgs/msg/String":
                lab = Labels.from_json(cdr_string(m.data))
                labels[drone, lab.stamp.ns] = lab
                pair(m, (drone, lab.stamp.ns))
            elif (kind == "image_raw" and m.type_name == IMAGE_TYPE) or (
                    kind == "image_raw/compressed" and m.type_name == COMPRESSED_TYPE):
                key = (drone, header_stamp_ns(m.data))
                if m.type_name == IMAGE_TYPE or key not in images:  # raw wins over a compressed copy
                    images[key] = (m.type_name, m.data)
                pair(m, key)
        except (*MALFORMED, ZebraSimError) as exc:
            skipped.append(skip_note(m, exc))
    out = Path(cfg.out)
    out.mkdir(parents=True, exist_ok=True)
    quoted = json.dumps(str(out.resolve()))
    (out / "dataset.yaml").write_text(f"# zebra_sim_ros: frames of {', '.join(cfg.bags)} (YOLO format)\n"
                                      f"path: {quoted}\ntrain: images/train\nval: images/val\nnc: 1\nnames:\n"
                                      "  0: zebra\n")
    return {"out": str(out), "frames": dict(writer.frames), "zebras_labelled": writer.zebras,
            "images_without_labels": len(images), "labels_without_image": len(labels), "skipped": skipped,
            "damaged": reader.stopped}
