"""Training the crop verifier (:mod:`zebra_sim_ros.detection.verify`) from scratch on generated frames only.

Crops of every animal the frames' annotations list (zebras and other species) and of background, optionally the
boxes a detector puts on no zebra (hard negatives), parts of the animals and drawn clutter (foliage, branches,
sky, defocus: what photographs hold and the generator's frames lack), under photometric augmentations;
``zebra-sim train-verifier``.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import torch
from numpy.typing import NDArray
from torch import nn

from zebra_sim_ros.detection.config import SPLITS, TrainVerifierConfig
from zebra_sim_ros.detection.verify import Verifier, read_rgb, save_verifier, square_crop
from zebra_sim_ros.errors import ParameterError

# crop kinds (a crop's ``kind`` indexes KINDS); ZEBRA_KINDS are the ones labelled zebra
BACKGROUND, OTHER_SPECIES, ZEBRA_CROP, FALSE_BOX, CLUTTER, ZEBRA_PART, OTHER_PART = range(7)
KINDS = ("background", "other species", "zebra", "detector's false boxes", "drawn clutter", "parts of zebras",
         "parts of other species")
ZEBRA_KINDS = (ZEBRA_CROP, ZEBRA_PART)
_STORE_MARGIN = 16  # crops are stored this much larger than the net's input: training draws a random window


@dataclass(frozen=True)
class CropSet:
    """Training crops: ``x`` (N, s, s, 3) RGB uint8, ``y`` 1 for zebras (a kind in :data:`ZEBRA_KINDS`),
    ``kind`` an index into :data:`KINDS`, ``frame`` the frame each was cut from (frames numbered through the
    datasets in order; drawn clutter counts as its frame's)."""

    x: NDArray[np.uint8]
    y: NDArray[np.float32]
    kind: NDArray[np.int64]
    frame: NDArray[np.int64]

    def counts(self) -> dict[str, int]:
        return {k: int((self.kind == i).sum()) for i, k in enumerate(KINDS)}


def collect_crops(cfg: TrainVerifierConfig) -> CropSet:
    """Two jittered crops (context 1.0-1.5x, centre moved up to 12% of the box, JPEG quality 35-95) of every animal
    with enough visible pixels in the datasets' annotated frames, and ``background_per_frame`` squares per frame
    (24 px to 60% of the short side, log-uniform) that hold no animal's centre; with ``cfg.detector``, also one
    crop (context 1.1-1.3x, centre moved up to 8%) of each of its zebra boxes of ``min_side`` or more whose centre
    lies in no zebra's box (visible or full, don't-care zebras included) and that overlaps none (IoU < 0.1), nor,
    with ``cfg.mine_on_animals`` off, any other animal's; with ``cfg.parts_per_animal``, squares of part of each
    cropped animal; with ``cfg.clutter_per_frame``, drawn clutter (:func:`draw_clutter`). Seeded by ``cfg.seed``;
    the detector's crops, the parts and the clutter each draw from a stream of their own, so the other crops are the
    same without them."""
    from zebra_sim_ros.detection.metrics import iou_matrix
    from zebra_sim_ros.detection.model import ZEBRA
    from zebra_sim_ros.detection.predict import detect
    from zebra_sim_ros.messages import FrameAnnotation

    rng = np.random.default_rng([cfg.seed, 0x5E7])
    mine = np.random.default_rng([cfg.seed, 0x4E6])
    parts = np.random.default_rng([cfg.seed, 0x9A7])
    clutter = np.random.default_rng([cfg.seed, 0xC17])
    detector = None
    if cfg.detector:
        from zebra_sim_ros.detection.checkpoint import load_model

        detector, _ = load_model(_detector_file(cfg))
    store = cfg.model.crop + _STORE_MARGIN
    xs: list[NDArray[np.uint8]] = []
    kinds: list[int] = []
    frames: list[int] = []  # per crop, the number of the frame it was cut from
    files = [(Path(d), f) for d in cfg.data for f in sorted((Path(d) / "annotations").glob("*.json"))]
    for frame, (root, f) in enumerate(files):
        ann = FrameAnnotation.from_json(f.read_text())
        img = read_rgb(root / ann.image)
        h, w = img.shape[:2]
        centres = []
        for z in ann.labels.zebras:
            if z.box_visible is None:
                continue
            b = np.asarray(z.box_visible, np.float64)
            centres.append(((b[0] + b[2]) / 2, (b[1] + b[3]) / 2))
            if (max(b[2] - b[0], b[3] - b[1]) < cfg.model.min_side or z.visible_pixels < cfg.min_visible_pixels
                    or z.visible_fraction < cfg.min_visible_fraction):
                continue
            for _ in range(2):
                shift = rng.uniform(-0.12, 0.12, 2)
                c = square_crop(img, b, float(rng.uniform(1.0, 1.5)), store, (float(shift[0]), float(shift[1])))
                ok, buf = cv2.imencode(".jpg", c, [cv2.IMWRITE_JPEG_QUALITY, int(rng.integers(35, 96))])
                xs.append(np.asarray(cv2.imdecode(buf, cv2.IMREAD_UNCHANGED), dtype=np.uint8) if ok else c)
                kinds.append(ZEBRA_CROP if z.is_zebra else OTHER_SPECIES)
            long_side = max(b[2] - b[0], b[3] - b[1])
            for _ in range(cfg.parts_per_animal):
                side = long_side * parts.uniform(0.4, 0.75)
                cx, cy = b[0] + (b[2] - b[0]) * parts.uniform(0.25, 0.75), b[1] + (b[3] - b[1]) * parts.uniform(
                    0.25, 0.75)
                xs.append(square_crop(img, (cx - side / 2, cy - side / 2, cx + side / 2, cy + side / 2), 1.0,
                                      store))
                kinds.append(ZEBRA_PART if z.is_zebra else OTHER_PART)
        for _ in range(cfg.background_per_frame):
            side = float(np.exp(rng.uniform(np.log(24), np.log(max(25.0, min(h, w) * 0.6)))))
            cx, cy = rng.uniform(side / 2, max(side / 2 + 1, w - side / 2)), rng.uniform(
                side / 2, max(side / 2 + 1, h - side / 2))
            if any(abs(px - cx) < side / 2 and abs(py - cy) < side / 2 for px, py in centres):
                continue
            xs.append(square_crop(img, (cx - side / 2, cy - side / 2, cx + side / 2, cy + side / 2), 1.0, store))
            kinds.append(BACKGROUND)
        for _ in range(cfg.clutter_per_frame):
            xs.append(draw_clutter(clutter, store))
            kinds.append(CLUTTER)
        if detector is not None:
            keep_off = np.array([b for z in ann.labels.zebras if z.is_zebra or not cfg.mine_on_animals
                                 for b in (z.box_visible, z.box_full) if b is not None], np.float64).reshape(-1, 4)
            for b in _false_boxes(detect(detector, [img], cfg.mine_imgsz, cfg.mine_conf)[0], keep_off,
                                  cfg.model.min_side, ZEBRA, iou_matrix):
                shift = mine.uniform(-0.08, 0.08, 2)
                xs.append(square_crop(img, b, float(mine.uniform(1.1, 1.3)), store,
                                      (float(shift[0]), float(shift[1]))))
                kinds.append(FALSE_BOX)
        frames += [frame] * (len(xs) - len(frames))
    if not xs:
        raise ParameterError("--data", list(cfg.data), "frames with animals of at least "
                             f"{cfg.min_visible_pixels} visible pixels")
    kind = np.asarray(kinds, np.int64)
    return CropSet(np.stack(xs), np.isin(kind, ZEBRA_KINDS).astype(np.float32), kind, np.asarray(frames, np.int64))


def held_out(crops: CropSet, split: str, fraction: float, g: torch.Generator) -> tuple[torch.Tensor, torch.Tensor]:
    """Indices of the held-out and the training crops: a random ``fraction`` of the crops (``split`` "crop"), or
    every crop of a random ``fraction`` of the frames that gave crops ("frame"; at least one frame each side)."""
    if split == "crop":
        perm = torch.randperm(len(crops.x), generator=g)
        n_val = max(1, int(len(crops.x) * fraction))
        return perm[:n_val], perm[n_val:]
    if split != "frame":
        raise ParameterError("--split", split, " or ".join(SPLITS))
    frames = np.unique(crops.frame)
    if len(frames) < 2:
        raise ParameterError("--split", split, "crops from two frames or more (these gave crops from one)")
    n_val = min(len(frames) - 1, max(1, round(len(frames) * fraction)))
    chosen = frames[torch.randperm(len(frames), generator=g)[:n_val].numpy()]
    val = np.isin(crops.frame, chosen)
    return torch.from_numpy(np.flatnonzero(val)), torch.from_numpy(np.flatnonzero(~val))


# natural colours (RGB) for drawn clutter: foliage, bark and soil, rock, shade, and the sky behind them
_FOLIAGE = np.array([[40, 60, 30], [60, 90, 40], [90, 120, 50], [120, 140, 70], [150, 160, 90], [80, 60, 40],
                     [110, 90, 60], [150, 120, 80], [190, 170, 120], [60, 55, 50], [90, 90, 90], [140, 135, 130],
                     [25, 25, 25], [200, 200, 190]], np.float32)
_SKY = np.array([[170, 200, 230], [220, 225, 235], [140, 170, 210], [240, 240, 240], [190, 190, 200]], np.float32)


def draw_clutter(rng: np.random.Generator, side: int) -> NDArray[np.uint8]:
    """A ``side`` px RGB square of what photographs hold around animals and the generator's frames lack: fractal
    texture (4-7 octaves of smooth noise, down to a few px) between two natural colours, one time in three cut by
    a sky, up to five strokes (branches, grass blades, horns) three times in five, light discs (out-of-focus
    highlights) one time in four, then defocus (Gaussian, sigma 0.5-6 px) seven times in ten and JPEG. No regular
    stripes are drawn."""
    def fractal() -> NDArray[np.float32]:
        acc = np.zeros((side, side), np.float32)
        amp, persistence = 1.0, float(rng.uniform(0.4, 0.9))
        for octave in range(int(rng.integers(4, 8))):
            n = 2 + 2 ** octave
            acc += amp * cv2.resize(rng.standard_normal((n, n)).astype(np.float32), (side, side),
                                    interpolation=cv2.INTER_CUBIC)
            amp *= persistence
        acc -= acc.min()
        return np.asarray(acc / max(float(acc.max()), 1e-6), np.float32)

    def colour(table: NDArray[np.float32]) -> NDArray[np.float32]:
        return np.asarray(np.clip(table[rng.integers(len(table))] + rng.uniform(-20, 20, 3), 0, 255), np.float32)

    t = fractal()[..., None]
    img = colour(_FOLIAGE) * (1 - t) + colour(_FOLIAGE) * t
    if rng.random() < 1 / 3:
        img[fractal() > rng.uniform(0.4, 0.7)] = colour(_SKY)
    if rng.random() < 0.6:
        for _ in range(int(rng.integers(1, 6))):
            p0, p1, p2 = rng.uniform(-0.2, 1.2, (3, 2)) * side
            u = np.linspace(0, 1, 24)[:, None]
            pts = ((1 - u) ** 2 * p0 + 2 * u * (1 - u) * p1 + u ** 2 * p2).round().astype(np.int32)
            width = int(np.exp(rng.uniform(0, np.log(max(2.0, side / 8)))))
            cv2.polylines(img, [pts], False, colour(_FOLIAGE).tolist(), width, cv2.LINE_AA)
    if rng.random() < 0.25:
        glow = np.zeros((side, side), np.float32)
        for _ in range(int(rng.integers(3, 16))):
            cx, cy = (int(v) for v in rng.integers(0, side, 2))
            cv2.circle(glow, (cx, cy), int(rng.integers(2, max(3, side // 8))), 1.0, -1, cv2.LINE_AA)
        light = colour(_SKY)
        a = 0.6 * glow[..., None]
        img = img * (1 - a) + light * a
    if rng.random() < 0.7:
        img = cv2.GaussianBlur(img, (0, 0), float(np.exp(rng.uniform(np.log(0.5), np.log(6.0)))))
    out = np.asarray(np.clip(img, 0, 255).round(), np.uint8)
    ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, int(rng.integers(35, 96))])
    return np.asarray(cv2.imdecode(buf, cv2.IMREAD_UNCHANGED), dtype=np.uint8) if ok else out


def _false_boxes(det: NDArray[Any], zebras: NDArray[np.float64], min_side: float, zebra_class: int,
                 iou: Callable[[NDArray[np.float64], NDArray[np.float64]], NDArray[np.float64]]) -> NDArray[Any]:
    """The rows of ``det`` of class ``zebra_class`` and ``min_side`` or more that are on no zebra: centre in none of
    the ``zebras`` boxes and IoU < 0.1 with each."""
    d = det[(det[:, 5] == zebra_class) & (np.maximum(det[:, 2] - det[:, 0], det[:, 3] - det[:, 1]) >= min_side)]
    if not len(d) or not len(zebras):
        return d
    cx, cy = (d[:, 0] + d[:, 2]) / 2, (d[:, 1] + d[:, 3]) / 2
    inside = ((cx[:, None] >= zebras[None, :, 0]) & (cx[:, None] <= zebras[None, :, 2])
              & (cy[:, None] >= zebras[None, :, 1]) & (cy[:, None] <= zebras[None, :, 3])).any(1)
    return d[~inside & (iou(d[:, :4].astype(np.float64), zebras).max(1) < 0.1)]


def augment(x: torch.Tensor, g: torch.Generator, out: int) -> torch.Tensor:
    """A batch (B, 3, s, s) RGB 0..1 of stored crops -> (B, 3, out, out): one random window, flips, white balance
    (+-25% per channel), exposure (0.6-1.4x), contrast (0.6-1.4x), saturation (0.5-1.5x; grey one time in five),
    gamma (e^+-0.4), lost resolution (three in ten: down to 25-75% and back), a 3x3 blur (one in five), noise."""
    b, s = x.shape[0], x.shape[-1]
    i, j = (int(v) for v in torch.randint(0, s - out + 1, (2,), generator=g))
    x = x[:, :, i:i + out, j:j + out]

    def u(*shape: int) -> torch.Tensor:
        return torch.rand(*shape, generator=g)

    x = torch.where((u(b) < 0.5)[:, None, None, None], x.flip(3), x)
    x = x * (1 + 0.25 * (u(b, 3, 1, 1) * 2 - 1)) * (0.6 + 0.8 * u(b, 1, 1, 1))
    mean = x.mean((1, 2, 3), keepdim=True)
    x = (x - mean) * (0.6 + 0.8 * u(b, 1, 1, 1)) + mean
    grey = x.mean(1, keepdim=True)
    sat = torch.where(u(b, 1, 1, 1) < 0.2, torch.zeros(b, 1, 1, 1), 0.5 + u(b, 1, 1, 1))
    x = ((x - grey) * sat + grey).clamp(0, 1) ** torch.exp(0.4 * (u(b, 1, 1, 1) * 2 - 1))
    low = u(b) < 0.3
    if low.any():
        f = float(0.25 + 0.5 * u(1))
        small = nn.functional.interpolate(x[low], scale_factor=f, mode="area")
        x[low] = nn.functional.interpolate(small, size=(out, out), mode="bilinear", align_corners=False)
    blur = u(b) < 0.2
    if blur.any():
        x[blur] = nn.functional.avg_pool2d(x[blur], 3, 1, 1, count_include_pad=False)
    x = x + torch.randn(x.shape, generator=g) * (0.03 * u(b, 1, 1, 1))
    return x.clamp(0, 1)


def _detector_file(cfg: TrainVerifierConfig) -> Path:
    """The checkpoint file that mines ``cfg``'s hard negatives ("shipped": the package's weights)."""
    from zebra_sim_ros.detection.checkpoint import SHIPPED

    return SHIPPED if cfg.detector == "shipped" else Path(cfg.detector)


def train_verifier(cfg: TrainVerifierConfig, log: Callable[[str], None] = print) -> dict[str, Any]:
    """Train a verifier on ``cfg``'s crops (AdamW, one-cycle learning rate, the zebra class weighted to balance
    the rest, bfloat16 autocast where the CPU has it) and save it to ``cfg.out``; returns what the checkpoint
    records besides the weights."""
    cfg.check()
    t0 = time.perf_counter()
    crops = collect_crops(cfg)
    log(f"[train-verifier] {len(crops.x)} crops {crops.counts()} in {time.perf_counter() - t0:.0f} s")
    torch.manual_seed(cfg.seed)
    g = torch.Generator().manual_seed(cfg.seed)
    x = torch.from_numpy(crops.x).permute(0, 3, 1, 2).contiguous()
    y = torch.from_numpy(crops.y)
    kind = torch.from_numpy(crops.kind)
    val, tr = held_out(crops, cfg.split, cfg.val_fraction, g)
    net = Verifier(cfg.model).to(memory_format=torch.channels_last)  # type: ignore[call-overload]
    opt = torch.optim.AdamW(net.parameters(), cfg.lr, weight_decay=5e-4)
    per_epoch = max(1, len(tr) // cfg.batch)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, cfg.lr, total_steps=cfg.epochs * per_epoch, pct_start=0.1)
    pos = float(y[tr].mean())
    lossf = nn.BCEWithLogitsLoss(pos_weight=torch.tensor((1 - pos) / pos if 0 < pos < 1 else 1.0))
    from zebra_sim_ros.detection.checkpoint import amp_dtype, file_sha256

    dtype = amp_dtype("auto", torch.device("cpu"))  # the trainer's rule: bfloat16 where the CPU has it
    m = _STORE_MARGIN // 2  # the centre window of each stored crop
    xv = x[val].float()[:, :, m:m + cfg.model.crop, m:m + cfg.model.crop] / 255
    history = []
    for ep in range(cfg.epochs):
        net.train()
        order = tr[torch.randperm(len(tr), generator=g)]
        total = 0.0
        for k in range(per_epoch):
            idx = order[k * cfg.batch:(k + 1) * cfg.batch]
            xb = augment(x[idx].float() / 255, g, cfg.model.crop).contiguous(memory_format=torch.channels_last)
            with torch.autocast("cpu", dtype=dtype or torch.bfloat16, enabled=dtype is not None):  # CPU only
                logits = net(xb)
            loss = lossf(logits.float(), y[idx])
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            total += float(loss.detach())
        net.eval()
        with torch.no_grad():
            p = torch.cat([torch.sigmoid(net(xv[i:i + 256])) for i in range(0, len(xv), 256)])
        called = {name: round(float((p[kind[val] == i] > 0.5).float().mean()), 4) if (kind[val] == i).any() else None
                  for i, name in enumerate(KINDS)}
        history.append({"epoch": ep + 1, "loss": round(total / per_epoch, 4), "called_zebra": called})
        log(f"[train-verifier] epoch {ep + 1}/{cfg.epochs}: loss {total / per_epoch:.4f}, called zebra on held-out "
            f"crops: {json.dumps(called)} ({time.perf_counter() - t0:.0f} s)")
    record: dict[str, Any] = {"train": cfg.to_dict(), "crops": crops.counts(), "val": history[-1]["called_zebra"],
              "history": history, "seconds": round(time.perf_counter() - t0, 1)}
    if cfg.detector:  # which weights mined the hard negatives: "shipped" names different weights as they change
        record["detector_sha256"] = file_sha256(_detector_file(cfg))
    save_verifier(cfg.out, net, **record)
    return record
