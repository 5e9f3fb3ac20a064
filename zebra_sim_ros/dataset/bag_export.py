"""A recorded run as a YOLO dataset (``zebra-sim bag export BAG --out DIR``): each camera image of the bag with the
labeller's labels of the same frame, so that ``zebra-sim train`` and ``val`` read a live graph's run as they read
``generate``'s sets.

Pairs ``<drone>/image_raw`` (rgb8 or bgr8), or ``<drone>/image_raw/compressed`` (jpeg or png), with
``<drone>/labels`` by the image's stamp, and writes, as ``generate`` lays a set out::

    DIR/images/{train,val}/<bag>_<camera>_<stamp>.jpg   the image (see below)
    DIR/labels/{train,val}/<same>.txt                   YOLO lines of the kept zebras (visible boxes)
    DIR/ignore/{train,val}/<same>.txt                   the zebras seen but not kept: don't-care regions for val
    DIR/dataset.yaml                                    path, train, val, names (0: zebra)

``<camera>`` is the topic's namespace with ``/`` as ``_`` (``drone_0``, ``g1_drone_0``). Each labels message pairs
with the camera's image of its stamp that arrived last before it (by the recorder's receive times) and after the
labels of that stamp before it: so a run that starts again at the same stamps (a restarted placer, a looping
replay) pairs its own images (its frames get ``_r<k>``), labels out of order pair all the same, and a step sent
again with the same labels is one frame. Raw images win over a compressed copy of the frame and are written as jpg
(``jpeg_quality``) or png; compressed ones as recorded where the file reads back in the colours recorded (a codec
holding BGR or grey, the bytes a JPEG or PNG), else decoded and written as raw ones are. Pairing stays within one
BAG argument: give a split recording as its folder.

Two passes over each bag: the labels and the images' times first, then each image written as it is read, so
memory does not grow with the bag. A step's frames go to one split, drawn from the step and ``seed``
(``val_fraction`` of the steps to val; with a fraction above 0 and two written steps or more, at least one in each
split). Images without labels (and labels without an image) are counted, not written; a message that does not
parse, or an image whose size is not its labels', is noted and skipped; a damaged bag gives what is intact. No
COCO file: the masks are not in the bag. ``--out`` must be new or empty: remove a half-written one to start again.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2

from zebra_sim_ros.dataset.coco import encode_frame, write_dataset_yaml, yolo_lines
from zebra_sim_ros.errors import ParameterError, ZebraSimError
from zebra_sim_ros.messages import Labels
from zebra_sim_ros.recording.cdr import MALFORMED, cdr_compressed_image, cdr_string, header_stamp_ns, rgb_image
from zebra_sim_ros.recording.evaluate import skip_note
from zebra_sim_ros.recording.images import COMPRESSED_TYPE, IMAGE_TYPE, CompressedFormat, decompress_rgb
from zebra_sim_ros.recording.reader import CAMERA_IMAGES, BagMessage, BagReader, topic_owner

_KINDS = (*CAMERA_IMAGES, "labels")  # a camera's topics that bag export reads
_IMAGE_KINDS = ((CAMERA_IMAGES[0], IMAGE_TYPE), (CAMERA_IMAGES[1], COMPRESSED_TYPE))
FORMATS = ("jpg", "png")
_MAGIC = {"jpg": b"\xff\xd8\xff", "png": b"\x89PNG\r\n\x1a\n"}
# How much later than its labels the recorder may receive an image of the same frame (a large image's fragments
# arrive after the small labels message), and how far apart two copies of one frame (raw, compressed) may arrive.
LATE_S = 2.0

Frame = tuple[int, str, int, int]  # (bag index, camera, stamp ns, occurrence k of that stamp's labels)
ImageId = tuple[int, str, int, str, int]  # (bag index, camera, stamp ns, type, receive time ns)


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
            raise ParameterError("--out", self.out, "a new or empty folder (frames of another export would mix in; "
                                 "remove a half-written one to start again)")


def step_draw(seed: int, step: tuple[int, int, int]) -> float:
    """A step's uniform draw in [0, 1) from ``seed`` and the step (bag index, stamp, occurrence)."""
    return int.from_bytes(hashlib.sha256(f"{seed}:{step}".encode()).digest()[:8], "big") / 2**64


@dataclass
class _Scan:
    """Pass one: each frame's labels and the image message it is written from, and what could not be used."""

    labels: dict[Frame, Labels] = field(default_factory=dict)
    chosen: dict[ImageId, Frame] = field(default_factory=dict)
    images_without_labels: int = 0
    labels_without_image: int = 0
    skipped: list[str] = field(default_factory=list)
    damaged: list[str] = field(default_factory=list)


