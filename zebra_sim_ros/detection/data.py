"""YOLO-format datasets and the augmentations of the paper's YOLOv5 defaults.

A set is a folder of images with a sibling ``labels`` folder (``images/x/a.jpg`` -> ``labels/x/a.txt``, lines
``class cx cy w h`` normalised), or a ``dataset.yaml`` naming ``train`` and ``val`` folders. An optional sibling
``ignore`` folder in the same format holds don't-care boxes (objects present but not labelled), which validation
scores as COCO scores crowd regions. Training with ``dont_care`` adds them to the targets with class
:data:`DONT_CARE` (-1), augmented as the labels are, so the loss neither rewards nor punishes detecting them.
Training with ``other_class`` adds each generated frame's animals of other species (from its annotation) with that
class, so a model learns an "other animal" class beside zebras (``train --other-animals``).
Batches are ``(images (B, 3, H, W) float in [0, 1], targets (T, 6) [image index, class, x0, y0, x1, y1] pixels)``;
training batches are square (H = W = imgsz).

Training augmentation: mosaic of four images, random affine (scale, translation), horizontal flip and HSV
jitter (YOLOv5's), then what breaks the synthetic shortcuts (their strengths:
:class:`~zebra_sim_ros.detection.config.Augment`): crops zoomed around one zebra, cut-out, grey images, gamma and
white balance, blur, sensor noise and JPEG.
Validation: letterbox only, as inference letterboxes (long side to the inference size, each side padded
to a multiple of 32), with the scale and padding kept to map boxes back to the original image.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import torch
import yaml
from numpy.typing import NDArray
from torch.utils.data import Dataset

from zebra_sim_ros.detection.config import STRIDE, Augment
from zebra_sim_ros.detection.model import ZEBRA
from zebra_sim_ros.errors import AssetError, ParameterError

IMAGE_EXTS = (".jpg", ".jpeg", ".png", ".bmp")
DONT_CARE = -1  # the class of a don't-care box among training targets


def generate_settings(data: str | Path) -> dict[str, Any] | None:
    """The settings ``zebra-sim generate`` recorded for a set (its ``generate.json`` beside the dataset.yaml, or in
    the folder), which a checkpoint keeps beside its training arguments; for a dataset.yaml that lists several
    generated sets' training folders, ``{"sets": {root: settings}}``; None for other sets."""
    p = Path(data)
    own = generate_config(p.parent if p.suffix in (".yaml", ".yml") else p)
    if own is not None:
        return own
    try:
        roots = [f.parent.parent for f in resolve_splits(p, "train")]
    except ParameterError:
        return None
    sets: dict[str, Any] = {}
    for r in roots:
        g = generate_config(r)
        if g is not None and isinstance(g.get("sets"), dict):  # a folder gathered from several sets (gpu/pack.py)
            sets.update(g["sets"])
        elif g is not None:
            sets[str(r)] = g
    return {"sets": sets} if sets else None


def generate_config(folder: Path) -> dict[str, Any] | None:
    """The ``config`` a ``generate.json`` in ``folder`` records (None: no file, or none readable)."""
    try:
        return dict(json.loads((folder / "generate.json").read_text()).get("config") or {}) or None
    except (OSError, ValueError, AttributeError, TypeError):
        return None


def resolve_split(data: str | Path, split: str) -> Path:
    """The image folder of ``split`` from a dataset.yaml, or ``data`` itself if it is a folder (one folder: a
    dataset.yaml that lists several for ``split`` is refused, naming the split).

    A folder holding a ``dataset.yaml`` (what ``zebra-sim generate`` writes) is read as that file: taken as a
    plain folder, its instance masks (``masks/*.png``) would count as unlabelled images.
    """
    folders = resolve_splits(data, split)
    if len(folders) != 1:
        raise ParameterError("--data", str(data), f"one '{split}' folder here ({len(folders)} listed)")
    return folders[0]


def resolve_splits(data: str | Path, split: str) -> list[Path]:
    """The image folders of ``split``: as :func:`resolve_split`, and YOLO's list form, ``train: [a/images/train,
    b/images/train]`` (each relative to ``path``), which trains on several generated sets at once."""
    p = Path(data)
    if p.is_dir() and (p / "dataset.yaml").is_file():
        p = p / "dataset.yaml"
    if p.is_dir():
        return [p]
    if not p.is_file():
        raise ParameterError("--data", str(p), "a dataset.yaml or an image folder that exists")
    try:
        y = yaml.safe_load(p.read_text())
        root = Path(y.get("path") or p.parent)
        if not root.is_absolute():
            root = p.parent / root
        entry = y[split]
        folders = [root / str(e) for e in (entry if isinstance(entry, list) else [entry])]
    except (yaml.YAMLError, KeyError, TypeError, AttributeError) as exc:
        raise ParameterError("--data", str(p), f"a YOLO dataset.yaml with '{split}' ({exc})") from exc
    if not folders:
        raise ParameterError("--data", str(p), f"at least one '{split}' folder")
    for folder in folders:
        if not folder.is_dir():
            raise ParameterError("--data", str(p), f"a '{split}' folder that exists (not {folder})")
    return folders


def _images_index(parts: tuple[str, ...]) -> int | None:
    """The index of the last ``images`` component of a path's parts (None if there is none)."""
    return next((i for i in range(len(parts) - 1, -1, -1) if parts[i] == "images"), None)


