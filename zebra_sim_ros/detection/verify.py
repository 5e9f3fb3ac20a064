"""A second look at the detector's larger boxes: a small network that tells a zebra from anything else in a crop.

The detector keeps its boxes. Each box whose long side is at least ``min_side`` pixels of the image has its score
multiplied by the verifier's p(zebra) for a square crop around it (the box's long side times ``context``, area-
resized to ``crop`` px); smaller boxes keep their score, so a far zebra of a few pixels is left to the detector
alone. The verifier is trained from scratch on crops of generated frames only (their annotations say which
animal is a zebra): zebras, animals of other species and background squares, under photometric augmentations
(white balance, exposure, contrast, saturation and grey, gamma, lost resolution, blur, noise; JPEG at a random
quality when the crops are cut). Images are RGB, as :func:`zebra_sim_ros.detection.predict.detect` takes them.

A verifier checkpoint is a dict: ``format`` ("zebra_sim_ros/verifier"), ``version``, ``config``
(:class:`VerifierConfig`), ``model`` (state dict), ``train`` (the :class:`TrainVerifierConfig` it was trained with,
seed included), ``crops`` (how many of each kind) and ``val`` (share called zebra per kind on the held-out crops).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import torch
from numpy.typing import NDArray
from torch import nn

from zebra_sim_ros.errors import ParameterError

FORMAT = "zebra_sim_ros/verifier"
VERSION = 1
SHIPPED_VERIFIER = Path(__file__).resolve().parent / "weights" / "zebra_verifier.pt"
KINDS = ("background", "other species", "zebra", "detector's false boxes")  # crop kinds: index = a crop's ``kind``
_STORE_MARGIN = 16  # crops are stored this much larger than the net's input: training draws a random window


@dataclass(frozen=True)
class VerifierConfig:
    """What the verifier sees: ``crop`` px squares around boxes of at least ``min_side`` px, ``context`` times the
    box's long side."""

    crop: int = 96
    context: float = 1.2
    min_side: float = 24.0
    widths: tuple[int, ...] = (32, 64, 96, 128, 192)

    def check(self) -> None:
        if not 32 <= self.crop <= 256:
            raise ParameterError("verifier crop", self.crop, "32..256 px")
        if not 1.0 <= self.context <= 3.0:
            raise ParameterError("verifier context", self.context, "1.0..3.0 (times the box's long side)")
        if not self.min_side >= 1.0:
            raise ParameterError("verifier min_side", self.min_side, ">= 1 px")
        if not self.widths or any(w < 1 for w in self.widths):
            raise ParameterError("verifier widths", self.widths, "a non-empty list of channel counts >= 1")

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> VerifierConfig:
        cfg = cls(int(d["crop"]), float(d["context"]), float(d["min_side"]), tuple(int(w) for w in d["widths"]))
        cfg.check()
        return cfg