def _messages(path: str, into: list[str]) -> Iterator[BagMessage]:
    """A bag's messages; its damage goes ``into`` the list at the end."""
    reader = BagReader.open([path], name="BAG")
    yield from reader.messages()
    into.extend(reader.stopped)


def _pair(i: int, camera: str, stamp: int, labels: list[tuple[int, Labels]], images: list[tuple[int, str]],
          scan: _Scan) -> None:
    """One camera's labels and images of one stamp, in receive order: each labels message takes the last image
    received up to :data:`LATE_S` after it and after the image the labels before it took (raw before a compressed
    copy received within :data:`LATE_S` of it); the same labels again are a step sent again, not a frame."""
    late = int(LATE_S * 1e9)
    taken, k, last = -1, 0, None
    used: list[tuple[int, int]] = []  # the receive times of the frames paired, their copies included
    for t, lab in sorted(labels, key=lambda x: x[0]):
        if last is not None and lab == last:
            continue  # sent again
        last = lab
        candidates = [(pt, ty) for pt, ty in images if taken < pt <= t + late]
        if not candidates:
            scan.labels_without_image += 1
            continue
        newest = max(pt for pt, _ in candidates)
        copies = [c for c in candidates if c[0] >= newest - late]
        pt, ty = max(copies, key=lambda c: (c[1] == IMAGE_TYPE, c[0]))
        frame = (i, camera, stamp, k)
        scan.labels[frame], scan.chosen[i, camera, stamp, ty, pt] = lab, frame
        taken, k = newest, k + 1
        used.append((newest - late, newest))
    scan.images_without_labels += sum(1 for pt, _ in images if not any(a <= pt <= b for a, b in used))


def _scan(cfg: ExportConfig) -> _Scan:
    scan = _Scan()
    for i, path in enumerate(cfg.bags):
        labels: dict[tuple[str, int], list[tuple[int, Labels]]] = {}
        images: dict[tuple[str, int], list[tuple[int, str]]] = {}
        for m in _messages(path, scan.damaged):
            owner = topic_owner(m.topic, _KINDS)
            if not owner:
                continue
            camera, kind = owner
            try:
                if kind == "labels" and m.type_name == "std_msgs/msg/String":
                    lab = Labels.from_json(cdr_string(m.data))
                    labels.setdefault((camera, lab.stamp.ns), []).append((m.publish_time, lab))
                elif (kind, m.type_name) in _IMAGE_KINDS:
                    images.setdefault((camera, header_stamp_ns(m.data)), []).append((m.publish_time, m.type_name))
            except (*MALFORMED, ZebraSimError) as exc:
                scan.skipped.append(skip_note(m, exc))
        for key in sorted(set(labels) | set(images)):
            _pair(i, *key, labels.get(key, []), images.get(key, []), scan)
    return scan