def annotation_path(image: Path) -> Path:
    """``<set>/images/<x>/a.jpg`` -> ``<set>/annotations/a.json``: the frame's full record as ``zebra-sim
    generate`` writes it (other sets have none)."""
    i = _images_index(image.parts)
    return image.with_suffix(".json") if i is None else Path(*image.parts[:i], "annotations", image.stem + ".json")


def other_species_boxes(image: Path, min_pixels: int = 40) -> NDArray[np.float32]:
    """(n, 4) visible boxes [x0, y0, x1, y1] (the frame's pixels) of the animals of other species in a generated
    frame with at least ``min_pixels`` visible pixels, from its annotation; none without one (other sets) or if
    it is unreadable (a training sample must not fail on a missing record)."""
    try:
        rec = json.loads(annotation_path(image).read_text())
        boxes = [z["box_visible"] for z in rec["labels"]["zebras"]
                 if z.get("species", "zebra") != "zebra" and z.get("box_visible")
                 and int(z.get("visible_pixels", 0)) >= min_pixels]
    except (OSError, ValueError, KeyError, TypeError):
        return np.zeros((0, 4), np.float32)
    return np.asarray(boxes, np.float32).reshape(-1, 4)


def label_path(image: Path, folder: str = "labels") -> Path:
    """``.../images/<x>/a.jpg`` -> ``.../labels/<x>/a.txt`` (YOLO's convention); ``folder`` "ignore" gives the
    image's don't-care boxes (same format; a missing file means none)."""
    parts = list(image.parts)
    i = _images_index(image.parts)
    if i is not None:
        parts[i] = folder
    return Path(*parts).with_suffix(".txt")


def read_labels(path: Path, width: int, height: int) -> NDArray[np.float32]:
    """(n, 5) [class, x0, y0, x1, y1] pixels from a YOLO label file (missing file: no objects).

    A line that is not at least five numbers raises :class:`AssetError` naming the file and the line."""
    if not path.exists():
        return np.zeros((0, 5), np.float32)
    rows = []
    for k, line in enumerate(path.read_text().splitlines(), 1):
        if not line.strip():
            continue
        try:
            rows.append([float(v) for v in line.split()[:5]])
        except ValueError:
            rows.append([])
        if len(rows[-1]) < 5:
            raise AssetError(f"label file {path} line {k} is {line!r}; want 'class cx cy w h' (numbers)")
    if not rows:
        return np.zeros((0, 5), np.float32)
    a = np.array(rows, dtype=np.float32)
    out = np.empty_like(a)
    out[:, 0] = a[:, 0]
    out[:, 1] = (a[:, 1] - a[:, 3] / 2) * width
    out[:, 2] = (a[:, 2] - a[:, 4] / 2) * height
    out[:, 3] = (a[:, 1] + a[:, 3] / 2) * width
    out[:, 4] = (a[:, 2] + a[:, 4] / 2) * height
    return out


def image_size(path: Path) -> tuple[int, int] | None:
    """(width, height) of a PNG or JPEG from its header, without decoding the pixels; None for any other file,
    a header not understood, or a JPEG with Exif (whose orientation the decoder may apply, swapping the sides).
    Mosaic crops use it to place four frames and decode only those the crop's window shows."""
    try:
        with open(path, "rb") as f:
            head = f.read(24)
            if head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR":
                w, h = struct.unpack(">II", head[16:24])
                return int(w), int(h)
            if head[:2] != b"\xff\xd8":
                return None
            f.seek(2)
            while True:
                b = f.read(1)
                if b != b"\xff":
                    return None  # a segment must start at a marker
                while b == b"\xff":  # fill bytes
                    b = f.read(1)
                if not b:
                    return None
                marker = b[0]
                if marker == 0x01 or 0xD0 <= marker <= 0xD7:
                    continue  # markers without a length
                if marker in (0xD9, 0xDA):
                    return None  # the image's end or its scan before any frame header
                seg = f.read(2)
                if len(seg) < 2:
                    return None
                length, start = struct.unpack(">H", seg)[0], f.tell()
                if marker == 0xE1 and f.read(4) == b"Exif":
                    return None
                if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):  # a start-of-frame header
                    f.seek(start)
                    data = f.read(5)
                    if len(data) < 5:
                        return None
                    h, w = struct.unpack(">xHH", data)
                    return (int(w), int(h)) if w and h else None
                f.seek(start + length - 2)
    except OSError:
        return None


def letterbox_size(h: int, w: int, size: int) -> tuple[int, int]:
    """(height, width) of an h x w image resized so its long side is ``size`` (what :func:`letterbox` does)."""
    r = size / max(h, w)
    return round(h * r), round(w * r)


