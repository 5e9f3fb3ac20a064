"""A second look at the detector's larger boxes: a small network that tells a zebra from anything else in a crop.

The detector keeps its boxes. Each box whose long side is at least ``min_side`` pixels of the image, and at least
``min_side_fraction`` of the image's long side, has its score multiplied by the verifier's p(zebra) for a square
crop around it (the box's long side times ``context``, area-resized to ``crop`` px); smaller boxes keep their score,
so a far zebra of a few pixels is left to the detector alone. The verifier is trained from scratch on crops of
generated frames only (their annotations say which animal is a zebra): zebras, animals of other species and
background squares, under photometric augmentations (white balance, exposure, contrast, saturation and grey, gamma,
lost resolution, blur, noise; JPEG at a random quality when the crops are cut). Images are RGB, as
:func:`zebra_sim_ros.detection.predict.detect` takes them.

Training (``zebra-sim train-verifier``) is :mod:`zebra_sim_ros.detection.verify_train`. A verifier checkpoint is a
dict: ``format`` ("zebra_sim_ros/verifier"), ``version``, ``config``
(:class:`~zebra_sim_ros.detection.config.VerifierConfig`), ``model`` (state dict), ``train`` (the
:class:`~zebra_sim_ros.detection.config.TrainVerifierConfig` it was trained with, seed included), ``crops`` (how
many of each kind), ``val`` (share called zebra per kind on the held-out crops) and, where hard negatives were mined,
``detector_sha256`` (the mining detector's file). An ensemble (:func:`ensemble_verifiers`, ``zebra-sim
verifier-ensemble``) is a verifier whose config has ``members`` > 1: its ``model`` holds each member's weights
(``members.<i>.``) and its ``members`` key each member's file sha256 and record.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import torch
from numpy.typing import NDArray
from torch import nn

from zebra_sim_ros.detection.config import MAX_MEMBERS, VerifierConfig
from zebra_sim_ros.errors import ParameterError

FORMAT = "zebra_sim_ros/verifier"
VERSION = 1  # one network
ENSEMBLE_VERSION = 2  # members > 1: a build that reads version 1 only refuses it by its version, not by its keys
SHIPPED_VERIFIER = Path(__file__).resolve().parent / "weights" / "zebra_verifier.pt"


class Verifier(nn.Module):
    """Stride-2 stages of two 3x3 convolutions each (batch norm, SiLU), global average, one logit: p(zebra). With
    ``cfg.members`` > 1, that many such networks (``self.members``), their probabilities averaged."""

    def __init__(self, cfg: VerifierConfig | None = None) -> None:
        super().__init__()
        self.cfg = cfg or VerifierConfig()
        self.cfg.check()
        if self.cfg.members > 1:
            one = replace(self.cfg, members=1)
            self.members = nn.ModuleList(Verifier(one) for _ in range(self.cfg.members))
            return
        layers: list[nn.Module] = []
        chans = (3, *self.cfg.widths)
        for a, b in zip(chans[:-1], chans[1:], strict=True):
            layers += [nn.Conv2d(a, b, 3, 2, 1, bias=False), nn.BatchNorm2d(b), nn.SiLU(),
                       nn.Conv2d(b, b, 3, 1, 1, bias=False), nn.BatchNorm2d(b), nn.SiLU()]
        self.body = nn.Sequential(*layers)
        self.head = nn.Linear(chans[-1], 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(B, 3, crop, crop) RGB in 0..1 -> (B,) logits of "zebra" (an ensemble's: the logit of its mean p)."""
        if self.cfg.members > 1:
            return torch.logit(self.probability(x), eps=1e-7)
        return self.head(self.body(x).mean((2, 3))).squeeze(1)

    def probability(self, x: torch.Tensor) -> torch.Tensor:
        """(B, 3, crop, crop) RGB in 0..1 -> (B,) p(zebra): an ensemble's is its members' mean."""
        if self.cfg.members > 1:
            return torch.stack([torch.sigmoid(m(x)) for m in self.members]).mean(0)
        return torch.sigmoid(self(x))

    @property
    def fused(self) -> bool:
        """Whether :meth:`fuse` folded the batch norms away (a network for serving only)."""
        if self.cfg.members > 1:  # one member folded is enough to make the whole untrainable and unsavable
            return any(m.fused for m in self.members)  # type: ignore[union-attr]
        return not any(isinstance(m, nn.BatchNorm2d) for m in self.body)

    @torch.no_grad()
    def fuse(self) -> Verifier:
        """Fold each batch norm's running statistics into the convolution before it and lay the weights out
        channels-last, as the crops arrive (``zebra_probability`` permutes HWC crops): for serving, in place; the
        same p(zebra) to float32 rounding in 0.78-0.87x the time. A fused verifier can be neither trained nor saved."""
        if self.cfg.members > 1:
            for m in self.members:
                m.fuse()  # type: ignore[operator]
            return self.eval()
        layers: list[nn.Module] = []
        mods = list(self.body)
        i = 0
        while i < len(mods):
            conv, bn = mods[i], mods[i + 1] if i + 1 < len(mods) else None
            if isinstance(conv, nn.Conv2d) and isinstance(bn, nn.BatchNorm2d):
                assert bn.running_var is not None and bn.running_mean is not None
                scale = bn.weight / (bn.running_var + bn.eps).sqrt()
                folded = nn.Conv2d(conv.in_channels, conv.out_channels, conv.kernel_size,  # type: ignore[arg-type]
                                   conv.stride, conv.padding, bias=True).to(conv.weight.device)  # type: ignore[arg-type]
                folded.weight.copy_(conv.weight * scale.view(-1, 1, 1, 1))
                assert folded.bias is not None
                folded.bias.copy_(bn.bias - bn.running_mean * scale)
                layers.append(folded)
                i += 2
            else:
                layers.append(conv)
                i += 1
        self.body = nn.Sequential(*layers)
        self.to(memory_format=torch.channels_last)  # type: ignore[call-overload]
        return self.eval()

    def train(self, mode: bool = True) -> Verifier:
        if mode and self.fused:
            raise RuntimeError("a fused verifier (batch norms folded for serving) cannot be trained: load it with "
                               "load_verifier(..., fuse=False)")
        return super().train(mode)


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
    r0, r1, c0, c1 = max(top, 0), min(top + side, h), max(left, 0), min(left + side, w)  # the part inside the image
    patch: NDArray[np.uint8]
    if (r0, r1, c0, c1) == (top, top + side, left, left + side):
        patch = img[top:top + side, left:left + side]
    elif r0 < r1 and c0 < c1:  # that part with its edge pixels repeated, not the whole image padded (a copy per box)
        patch = np.asarray(cv2.copyMakeBorder(img[r0:r1, c0:c1], r0 - top, top + side - r1, c0 - left,
                                              left + side - c1, cv2.BORDER_REPLICATE), dtype=np.uint8)
    else:  # wholly outside (a shifted training crop): each pixel the nearest edge pixel
        rows = np.clip(np.arange(top, top + side), 0, h - 1)
        cols = np.clip(np.arange(left, left + side), 0, w - 1)
        patch = img[rows[:, None], cols[None, :]]
    return np.asarray(cv2.resize(patch, (out, out), interpolation=cv2.INTER_AREA if side > out else cv2.INTER_LINEAR),
                      dtype=np.uint8)