class Verifier(nn.Module):
    """Stride-2 stages of two 3x3 convolutions each (batch norm, SiLU), global average, one logit: p(zebra)."""

    def __init__(self, cfg: VerifierConfig | None = None) -> None:
        super().__init__()
        self.cfg = cfg or VerifierConfig()
        self.cfg.check()
        layers: list[nn.Module] = []
        chans = (3, *self.cfg.widths)
        for a, b in zip(chans[:-1], chans[1:], strict=True):
            layers += [nn.Conv2d(a, b, 3, 2, 1, bias=False), nn.BatchNorm2d(b), nn.SiLU(),
                       nn.Conv2d(b, b, 3, 1, 1, bias=False), nn.BatchNorm2d(b), nn.SiLU()]
        self.body = nn.Sequential(*layers)
        self.head = nn.Linear(chans[-1], 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(B, 3, crop, crop) RGB in 0..1 -> (B,) logits of "zebra"."""
        return self.head(self.body(x).mean((2, 3))).squeeze(1)


def square_crop(img: NDArray[np.uint8], box: Sequence[float] | NDArray[Any], context: float, out: int,
                shift: tuple[float, float] = (0.0, 0.0)) -> NDArray[np.uint8]:
    """The square of side ``context`` x the long side of ``box`` [x0, y0, x1, y1] around its centre (moved by
    ``shift`` times the box's width and height), area-averaged (or, enlarged, bilinearly resized) to ``out`` x
    ``out``; beyond the image's edge its edge pixels are repeated."""
    x0, y0, x1, y1 = (float(v) for v in box[:4])
    h, w = img.shape[:2]
    side = max(2, int(round(max(x1 - x0, y1 - y0) * context)))
    cx, cy = (x0 + x1) / 2 + shift[0] * (x1 - x0), (y0 + y1) / 2 + shift[1] * (y1 - y0)
    left, top = int(round(cx - side / 2)), int(round(cy - side / 2))
    pad = max(0, -left, -top, left + side - w, top + side - h)
    src = cv2.copyMakeBorder(img, pad, pad, pad, pad, cv2.BORDER_REPLICATE) if pad else img
    patch = src[top + pad:top + pad + side, left + pad:left + pad + side]
    return np.asarray(cv2.resize(patch, (out, out), interpolation=cv2.INTER_AREA if side > out else cv2.INTER_LINEAR),
                      dtype=np.uint8)


@torch.no_grad()
def zebra_probability(net: Verifier, image: NDArray[np.uint8], boxes: NDArray[Any], batch: int = 64
                      ) -> NDArray[np.float32]:
    """p(zebra) of each box [x0, y0, x1, y1, ...] of an RGB ``image``."""
    if not len(boxes):
        return np.zeros(0, np.float32)
    c = net.cfg
    crops = np.stack([square_crop(image, b, c.context, c.crop) for b in boxes])
    dev = next(net.parameters()).device
    x = torch.from_numpy(crops).permute(0, 3, 1, 2).float().div_(255)
    was = net.training
    net.eval()
    p = torch.cat([torch.sigmoid(net(x[i:i + batch].to(dev))).float().cpu() for i in range(0, len(x), batch)])
    net.train(was)
    return p.numpy().astype(np.float32)


def verify(net: Verifier, image: NDArray[np.uint8], dets: NDArray[Any]) -> NDArray[Any]:
    """``dets`` (n, >= 5) [x0, y0, x1, y1, score, ...] of an RGB ``image`` with the score of every box whose long
    side is at least ``min_side`` px multiplied by its p(zebra); a copy, in the same order."""
    out = np.array(dets, copy=True)
    if not len(out):
        return out
    big = np.maximum(out[:, 2] - out[:, 0], out[:, 3] - out[:, 1]) >= net.cfg.min_side
    if big.any():
        out[big, 4] *= zebra_probability(net, image, out[big])
    return out


def read_rgb(path: str | Path) -> NDArray[np.uint8]:
    """An image file as RGB uint8 (what :func:`verify` crops); a file that cannot be read names itself."""
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise ParameterError("image", str(path), "a readable image file")
    return np.asarray(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB), dtype=np.uint8)


def rescore(net: Verifier, image: NDArray[np.uint8], dets: NDArray[Any], conf: float = 0.0,
            cls: int | None = None) -> NDArray[Any]:
    """:func:`verify` on the rows of ``dets`` whose class (column 5) is ``cls`` (None: every row; other classes keep
    their score), then the rows now scoring under ``conf`` dropped and the rest ordered by score, highest first,
    as NMS leaves them."""
    out = np.array(dets, copy=True)
    if not len(out):
        return out
    mine = np.ones(len(out), bool) if cls is None else out[:, 5] == cls
    if mine.any():
        out[mine] = verify(net, image, out[mine])
    out = out[out[:, 4] >= conf]
    return out[np.argsort(-out[:, 4], kind="stable")]


def save_verifier(path: str | Path, net: Verifier, **extra: Any) -> None:
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.with_name(p.name + ".tmp")
    torch.save({"format": FORMAT, "version": VERSION, "config": {**asdict(net.cfg), "widths": list(net.cfg.widths)},
                "model": net.state_dict(), **extra}, tmp)
    tmp.replace(p)


def load_verifier(path: str | Path | None = None, device: str | torch.device = "cpu",
                  name: str = "verifier") -> tuple[Verifier, dict[str, Any]]:
    """The verifier of a checkpoint (None or "shipped": the package's), in eval mode, and its checkpoint dict
    (without the weights). A missing file is a :class:`ParameterError` naming ``name``; a bad one an
    :class:`AssetError`."""
    from zebra_sim_ros.detection.checkpoint import read_checkpoint

    p = SHIPPED_VERIFIER if path in (None, "", "shipped") else Path(path)
    if not p.is_file():
        raise ParameterError(name, str(p), "an existing verifier checkpoint ('shipped': the package's)")
    ckpt = read_checkpoint(p, name, FORMAT, VERSION)
    net = Verifier(VerifierConfig.from_dict(ckpt["config"]))
    net.load_state_dict({k: v.float() for k, v in ckpt["model"].items()})
    return net.to(device).eval(), {k: v for k, v in ckpt.items() if k != "model"}


# -- training ------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class TrainVerifierConfig:
    """``zebra-sim train-verifier``: crops of the generated datasets in ``data`` (folders with ``annotations/``)."""

    data: tuple[str, ...]
    out: str
    epochs: int = 10
    batch: int = 128
    lr: float = 2e-3
    seed: int = 25
    val_fraction: float = 0.1
    min_visible_pixels: int = 300  # animals with fewer visible pixels are not cropped
    min_visible_fraction: float = 0.3
    background_per_frame: int = 2
    # hard negatives: a detector's boxes on the frames ('shipped' or a checkpoint; '' = none) at mine_imgsz and
    # mine_conf that overlap no zebra become crops of kind "detector's false boxes"
    detector: str = ""
    mine_imgsz: int = 640
    mine_conf: float = 0.1
    model: VerifierConfig = field(default_factory=VerifierConfig)

    def check(self) -> None:
        if not self.data:
            raise ParameterError("--data", list(self.data), "one or more generated dataset folders")
        for d in self.data:
            if not (Path(d) / "annotations").is_dir():
                raise ParameterError("--data", d, "a folder written by zebra-sim generate (with annotations/)")
        for name, value, lo in (("--epochs", self.epochs, 1), ("--batch", self.batch, 2), ("--seed", self.seed, 0),
                                ("--background-per-frame", self.background_per_frame, 0)):
            if value < lo:
                raise ParameterError(name, value, f">= {lo}")
        if not 0 < self.lr <= 1:
            raise ParameterError("--lr", self.lr, "in (0, 1]")
        if not 0 < self.val_fraction < 0.5:
            raise ParameterError("--val-fraction", self.val_fraction, "in (0, 0.5)")
        from zebra_sim_ros.detection.config import imgsz_ok

        if not imgsz_ok(self.mine_imgsz):
            raise ParameterError("--mine-imgsz", self.mine_imgsz, "a multiple of 32 in 64..4096")
        if not 0 < self.mine_conf < 1:
            raise ParameterError("--mine-conf", self.mine_conf, "in (0, 1)")
        if self.detector not in ("", "shipped") and not Path(self.detector).is_file():
            raise ParameterError("--detector", self.detector, "empty, shipped or an existing detector checkpoint")
        self.model.check()

    def to_dict(self) -> dict[str, Any]:
        return {**asdict(self), "data": list(self.data),
                "model": {**asdict(self.model), "widths": list(self.model.widths)}}


@dataclass(frozen=True)
class CropSet:
    """Training crops: ``x`` (N, s, s, 3) RGB uint8, ``y`` 1 for zebras, ``kind`` an index into :data:`KINDS`."""

    x: NDArray[np.uint8]
    y: NDArray[np.float32]
    kind: NDArray[np.int64]

    def counts(self) -> dict[str, int]:
        return {k: int((self.kind == i).sum()) for i, k in enumerate(KINDS)}


def collect_crops(cfg: TrainVerifierConfig) -> CropSet:
    """Two jittered crops (context 1.0-1.5x, centre moved up to 12% of the box, JPEG quality 35-95) of every animal
    with enough visible pixels in the datasets' annotated frames, and ``background_per_frame`` squares per frame
    (24 px to 60% of the short side, log-uniform) that hold no animal's centre; with ``cfg.detector``, also one
    crop (context 1.1-1.3x, centre moved up to 8%) of each of its zebra boxes of ``min_side`` or more whose centre
    lies in no zebra's box (visible or full, don't-care zebras included) and that overlaps none (IoU < 0.1). Seeded
    by ``cfg.seed``; the detector's crops draw from a stream of their own, so the others are the same without it."""
    from zebra_sim_ros.detection.metrics import iou_matrix
    from zebra_sim_ros.detection.model import ZEBRA
    from zebra_sim_ros.detection.predict import detect
    from zebra_sim_ros.messages import FrameAnnotation

    rng = np.random.default_rng([cfg.seed, 0x5E7])
    mine = np.random.default_rng([cfg.seed, 0x4E6])
    detector = None
    if cfg.detector:
        from zebra_sim_ros.detection.checkpoint import load_model

        detector, _ = load_model(None if cfg.detector == "shipped" else cfg.detector)
    store = cfg.model.crop + _STORE_MARGIN
    xs: list[NDArray[np.uint8]] = []
    kinds: list[int] = []
    for d in cfg.data:
        root = Path(d)
        for f in sorted((root / "annotations").glob("*.json")):
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
                    kinds.append(2 if z.is_zebra else 1)
            for _ in range(cfg.background_per_frame):
                side = float(np.exp(rng.uniform(np.log(24), np.log(max(25.0, min(h, w) * 0.6)))))
                cx, cy = rng.uniform(side / 2, max(side / 2 + 1, w - side / 2)), rng.uniform(
                    side / 2, max(side / 2 + 1, h - side / 2))
                if any(abs(px - cx) < side / 2 and abs(py - cy) < side / 2 for px, py in centres):
                    continue
                xs.append(square_crop(img, (cx - side / 2, cy - side / 2, cx + side / 2, cy + side / 2), 1.0, store))
                kinds.append(0)
            if detector is not None:
                zebras = np.array([b for z in ann.labels.zebras if z.is_zebra
                                   for b in (z.box_visible, z.box_full) if b is not None], np.float64).reshape(-1, 4)
                for b in _false_boxes(detect(detector, [img], cfg.mine_imgsz, cfg.mine_conf)[0], zebras,
                                      cfg.model.min_side, ZEBRA, iou_matrix):
                    shift = mine.uniform(-0.08, 0.08, 2)
                    xs.append(square_crop(img, b, float(mine.uniform(1.1, 1.3)), store,
                                          (float(shift[0]), float(shift[1]))))
                    kinds.append(3)
    if not xs:
        raise ParameterError("--data", list(cfg.data), "frames with animals of at least "
                             f"{cfg.min_visible_pixels} visible pixels")
    kind = np.asarray(kinds, np.int64)
    return CropSet(np.stack(xs), (kind == 2).astype(np.float32), kind)


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
    perm = torch.randperm(len(x), generator=g)
    n_val = max(1, int(len(x) * cfg.val_fraction))
    val, tr = perm[:n_val], perm[n_val:]
    net = Verifier(cfg.model).to(memory_format=torch.channels_last)  # type: ignore[call-overload]
    opt = torch.optim.AdamW(net.parameters(), cfg.lr, weight_decay=5e-4)
    per_epoch = max(1, len(tr) // cfg.batch)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, cfg.lr, total_steps=cfg.epochs * per_epoch, pct_start=0.1)
    pos = float(y[tr].mean())
    lossf = nn.BCEWithLogitsLoss(pos_weight=torch.tensor((1 - pos) / pos if 0 < pos < 1 else 1.0))
    from zebra_sim_ros.detection.train import amp_dtype  # the trainer's rule: bfloat16 where the CPU has it

    dtype = amp_dtype("auto", torch.device("cpu"))
    m = (cfg.model.crop + _STORE_MARGIN - cfg.model.crop) // 2
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
    record = {"train": cfg.to_dict(), "crops": crops.counts(), "val": history[-1]["called_zebra"],
              "history": history, "seconds": round(time.perf_counter() - t0, 1)}
    save_verifier(cfg.out, net, **record)
    return record