def rect_shape(h: int, w: int, size: int) -> tuple[int, int]:
    """(height, width) of the smallest input that holds an h x w image letterboxed to long side ``size``: each
    side rounded up to a multiple of the largest stride (32). A 16:9 frame costs about 0.56 of a square one."""
    nh, nw = letterbox_size(h, w, size)
    return -(-nh // STRIDE) * STRIDE, -(-nw // STRIDE) * STRIDE


def resize_long_side(img: NDArray[np.uint8], size: int) -> tuple[NDArray[np.uint8], float]:
    """Resize keeping the aspect ratio so the long side is ``size``; returns the image and the scale.

    Bilinear when enlarging, area averaging when shrinking. Training (mosaic tiles) and inference (letterbox)
    both resize through here: a model trained at an imgsz above its frames' size must see the same upsampling
    it will meet when served (area "upsampling" is a different, blockier kernel: 9/255 mean difference).
    """
    h, w = img.shape[:2]
    r = size / max(h, w)
    nh, nw = letterbox_size(h, w, size)
    if (nw, nh) == (w, h):
        return img, r
    return np.asarray(cv2.resize(img, (nw, nh), interpolation=cv2.INTER_LINEAR if r > 1 else cv2.INTER_AREA),
                      dtype=np.uint8), r


def letterbox(img: NDArray[np.uint8], size: int,
              shape: tuple[int, int] | None = None) -> tuple[NDArray[np.uint8], float, tuple[int, int]]:
    """Resize keeping the aspect ratio so the long side is ``size``, pad with grey to size x size or to
    ``shape`` (height, width; at least the resized image).

    Returns the image, the scale and the (left, top) padding: ``x_new = x * scale + left``.
    """
    img, r = resize_long_side(img, size)
    nh, nw = img.shape[:2]
    out_h, out_w = shape or (size, size)
    left, top = (out_w - nw) // 2, (out_h - nh) // 2
    out = np.full((out_h, out_w, 3), 114, np.uint8)
    out[top:top + nh, left:left + nw] = img
    return out, r, (left, top)


@dataclass(frozen=True)
class ImageMeta:
    """What validation keeps of an image beside its letterboxed tensor: where it came from, its size, the
    letterbox (``x_new = x * scale + left``), the inference size and input shape, and its labels and don't-care
    boxes ``(n, 5)`` [class, x0, y0, x1, y1] in its own pixels. Training keeps only ``file``."""

    file: str
    shape: tuple[int, int] = (0, 0)  # (height, width) of the image, px
    scale: float = 1.0
    pad: tuple[int, int] = (0, 0)  # (left, top), px
    imgsz: int = 0  # the long side it was resized to, px
    input: tuple[int, int] = (0, 0)  # (height, width) of its letterboxed input, px
    labels: NDArray[np.float32] = field(default_factory=lambda: np.zeros((0, 5), np.float32))
    ignore: NDArray[np.float32] = field(default_factory=lambda: np.zeros((0, 5), np.float32))


class YoloDataset(Dataset[Any]):
    """Images and YOLO labels; ``augment`` None for validation. ``dont_care``: with ``augment``, the don't-care
    boxes of ``ignore/`` join each image's targets as class :data:`DONT_CARE` (validation keeps them apart, in
    :attr:`ImageMeta.ignore`). ``other_class``: the animals of other species of a generated frame (its
    annotation; at least 40 visible pixels) join its labels as that class (frames without one have none).
    ``size_for``: in validation, each image's inference size from its long side (the detector's rule,
    :func:`~zebra_sim_ros.detection.predict.inference_size`) instead of ``imgsz``."""

    def __init__(self, folder: str | Path | Sequence[str | Path], imgsz: int = 640, augment: Augment | None = None,
                 seed: int = 0, dont_care: bool = False, size_for: Callable[[int], int] | None = None,
                 crop: int = 0, other_class: int | None = None) -> None:
        folders = [Path(f) for f in ([folder] if isinstance(folder, (str, Path)) else folder)]
        self.folder = folders[0]
        self.files: list[Path] = []
        for f in folders:
            found = sorted(p for p in f.rglob("*") if p.suffix.lower() in IMAGE_EXTS)
            if not found:
                raise ParameterError("--data", str(f), "a folder with images (.jpg, .png)")
            self.files += found
        self.imgsz = imgsz
        self.size_for = size_for
        self.augment = augment
        self.seed = seed
        self.dont_care = dont_care
        self.crop = crop  # with augment: each sample an imgsz sample's crop x crop window around a zebra (0: off)
        self.other_class = other_class  # the class of other species' animals among the labels (None: not labelled)
        self.epoch = 0
        self._others: dict[int, NDArray[np.float32]] = {}  # other species' boxes per image, read when first needed

    def __len__(self) -> int:
        return len(self.files)

    def load(self, i: int, dont_care: bool = False) -> tuple[NDArray[np.uint8], NDArray[np.float32]]:
        """Image (RGB) and labels in its own pixels; ``dont_care``: the don't-care boxes too, as class -1."""
        img = self.image(i)
        return img, self.labels(i, img.shape[1], img.shape[0], dont_care)

    def image(self, i: int) -> NDArray[np.uint8]:
        """Image ``i``, decoded, RGB."""
        img = cv2.imread(str(self.files[i]), cv2.IMREAD_COLOR)
        if img is None:
            raise ParameterError("image", str(self.files[i]), "a readable image file")
        return np.asarray(cv2.cvtColor(img, cv2.COLOR_BGR2RGB), dtype=np.uint8)  # BGR -> RGB, a new array

    def labels(self, i: int, w: int, h: int, dont_care: bool = False) -> NDArray[np.float32]:
        """Labels of image ``i`` (``w`` x ``h`` px) in its pixels, as :meth:`load` gives them."""
        lab = read_labels(label_path(self.files[i]), w, h)
        if self.other_class is not None:
            others = self._other_boxes(i)
            lab = np.concatenate([lab, np.concatenate([np.full((len(others), 1), self.other_class, np.float32),
                                                       others], 1)])
        if dont_care:
            ign = read_labels(label_path(self.files[i], "ignore"), w, h)
            ign[:, 0] = DONT_CARE
            lab = np.concatenate([lab, ign])
        return lab

    def frame_size(self, samples: int = 32) -> int:
        """The median long side, px, of up to ``samples`` images spread over the set: the training frame size a
        checkpoint records (:attr:`~zebra_sim_ros.detection.model.ModelConfig.frame`)."""
        picks = np.unique(np.linspace(0, len(self.files) - 1, min(samples, len(self.files))).round().astype(int))
        sides = []
        for i in picks:
            img = cv2.imread(str(self.files[i]), cv2.IMREAD_UNCHANGED)
            if img is None:
                raise ParameterError("image", str(self.files[i]), "a readable image file")
            sides.append(max(img.shape[:2]))
        return int(np.median(sides))

    @property
    def windowed(self) -> bool:
        """Whether training samples are a ``crop`` window of an ``imgsz`` sample (only the window is drawn). A
        ``crop`` larger than ``imgsz`` pads the whole sample instead; 0 is off."""
        return 0 < self.crop <= self.imgsz

    def _rng(self, i: int) -> np.random.Generator:
        return np.random.default_rng([self.seed, self.epoch, i])

    def __getitem__(self, i: int) -> tuple[torch.Tensor, torch.Tensor, ImageMeta]:
        a = self.augment
        if a is None:
            img, lab0 = self.load(i)
            h0, w0 = img.shape[:2]
            size = self.size_for(max(h0, w0)) if self.size_for else self.imgsz
            img, r, (left, top) = letterbox(img, size, rect_shape(h0, w0, size))
            lab = lab0.copy()
            lab[:, [1, 3]] = lab[:, [1, 3]] * r + left
            lab[:, [2, 4]] = lab[:, [2, 4]] * r + top
            meta = ImageMeta(str(self.files[i]), (h0, w0), r, (left, top), size, (img.shape[0], img.shape[1]), lab0,
                             read_labels(label_path(self.files[i], "ignore"), w0, h0))
        else:
            rng = self._rng(i)
            u = rng.uniform(size=2)
            centre: tuple[float, float] | None = None  # a zoom's animal (or hard negative): where a crop must go
            if u[0] < a.zoom:
                sample, lab, centre = self._zoom(i, rng)
            else:
                sample, lab = self._mosaic(i, rng) if u[1] < a.mosaic else self._single(i, rng)
            flip = rng.uniform() < a.fliplr
            if flip:
                lab[:, [1, 3]] = self.imgsz - lab[:, [3, 1]]
                centre = None if centre is None else (self.imgsz - centre[0], centre[1])
            if self.windowed:  # only the window is drawn (of a flipped sample: its mirror, flipped)
                x0, y0 = crop_origin(lab, self.imgsz, self.imgsz, self.crop, rng, centre)
                img = sample.window(self.imgsz - x0 - self.crop if flip else x0, y0, self.crop)
                lab = _warp_labels(lab, np.array([[1.0, 0.0, -x0], [0.0, 1.0, -y0]]), 1.0, self.crop)
                if flip:
                    img = np.asarray(cv2.flip(img, 1), dtype=np.uint8)
            else:
                img = sample.full()
                if flip:
                    img = np.asarray(cv2.flip(img, 1), dtype=np.uint8)  # the same pixels as img[:, ::-1], faster
                if self.crop:  # a window larger than the sample: the sample, padded
                    img, lab = crop_window(img, lab, self.crop, rng, centre)
            if a.hsv_h or a.hsv_s or a.hsv_v:  # the uint8 HSV round trip is lossy: never apply it for nothing
                img = _hsv(img, rng, a)
            img, lab = _cutout(img, lab, rng, a.cutout)
            img = _photometric(img, rng, a)
            meta = ImageMeta(str(self.files[i]))
        t = torch.from_numpy(np.ascontiguousarray(img.transpose(2, 0, 1))).float() / 255.0
        return t, torch.from_numpy(lab), meta

    def _single(self, i: int, rng: np.random.Generator) -> tuple[_Sample, NDArray[np.float32]]:
        img, lab = self.load(i, self.dont_care)
        img, r, (left, top) = letterbox(img, self.imgsz)
        lab = lab.copy()
        lab[:, [1, 3]] = lab[:, [1, 3]] * r + left
        lab[:, [2, 4]] = lab[:, [2, 4]] * r + top
        return _affine(img, lab, rng, self.augment or Augment(), self.imgsz)

    def _zoom(self, i: int, rng: np.random.Generator
              ) -> tuple[_Sample, NDArray[np.float32], tuple[float, float] | None]:
        """A square crop around one labelled zebra (a random one; don't-care boxes are never the centre), scaled so
        the zebra's long side spans 15-80% of ``imgsz`` (log-uniform; enlarged at most ``zoom_max`` times, shrunk
        freely), its centre anywhere in the middle 80% of the crop so edges may cut it. With ``train --crop``, with
        probability ``zoom_crop`` the 15-80% are of the crop window instead, and the window goes around the zebra.
        Without a labelled zebra: as :meth:`_single`. With probability ``background`` (a hard negative) the centre
        is instead an animal of another species (half the time, where the frame has one), scaled by the same rule,
        or a random point enlarged 1-4x (log-uniform); any zebras in view keep their labels. Also returns where
        the crop window must go: a hard negative's centre, or the zebra's when sized to the window (else None)."""
        img, lab = self.load(i, self.dont_care)
        a = self.augment or Augment()
        negative = a.background > 0 and rng.uniform() < a.background
        # drawn only when asked, so that recipes without it keep their random streams
        to_window = self.windowed and a.zoom_crop > 0 and rng.uniform() < a.zoom_crop
        ref = self.crop if to_window else self.imgsz  # the side the animal's 15-80% are of
        box: NDArray[np.float32] | None = None  # [x0, y0, x1, y1] of the animal to centre on
        if negative:
            others = self._other_boxes(i)
            if len(others) and rng.uniform() < 0.5:
                box = others[int(rng.integers(len(others)))]
        else:
            zebra = _random_zebra(lab, rng)
            if zebra is None:
                sample, lab = self._single(i, rng)
                return sample, lab, None
            box = zebra[1:]
        if box is not None:
            side = max(float(box[2] - box[0]), float(box[3] - box[1]), 1.0)
            share = float(np.exp(rng.uniform(np.log(0.15), np.log(0.8))))
            s = min(share * ref / side, a.zoom_max)
            cx, cy = (box[0] + box[2]) / 2, (box[1] + box[3]) / 2
        else:  # a random point of the frame
            s = float(np.exp(rng.uniform(0.0, np.log(4.0))))
            cx, cy = rng.uniform(0, img.shape[1]), rng.uniform(0, img.shape[0])
        ox, oy = rng.uniform(0.1, 0.9, 2) * self.imgsz  # where the centre lands in the output
        m = np.array([[s, 0.0, ox - s * cx], [0.0, s, oy - s * cy]])
        interp = cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR
        return (_Sample(img, m, self.imgsz, interp), _warp_labels(lab, m, s, self.imgsz),
                (float(ox), float(oy)) if negative or (to_window and box is not None) else None)

    def read_other_boxes(self) -> int:
        """Read every image's other-species boxes now (from its annotation; none for other sets) and keep them,
        so that data-loading processes started later share them instead of reading the records again each
        epoch. Returns how many boxes were found."""
        for i in range(len(self.files)):
            self._other_boxes(i)
        return sum(len(b) for b in self._others.values())

    def _other_boxes(self, i: int) -> NDArray[np.float32]:
        if i not in self._others:
            self._others[i] = other_species_boxes(self.files[i])
        return self._others[i]

    def _mosaic(self, i: int, rng: np.random.Generator) -> tuple[_Sample, NDArray[np.float32]]:
        """Four images (``i`` and three drawn) around a random centre of a 2 x imgsz canvas, each resized so its
        long side is imgsz, then :func:`_affine`. Images are placed by their header's size (:func:`image_size`)
        and decoded only when drawn: a crop's window (:meth:`_Sample.window`) decodes just those it shows."""
        s = self.imgsz
        cx, cy = (int(rng.uniform(s * 0.5, s * 1.5)) for _ in range(2))
        tiles: list[_Tile] = []
        labels = []
        idx = [i] + list(rng.integers(0, len(self), 3))
        for k, j in enumerate(idx):
            j = int(j)
            img: NDArray[np.uint8] | None = None
            size = image_size(self.files[j])
            if size is None:
                img, lab = self.load(j, self.dont_care)
                size = (img.shape[1], img.shape[0])
            else:
                lab = self.labels(j, *size, self.dont_care)
            h, w = letterbox_size(size[1], size[0], s)
            r = s / max(size)
            if k == 0:
                x0, y0, x1, y1 = max(cx - w, 0), max(cy - h, 0), cx, cy
                sx0, sy0 = w - (x1 - x0), h - (y1 - y0)
            elif k == 1:
                x0, y0, x1, y1 = cx, max(cy - h, 0), min(cx + w, 2 * s), cy
                sx0, sy0 = 0, h - (y1 - y0)
            elif k == 2:
                x0, y0, x1, y1 = max(cx - w, 0), cy, cx, min(2 * s, cy + h)
                sx0, sy0 = w - (x1 - x0), 0
            else:
                x0, y0, x1, y1 = cx, cy, min(cx + w, 2 * s), min(2 * s, cy + h)
                sx0, sy0 = 0, 0
            tiles.append(_Tile(j, img, size, (w, h), (x0, y0, x1, y1), (sx0, sy0)))
            lab = lab.copy()
            lab[:, [1, 3]] = lab[:, [1, 3]] * r + (x0 - sx0)
            lab[:, [2, 4]] = lab[:, [2, 4]] * r + (y0 - sy0)
            labels.append(lab)
        lab = np.concatenate(labels) if labels else np.zeros((0, 5), np.float32)
        lab[:, 1:] = np.clip(lab[:, 1:], 0, 2 * s)
        affine, lab = _affine_params(2 * s, 2 * s, lab, rng, self.augment or Augment(), s)
        return _MosaicSample(self, tiles, affine, s), lab


def _random_zebra(lab: NDArray[np.float32], rng: np.random.Generator) -> NDArray[np.float32] | None:
    """One labelled zebra's row [class, x0, y0, x1, y1], drawn at random (a don't-care box or an animal of another
    class never is); None if none."""
    real = lab[lab[:, 0] == ZEBRA] if len(lab) else lab
    return real[int(rng.integers(len(real)))] if len(real) else None


def crop_window(img: NDArray[np.uint8], lab: NDArray[np.float32], size: int, rng: np.random.Generator,
                centre: tuple[float, float] | None = None) -> tuple[NDArray[np.uint8], NDArray[np.float32]]:
    """A ``size`` square of ``img`` at its own scale around a random labelled zebra, or around ``centre`` if given
    (a hard negative's), that point anywhere in the middle 80% of the window (without either, anywhere): the
    object-centred crops of ``train --crop``, which spend the step on the zebras and not the empty ground around
    them. Boxes are clipped; one under 3 px or with less than 10% of its area left is dropped (as
    :func:`_warp_labels`)."""
    h, w = img.shape[:2]
    x0, y0 = crop_origin(lab, w, h, size, rng, centre)
    m = np.array([[1.0, 0.0, -x0], [0.0, 1.0, -y0]])
    return _padded_window(img, x0, y0, size), _warp_labels(lab, m, 1.0, size)


def crop_origin(lab: NDArray[np.float32], w: int, h: int, size: int, rng: np.random.Generator,
                centre: tuple[float, float] | None = None) -> tuple[int, int]:
    """The top-left corner of :func:`crop_window`'s window in a ``w`` x ``h`` image (the same random draws)."""
    if centre is None:
        b = _random_zebra(lab, rng)
        centre = None if b is None else (float(b[1] + b[3]) / 2, float(b[2] + b[4]) / 2)
    if centre is not None:
        cx, cy = centre
        ox, oy = rng.uniform(0.1, 0.9, 2) * size
        x0, y0 = cx - ox, cy - oy
    else:
        x0, y0 = rng.uniform(0, max(w - size, 0)), rng.uniform(0, max(h - size, 0))
    return int(np.clip(round(float(x0)), 0, max(w - size, 0))), int(np.clip(round(float(y0)), 0, max(h - size, 0)))


def _padded_window(img: NDArray[np.uint8], x0: int, y0: int, side: int) -> NDArray[np.uint8]:
    """The ``side`` square of ``img`` (any shape) at (x0, y0), padded grey where it leaves the image."""
    out = np.full((side, side, 3), 114, np.uint8)
    part = img[y0:y0 + side, x0:x0 + side]
    out[:part.shape[0], :part.shape[1]] = part
    return out


class _Sample:
    """A ``size`` square training sample not drawn yet: ``src`` through the affine ``m`` (None: ``src`` is the
    sample). With ``train --crop`` only the window is drawn, which on a 2176 px sample is 15x fewer pixels."""

    def __init__(self, src: NDArray[np.uint8], m: NDArray[np.float64] | None, size: int,
                 interp: int = cv2.INTER_LINEAR) -> None:
        self.src, self.m, self.size, self.interp = src, m, size, interp

    def full(self) -> NDArray[np.uint8]:
        if self.m is None:
            return self.src
        return np.asarray(cv2.warpAffine(self.src, self.m, (self.size, self.size), flags=self.interp,
                                         borderValue=(114, 114, 114)), dtype=np.uint8)

    def window(self, x0: int, y0: int, side: int) -> NDArray[np.uint8]:
        """The ``side`` square of :meth:`full` at (x0, y0), padded grey where it leaves the sample."""
        if self.m is None:
            return _padded_window(self.src, x0, y0, side)
        m = self.m.copy()
        m[:, 2] -= (x0, y0)
        out = np.asarray(cv2.warpAffine(self.src, m, (side, side), flags=self.interp, borderValue=(114, 114, 114)),
                         dtype=np.uint8)
        if x0 + side > self.size or y0 + side > self.size:  # the part beyond the sample is padding, as in full()
            out[:, max(self.size - x0, 0):] = 114
            out[max(self.size - y0, 0):] = 114
        return out


@dataclass
class _Tile:
    """One image of a mosaic: dataset index, pixels (None until drawn), its (width, height) and resized (width,
    height), the canvas rectangle (x0, y0, x1, y1) it fills and the resized image's pixel at that corner."""

    index: int
    img: NDArray[np.uint8] | None
    size: tuple[int, int]
    resized: tuple[int, int]
    rect: tuple[int, int, int, int]
    origin: tuple[int, int]


class _MosaicSample(_Sample):
    """A mosaic not drawn yet: four :class:`_Tile` on a 2 x ``size`` canvas through the affine ``m``.

    :meth:`full` draws the canvas and warps it, as a whole sample always was. :meth:`window` draws only the
    window, tile by tile: each tile's image is warped straight into the window (its resize and the sample's
    affine as one bilinear warp; a tile shrunk below its own size is resized first, by area, as in
    :meth:`full`), and a tile outside the window is never decoded. The two agree but for rounding and the last
    pixel row at a tile's edge (a mosaic crop of 1280x720 frames at 2176 px: a fifth of the time)."""

    def __init__(self, data: YoloDataset, tiles: list[_Tile], m: NDArray[np.float64] | None, size: int) -> None:
        super().__init__(np.zeros((0, 0, 3), np.uint8), m, size)
        self.data, self.tiles = data, tiles

    def _pixels(self, t: _Tile) -> NDArray[np.uint8]:
        if t.img is None:  # decoded once per mosaic, even where it draws the same frame twice
            t.img = next((o.img for o in self.tiles if o.index == t.index and o.img is not None), None)
        if t.img is None:
            t.img = self.data.image(t.index)
            if (t.img.shape[1], t.img.shape[0]) != t.size:
                raise AssetError(f"image {self.data.files[t.index]} is {t.img.shape[1]}x{t.img.shape[0]} px but its "
                                 f"header says {t.size[0]}x{t.size[1]}")
        return t.img

    def full(self) -> NDArray[np.uint8]:
        s = self.size
        canvas = np.full((2 * s, 2 * s, 3), 114, np.uint8)
        for t in self.tiles:
            img, _ = resize_long_side(self._pixels(t), s)
            x0, y0, x1, y1 = t.rect
            sx0, sy0 = t.origin
            canvas[y0:y1, x0:x1] = img[sy0:sy0 + (y1 - y0), sx0:sx0 + (x1 - x0)]
        self.src = canvas
        return super().full()

    def window(self, x0: int, y0: int, side: int) -> NDArray[np.uint8]:
        m = np.eye(3)[:2] if self.m is None else self.m
        a, tx, ty = float(m[0, 0]), float(m[0, 2]) - x0, float(m[1, 2]) - y0  # canvas -> window (no rotation)
        out = np.full((side, side, 3), 114, np.uint8)
        umax, vmax = min(max(self.size - x0, 0), side), min(max(self.size - y0, 0), side)  # beyond: padding
        for t in self.tiles:
            cx0, cy0, cx1, cy1 = t.rect
            # window pixels whose centre falls on the tile's canvas pixels [cx0, cx1) x [cy0, cy1)
            u0, u1 = (int(np.clip(np.ceil(a * (c - 0.5) + tx), 0, umax)) for c in (cx0, cx1))
            v0, v1 = (int(np.clip(np.ceil(a * (c - 0.5) + ty), 0, vmax)) for c in (cy0, cy1))
            if u1 <= u0 or v1 <= v0:
                continue
            img = self._pixels(t)
            (w0, h0), (w, h) = t.size, t.resized
            if w < w0:  # shrunk: by area, as full() does, then warped at the canvas's scale
                img, _ = resize_long_side(img, self.size)
                rx = ry = 1.0
                bx = by = 0.0
            else:  # enlarged (or kept): cv2.resize's pixel mapping, x_resized = (x + 0.5) * w / w0 - 0.5
                rx, ry = w / w0, h / h0
                bx, by = 0.5 * rx - 0.5, 0.5 * ry - 0.5
            ox, oy = cx0 - t.origin[0], cy0 - t.origin[1]  # canvas position of the resized image's pixel 0
            mt = np.array([[a * rx, 0.0, a * (bx + ox) + tx - u0], [0.0, a * ry, a * (by + oy) + ty - v0]])
            out[v0:v1, u0:u1] = cv2.warpAffine(img, mt, (u1 - u0, v1 - v0), flags=cv2.INTER_LINEAR,
                                               borderMode=cv2.BORDER_REPLICATE)
        return out


def _affine(img: NDArray[np.uint8], lab: NDArray[np.float32], rng: np.random.Generator, a: Augment,
            size: int) -> tuple[_Sample, NDArray[np.float32]]:
    """Random scale and translation into a ``size`` square; boxes follow, tiny or mostly cut ones are dropped."""
    h, w = img.shape[:2]
    m, lab = _affine_params(w, h, lab, rng, a, size)
    return _Sample(img, m, size), lab


def _affine_params(w: int, h: int, lab: NDArray[np.float32], rng: np.random.Generator, a: Augment,
                   size: int) -> tuple[NDArray[np.float64] | None, NDArray[np.float32]]:
    """:func:`_affine`'s draw for a ``w`` x ``h`` image: the affine (None where it is the identity) and the
    boxes through it."""
    c = np.eye(3)
    c[0, 2], c[1, 2] = -w / 2, -h / 2
    s = rng.uniform(1 - a.scale, 1 + a.scale)
    sc = np.diag([s, s, 1.0])
    t = np.eye(3)
    t[0, 2] = rng.uniform(0.5 - a.translate, 0.5 + a.translate) * size
    t[1, 2] = rng.uniform(0.5 - a.translate, 0.5 + a.translate) * size
    m = (t @ sc @ c)[:2]
    identity = (h, w) == (size, size) and np.allclose(m, np.eye(3)[:2])  # letterbox only: nothing to warp
    return None if identity else m, _warp_labels(lab, m, s, size)


def _warp_labels(lab: NDArray[np.float32], m: NDArray[np.float64], s: float, size: int) -> NDArray[np.float32]:
    """Boxes (n, 5) [class, x0, y0, x1, y1] through the affine ``m`` (scale ``s``) into a ``size`` square,
    clipped; a box under 3 px or with less than 10% of its area left is dropped."""
    if not len(lab):
        return lab
    pts = np.ones((len(lab) * 4, 3), np.float64)
    pts[:, :2] = lab[:, [1, 2, 3, 4, 1, 4, 3, 2]].reshape(-1, 2)
    xy = (pts @ m.T).reshape(-1, 8)
    new = np.stack([xy[:, [0, 2, 4, 6]].min(1), xy[:, [1, 3, 5, 7]].min(1), xy[:, [0, 2, 4, 6]].max(1),
                    xy[:, [1, 3, 5, 7]].max(1)], 1).clip(0, size)
    w0, h0 = (lab[:, 3] - lab[:, 1]) * s, (lab[:, 4] - lab[:, 2]) * s
    w1, h1 = new[:, 2] - new[:, 0], new[:, 3] - new[:, 1]
    keep = (w1 > 2) & (h1 > 2) & (w1 * h1 / (w0 * h0 + 1e-9) > 0.1)
    return np.concatenate([lab[keep, :1], new[keep]], 1).astype(np.float32)


def _cutout(img: NDArray[np.uint8], lab: NDArray[np.float32], rng: np.random.Generator,
            p: float) -> tuple[NDArray[np.uint8], NDArray[np.float32]]:
    """With probability ``p``, 1-3 grey rectangles of 5-25% of the side; boxes hidden over 60% are dropped."""
    if rng.uniform() >= p:
        return img, lab
    h, w = img.shape[:2]
    img = img.copy()
    hidden = np.zeros(len(lab))
    for _ in range(int(rng.integers(1, 4))):
        rw, rh = (rng.uniform(0.05, 0.25, 2) * (w, h)).astype(int)
        x0, y0 = int(rng.integers(0, max(w - rw, 1))), int(rng.integers(0, max(h - rh, 1)))
        img[y0:y0 + rh, x0:x0 + rw] = rng.integers(64, 192, 3).astype(np.uint8)
        if len(lab):
            ix = np.clip(np.minimum(lab[:, 3], x0 + rw) - np.maximum(lab[:, 1], x0), 0, None)
            iy = np.clip(np.minimum(lab[:, 4], y0 + rh) - np.maximum(lab[:, 2], y0), 0, None)
            area = np.maximum((lab[:, 3] - lab[:, 1]) * (lab[:, 4] - lab[:, 2]), 1e-9)
            hidden = np.maximum(hidden, ix * iy / area)  # the largest single rectangle's share (a lower bound)
    return img, lab[hidden <= 0.6]


def _photometric(img: NDArray[np.uint8], rng: np.random.Generator, a: Augment) -> NDArray[np.uint8]:
    """Another camera: grey, gamma and white balance (one lookup table per channel), then defocus blur, sensor noise
    and a JPEG round trip, each with its probability (the last draws of a sample: a setting here changes nothing
    before it)."""
    u = rng.uniform(size=10)
    if u[0] < a.grayscale:
        img = np.repeat(cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)[..., None], 3, axis=2)
    if a.gamma or a.white_balance:
        g = float(np.exp((2 * u[1] - 1) * a.gamma))
        gains = np.exp((2 * u[2:5] - 1) * a.white_balance)
        x = np.arange(256, dtype=np.float64) / 255.0
        luts = [np.clip(255.0 * np.clip(x * k, 0, 1) ** g + 0.5, 0, 255).astype(np.uint8) for k in gains]
        img = np.dstack([cv2.LUT(np.ascontiguousarray(img[..., c]), luts[c]) for c in range(3)])
    if u[5] < a.blur:
        img = np.asarray(cv2.GaussianBlur(img, (0, 0), 0.4 + 1.2 * float(u[6])), dtype=np.uint8)
    if u[7] < a.noise:
        sigma = 2.0 + 8.0 * float(u[8])
        noisy = img.astype(np.float32) + rng.normal(0.0, sigma, img.shape).astype(np.float32)
        img = np.clip(noisy + 0.5, 0, 255).astype(np.uint8)
    if u[9] < a.jpeg:
        quality = int(30 + 60 * rng.uniform())
        ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(img[..., ::-1]), [cv2.IMWRITE_JPEG_QUALITY, quality])
        decoded = cv2.imdecode(buf, cv2.IMREAD_COLOR) if ok else None
        if decoded is not None:  # encoded as BGR, as OpenCV's colour conversion for chroma subsampling expects
            img = np.asarray(decoded[..., ::-1], dtype=np.uint8)
    return np.ascontiguousarray(img, dtype=np.uint8)