@torch.no_grad()
def zebra_probability(net: Verifier, image: NDArray[np.uint8], boxes: NDArray[Any], batch: int = 64
                      ) -> NDArray[np.float32]:
    """p(zebra) of each box [x0, y0, x1, y1, ...] of an RGB ``image``: the mean over the crops of
    :meth:`VerifierConfig.views` (and, for an ensemble, over its members)."""
    if not len(boxes):
        return np.zeros(0, np.float32)
    c = net.cfg
    views = c.views()
    cut = {ctx: np.stack([square_crop(image, b, ctx, c.crop) for b in boxes])  # each context cut once
           for ctx in dict.fromkeys(ctx for ctx, _ in views)}
    crops = np.concatenate([cut[ctx][:, :, ::-1] if flip else cut[ctx] for ctx, flip in views])  # view-major
    dev = next(net.parameters()).device
    x = torch.from_numpy(crops).permute(0, 3, 1, 2).float().div_(255)
    was = net.training
    net.eval()
    p = torch.cat([net.probability(x[i:i + batch].to(dev)).float().cpu() for i in range(0, len(x), batch)])
    net.train(was)
    return p.view(len(views), len(boxes)).mean(0).numpy().astype(np.float32)


def judged_side(cfg: VerifierConfig, image_shape: tuple[int, ...]) -> float:
    """The long side from which a box of an image of ``image_shape`` (h, w, ...) is judged: ``min_side`` px, or
    ``min_side_fraction`` of the image's long side if that is more."""
    return max(cfg.min_side, cfg.min_side_fraction * max(image_shape[:2]))