class _Writer:
    def __init__(self, cfg: ExportConfig, scan: _Scan) -> None:
        self.cfg, self.out, self.scan = cfg, Path(cfg.out), scan
        stems = [re.sub(r"[^A-Za-z0-9_.-]", "_", Path(b).stem) for b in cfg.bags]
        self.prefixes = stems if len(set(stems)) == len(stems) else [f"b{i}_{s}" for i, s in enumerate(stems)]
        self.steps: dict[tuple[int, int, int], list[tuple[str, str]]] = {}  # step: its frames' (split, file name)
        self.zebras = 0
        self._folders: set[Path] = set()  # the folders made so far

    def folder(self, kind: str, split: str) -> Path:
        """``<out>/<kind>/<split>``, made on first use."""
        path = self.out / kind / split
        if path not in self._folders:
            path.mkdir(parents=True, exist_ok=True)
            self._folders.add(path)
        return path

    def split_of(self, step: tuple[int, int, int]) -> str:
        return "val" if step_draw(self.cfg.seed, step) < self.cfg.val_fraction else "train"

    def write(self, frame: Frame, type_name: str, data: bytes) -> None:
        """One frame: its image (CDR bytes of ``type_name``) and its labels; ValueError for an image that cannot be
        written in its colours, or whose size is not its labels'."""
        labels = self.scan.labels[frame]
        if labels.width <= 0 or labels.height <= 0:
            raise ValueError(f"labels of a {labels.width}x{labels.height} image")
        ext, blob, (w, h) = self._image(type_name, data)
        if (w, h) != (labels.width, labels.height):
            raise ValueError(f"an image of {w}x{h} px with labels of a {labels.width}x{labels.height} image")
        bag, camera, stamp, k = frame
        step = (bag, stamp, k)
        split = self.split_of(step)
        name = f"{self.prefixes[bag]}_{camera.strip('/').replace('/', '_')}_{stamp}" + (f"_r{k}" if k else "")
        (self.folder("images", split) / f"{name}.{ext}").write_bytes(blob)
        kept = yolo_lines(labels)
        (self.folder("labels", split) / f"{name}.txt").write_text("".join(f"{line}\n" for line in kept))
        if dont_care := yolo_lines(labels, dont_care=True):
            (self.folder("ignore", split) / f"{name}.txt").write_text("".join(f"{line}\n" for line in dont_care))
        self.steps.setdefault(step, []).append((split, f"{name}.{ext}"))
        self.zebras += len(kept)

    def balance(self) -> None:
        """With a val fraction above 0 and two written steps or more, a step in each split: the step of the lowest
        draw moved to an empty val, of the highest to an empty train."""
        splits = {sp for frames in self.steps.values() for sp, _ in frames}
        if self.cfg.val_fraction <= 0 or len(self.steps) < 2 or len(splits) == 2:
            return
        order = sorted(self.steps, key=lambda st: step_draw(self.cfg.seed, st))
        step, to = (order[0], "val") if splits == {"train"} else (order[-1], "train")
        for split, file in self.steps[step]:
            stem = Path(file).stem
            for folder, name in (("images", file), ("labels", f"{stem}.txt"), ("ignore", f"{stem}.txt")):
                src = self.out / folder / split / name
                if src.exists():
                    src.replace(self.folder(folder, to) / name)
        self.steps[step] = [(to, file) for _, file in self.steps[step]]

    def frames(self) -> dict[str, int]:
        out = {"train": 0, "val": 0}
        for frames in self.steps.values():
            for split, _ in frames:
                out[split] += 1
        return out

    def _image(self, type_name: str, data: bytes) -> tuple[str, bytes, tuple[int, int]]:
        """(extension, file bytes, (width, height)) of a recorded image."""
        if type_name == COMPRESSED_TYPE:
            _, fmt, blob = cdr_compressed_image(data)
            rgb = decompress_rgb(fmt, blob)  # ValueError for what our readers cannot take (depth, other codecs)
            size = (rgb.shape[1], rgb.shape[0])
            held = CompressedFormat.parse(fmt)
            as_read = held.holds_bgr or held.codec_encoding.startswith("mono")  # a file reads back in these colours
            for ext, magic in _MAGIC.items():
                if as_read and blob.startswith(magic):
                    return ext, blob, size
        else:
            got = rgb_image(data)
            if got is None:
                raise ValueError("an image of another encoding than rgb8 or bgr8")
            rgb = got[1]
            size = (rgb.shape[1], rgb.shape[0])
        if 0 in size:
            raise ValueError(f"an empty image ({size[0]}x{size[1]})")
        encoded = encode_frame(rgb, self.cfg.image_format, self.cfg.jpeg_quality)
        if encoded is None:
            raise ValueError(f"OpenCV could not encode it as {self.cfg.image_format}")
        return self.cfg.image_format, encoded, size


def export_bag(cfg: ExportConfig) -> dict[str, Any]:
    """Write the dataset (module docstring); returns what was written and what was not (``exit_code`` 1 when no
    frame was)."""
    cfg.check()
    for b in cfg.bags:
        BagReader.open([b], name="BAG")  # a missing file stops here, before anything is written
    scan = _scan(cfg)
    writer = _Writer(cfg, scan)
    skipped, ignored = list(scan.skipped), list[str]()
    for i, path in enumerate(cfg.bags):
        for m in _messages(path, ignored):  # its damage was noted by the first pass
            owner = topic_owner(m.topic, _KINDS)
            if not owner or (owner[1], m.type_name) not in _IMAGE_KINDS:
                continue
            try:
                frame = scan.chosen.get((i, owner[0], header_stamp_ns(m.data), m.type_name,
                                         m.publish_time))
                if frame is not None:
                    writer.write(frame, m.type_name, m.data)
            except (*MALFORMED, ValueError, cv2.error) as exc:
                skipped.append(skip_note(m, exc))
    writer.balance()
    frames = writer.frames()
    out = Path(cfg.out)
    out.mkdir(parents=True, exist_ok=True)
    val = "images/val" if frames["val"] else "images/train"  # no val step: val is the train split
    write_dataset_yaml(out, f"zebra_sim_ros: frames of {', '.join(cfg.bags)} (YOLO format)"
                       + ("" if frames["val"] else "; no step drawn for val: val is train"), val)
    written = sum(frames.values())
    return {"out": str(out), "seed": cfg.seed, "frames": frames, "val_is_train": not frames["val"],
            "zebras_labelled": writer.zebras,
            "images_without_labels": scan.images_without_labels, "labels_without_image": scan.labels_without_image,
            "skipped": skipped, "not_written": len(scan.labels) - written, "damaged": scan.damaged,
            **({} if written else {"exit_code": 1})}