def _hsv(img: NDArray[np.uint8], rng: np.random.Generator, a: Augment) -> NDArray[np.uint8]:
    r = rng.uniform(-1, 1, 3) * [a.hsv_h, a.hsv_s, a.hsv_v] + 1
    hsv = cv2.cvtColor(img, cv2.COLOR_RGB2HSV)
    x = np.arange(256, dtype=np.float32)
    lut_h = ((x * r[0]) % 180).astype(np.uint8)
    lut_s = np.clip(x * r[1], 0, 255).astype(np.uint8)
    lut_v = np.clip(x * r[2], 0, 255).astype(np.uint8)
    hsv = cv2.merge((cv2.LUT(hsv[..., 0], lut_h), cv2.LUT(hsv[..., 1], lut_s), cv2.LUT(hsv[..., 2], lut_v)))
    return np.asarray(cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB), dtype=np.uint8)


def collate(batch: list[tuple[torch.Tensor, torch.Tensor, ImageMeta]]) -> tuple[torch.Tensor, torch.Tensor,
                                                                                  list[ImageMeta]]:
    """Stack images, padding smaller ones at the bottom and right (validation of frames of several sizes; each
    image's letterbox padding in its meta is unchanged); targets become (T, 6) [image index, class, x0, y0, x1,
    y1]."""
    h = max(b[0].shape[1] for b in batch)
    w = max(b[0].shape[2] for b in batch)
    if all(b[0].shape[1:] == (h, w) for b in batch):
        imgs = torch.stack([b[0] for b in batch])
    else:
        imgs = torch.full((len(batch), 3, h, w), 114 / 255.0)
        for k, b in enumerate(batch):
            imgs[k, :, : b[0].shape[1], : b[0].shape[2]] = b[0]
    targets = [torch.cat([torch.full((len(b[1]), 1), float(i)), b[1]], 1) for i, b in enumerate(batch)]
    return imgs, torch.cat(targets) if targets else torch.zeros((0, 6)), [b[2] for b in batch]