def verify(net: Verifier, image: NDArray[np.uint8], dets: NDArray[Any]) -> NDArray[Any]:
    """``dets`` (n, >= 5) [x0, y0, x1, y1, score, ...] of an RGB ``image`` with the score of every box whose long
    side is at least :func:`judged_side` multiplied by its p(zebra), or by p(zebra) to the verifier's ``power``
    where the long side is also its ``power_from`` of the image's long side or more; a copy, in the same order."""
    out = np.array(dets, copy=True)
    if not len(out):
        return out
    side = np.maximum(out[:, 2] - out[:, 0], out[:, 3] - out[:, 1])
    big = side >= judged_side(net.cfg, image.shape)
    if big.any():
        p = zebra_probability(net, image, out[big])
        if net.cfg.power != 1.0:
            strong = side[big] >= net.cfg.power_from * max(image.shape[:2])
            p = np.where(strong, p ** np.float32(net.cfg.power), p).astype(np.float32)
        out[big, 4] *= p
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


def save_verifier(path: str | Path, net: Verifier, *, half: bool = False, **extra: Any) -> None:
    """Write ``net`` and ``extra`` as a verifier checkpoint (its floating-point weights in float16 with ``half``:
    half the file, read back as float32)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.with_name(p.name + ".tmp")
    if net.fused:
        raise ParameterError("verifier", str(p), "an unfused verifier to save (this one's batch norms are folded "
                             "for serving: load it with fuse=False)")
    state = {k: v.half() if half and v.is_floating_point() else v for k, v in net.state_dict().items()}
    torch.save({"format": FORMAT, "version": ENSEMBLE_VERSION if net.cfg.members > 1 else VERSION,
                "config": net.cfg.to_dict(),
                "model": state, **extra}, tmp)
    tmp.replace(p)


def load_verifier(path: str | Path | None = None, device: str | torch.device = "cpu",
                  name: str = "verifier", fuse: bool = True) -> tuple[Verifier, dict[str, Any]]:
    """The verifier of a checkpoint (None or "shipped": the package's), in eval mode, and its checkpoint dict
    (without the weights). ``fuse``: its batch norms folded for serving (:meth:`Verifier.fuse`); without, a network
    that can be trained, saved or joined into an ensemble. A missing file is a :class:`ParameterError` naming
    ``name``; a bad one an :class:`AssetError`."""
    ckpt, net = _read_verifier(path, name)
    net = net.to(device).eval()
    return net.fuse() if fuse else net, {k: v for k, v in ckpt.items() if k != "model"}


def _read_verifier(path: str | Path | None, name: str) -> tuple[dict[str, Any], Verifier]:
    """The checkpoint dict of the verifier at ``path`` (:func:`verifier_file`) and its network, unfused, on the
    CPU; errors as :func:`load_verifier` says."""
    from zebra_sim_ros.detection.checkpoint import load_weights, read_checkpoint

    p = verifier_file(path)
    if not p.is_file():
        raise ParameterError(name, str(p), "an existing verifier checkpoint ('shipped': the package's)")
    ckpt = read_checkpoint(p, name, FORMAT, (VERSION, ENSEMBLE_VERSION))
    net = Verifier(VerifierConfig.from_dict(ckpt["config"]))
    load_weights(net, ckpt["model"], f"{name} {p}: its weights do not fit its config {ckpt['config']}")
    return ckpt, net


def verifier_file(path: str | Path | None) -> Path:
    """The file a verifier argument names: None, "" or "shipped" the package's, else the path itself."""
    return SHIPPED_VERIFIER if path in (None, "", "shipped") else Path(path)


SERVING = ("min_side_fraction", "contexts", "mirror", "power", "power_from")  # VerifierConfig's serving-only fields


def reserve_verifier(path: str | Path, out: str | Path, **serving: Any) -> dict[str, Any]:
    """Write to ``out`` the verifier at ``path`` ("shipped": the package's; a single one or an ensemble) with other
    serving settings (``serving``: fields of :data:`SERVING`; those not given kept): the same weights, as stored,
    and the same record. Returns the new config (``config``), the file read (``from``) and its record (less its
    history); a bad setting is a ParameterError naming its field."""
    unknown = sorted(set(serving) - set(SERVING))
    if unknown:
        raise ParameterError(unknown[0], serving[unknown[0]], f"one of the serving settings {list(SERVING)}")
    ckpt, net = _read_verifier(path, "verifier")  # its weights fit its config
    changes: dict[str, Any] = {k: tuple(float(c) for c in v) if k == "contexts" else v for k, v in serving.items()}
    cfg = replace(net.cfg, **changes)
    cfg.check()
    p = Path(out)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.with_name(p.name + ".tmp")
    torch.save({**ckpt, "config": cfg.to_dict()}, tmp)
    tmp.replace(p)
    return {"config": cfg.to_dict(), "from": str(verifier_file(path)),
            **{k: v for k, v in ckpt.items() if k not in ("format", "version", "config", "history", "model")}}


def ensemble_verifiers(paths: Sequence[str | Path], out: str | Path, contexts: Sequence[float] | None = None,
                       mirror: bool | None = None, half: bool = False) -> dict[str, Any]:
    """Write to ``out`` one verifier that averages the p(zebra) of the single verifiers at ``paths`` (2 to
    MAX_MEMBERS of them, distinct files of one network shape, crop, context and ``min_side``; "shipped" for
    :data:`SHIPPED_VERIFIER`). Its serving settings are the first member's, ``contexts`` and ``mirror`` overriding
    theirs where given; ``half`` stores the weights in float16. Returns the checkpoint's record (without weights):
    ``members`` lists each file's sha256 and record."""
    from zebra_sim_ros.detection.checkpoint import file_sha256

    if not 2 <= len(paths) <= MAX_MEMBERS:
        raise ParameterError("members", [str(p) for p in paths], f"2..{MAX_MEMBERS} verifier checkpoints")
    if contexts is not None:  # checked before any member is read: the error names the option, not a member
        replace(VerifierConfig(), contexts=tuple(float(c) for c in contexts)).check()
    nets: list[Verifier] = []
    records: list[dict[str, Any]] = []
    shas: list[str] = []
    for path in paths:
        net, record = load_verifier(path, "cpu", "members", fuse=False)
        if net.cfg.members != 1:
            raise ParameterError("members", str(path), "a single verifier (this one is an ensemble already)")
        first = nets[0].cfg if nets else net.cfg
        for field in ("crop", "context", "min_side", "widths"):
            if getattr(net.cfg, field) != getattr(first, field):
                raise ParameterError("members", str(path), f"a verifier of the first one's {field} "
                                     f"{getattr(first, field)!r} (this one has {getattr(net.cfg, field)!r})")
        sha = file_sha256(verifier_file(path))
        if sha in shas:
            raise ParameterError("members", str(path), "verifiers trained apart (this file is an earlier member's)")
        nets.append(net)
        records.append(record)
        shas.append(sha)
    cfg = replace(nets[0].cfg, members=len(nets),
                  contexts=nets[0].cfg.contexts if contexts is None else tuple(float(c) for c in contexts),
                  mirror=nets[0].cfg.mirror if mirror is None else bool(mirror))
    ens = Verifier(cfg)
    for slot, net in zip(ens.members, nets, strict=True):
        slot.load_state_dict(net.state_dict())
    members = [{"sha256": sha, "file": str(path), **{k: v for k, v in rec.items()
                                                      if k not in ("format", "version", "config")}}
               for sha, path, rec in zip(shas, paths, records, strict=True)]
    save_verifier(out, ens.eval(), half=half, members=members, float16=half)
    return {"config": cfg.to_dict(), "members": members, "float16": half}
