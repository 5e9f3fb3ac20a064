"""The detector: CSP backbone (C2f blocks), PAN neck and an anchor-free decoupled head, in plain torch.

Shapes: input (B, 3, H, W), RGB in [0, 1], H and W multiples of 32. Training output: a list of three maps
(B, 4 * reg_max + nc, H/s, W/s) for strides s = 8, 16, 32, four with ``ModelConfig.p2`` (s = 4, 8, 16, 32).
Inference output: (B, N, 4 + nc) with xyxy boxes in input pixels and class probabilities, N = sum over strides of
(H/s) * (W/s).

``p2`` adds a stride-4 level for the smallest zebras: the stride-8 output upsampled and joined with the stem's
stride-4 features (a C2f), with box and class heads of its own. It is a leaf of the neck (nothing else reads
it), so every other tensor has the same name and shape as without it: a three-level checkpoint initialises a
P2 model (``train --p2 --init``) with its stride-8..32 outputs unchanged and only the new level fresh.

The checkpoint holds :class:`ModelConfig` as a plain dict beside the weights, so a checkpoint alone rebuilds
its model (:func:`build_model`).
"""

from __future__ import annotations

import hashlib
from dataclasses import asdict, dataclass
from typing import Any

import torch
from torch import Tensor, nn

from zebra_sim_ros.detection.boxes import decode_ltrb
from zebra_sim_ros.detection.config import STRIDE, clamp_size
from zebra_sim_ros.errors import ParameterError

ZEBRA = 0  # the class index of zebras in every checkpoint: the class every score (val, bag eval, up) counts
OTHER_ANIMAL = "other_animal"  # the name of the class ``train --other-animals`` adds: any animal that is not a zebra

# (width multiple, depth multiple, maximum channels), as in the YOLO family.
SIZES: dict[str, tuple[float, float, int]] = {"n": (0.25, 0.34, 1024), "s": (0.50, 0.34, 1024),
                                              "m": (0.75, 0.67, 768)}


@dataclass(frozen=True)
class ModelConfig:
    """Everything needed to rebuild a model."""

    size: str = "n"
    nc: int = 1
    names: tuple[str, ...] = ("zebra",)
    reg_max: int = 16
    imgsz: int = 640  # inference size, px, for frames whose long side is ``frame``
    frame: int = 0  # long side of the frames it was trained on, px (0: unknown, serve every frame at ``imgsz``)
    p2: bool = False  # a fourth, stride-4 level (P2) for small objects (see the module docstring)

    def __post_init__(self) -> None:
        if self.size not in SIZES:
            raise ParameterError("model", self.size, f"one of {sorted(SIZES)}")
        if not isinstance(self.p2, bool):
            raise ParameterError("p2", self.p2, "true or false")
        if self.nc != len(self.names):
            raise ParameterError("names", list(self.names), f"{self.nc} class names")
        if self.names[ZEBRA] != "zebra":
            raise ParameterError("names", list(self.names), f"'zebra' as class {ZEBRA}")
        if self.imgsz % 32:
            raise ParameterError("imgsz", self.imgsz, "a multiple of 32")
        if not isinstance(self.frame, int) or self.frame < 0:
            raise ParameterError("frame", self.frame, "0 (unknown) or the training frames' long side in px")

    def serve_size(self, long_side: int) -> int:
        """The inference size for a frame whose long side is ``long_side`` px: the scale the checkpoint serves
        at (``imgsz / frame``) times that side, rounded up to a multiple of 32 within 64..4096 (exactly
        ``imgsz`` for frames of the training size), so a frame of any size sees its zebras at the pixel size
        the model learnt them at. ``imgsz`` for every frame where the training frame size is unknown."""
        if not self.frame:
            return self.imgsz
        return clamp_size(-(-long_side * self.imgsz // (self.frame * STRIDE)) * STRIDE)  # integer: no rounding

    def to_dict(self) -> dict[str, Any]:
        """Plain types only (safe with ``torch.load(weights_only=True)``)."""
        d = asdict(self)
        d["names"] = list(self.names)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> ModelConfig:
        """Inverse of :meth:`to_dict`."""
        return cls(**{**d, "names": tuple(d["names"])})


class Conv(nn.Module):
    """Conv2d + BatchNorm + SiLU."""

    def __init__(self, c1: int, c2: int, k: int = 1, s: int = 1) -> None:
        super().__init__()
        self.conv = nn.Conv2d(c1, c2, k, s, k // 2, bias=False)
        self.bn = nn.BatchNorm2d(c2, eps=1e-3, momentum=0.03)
        self.act = nn.SiLU(inplace=True)

    def forward(self, x: Tensor) -> Tensor:
        return self.act(self.bn(self.conv(x)))

    @torch.no_grad()
    def fuse(self) -> None:
        """Fold the batch norm into the convolution (inference only: the running statistics become weights)."""
        if isinstance(self.bn, nn.Identity):
            return
        bn = self.bn
        assert isinstance(bn, nn.BatchNorm2d) and bn.running_var is not None and bn.running_mean is not None
        std = (bn.running_var + bn.eps).sqrt()
        c = self.conv
        fused = nn.Conv2d(c.in_channels, c.out_channels, c.kernel_size[0], c.stride[0], c.padding[0],  # type: ignore[index]
                          bias=True).to(c.weight.device)
        fused.weight.copy_(c.weight * (bn.weight / std).view(-1, 1, 1, 1))
        assert fused.bias is not None
        fused.bias.copy_(bn.bias - bn.running_mean * bn.weight / std)
        self.conv = fused
        self.bn = nn.Identity()  # type: ignore[assignment]


class Bottleneck(nn.Module):
    """Two 3x3 convolutions with an optional residual."""

    def __init__(self, c: int, shortcut: bool = True) -> None:
        super().__init__()
        self.cv1, self.cv2 = Conv(c, c, 3), Conv(c, c, 3)
        self.add = shortcut

    def forward(self, x: Tensor) -> Tensor:
        y = self.cv2(self.cv1(x))
        return x + y if self.add else y


class C2f(nn.Module):
    """Cross-stage partial block: split, n bottlenecks on one half, concatenate every stage, fuse."""

    def __init__(self, c1: int, c2: int, n: int = 1, shortcut: bool = False) -> None:
        super().__init__()
        self.c = c2 // 2
        self.cv1 = Conv(c1, 2 * self.c, 1)
        self.cv2 = Conv((2 + n) * self.c, c2, 1)
        self.m = nn.ModuleList(Bottleneck(self.c, shortcut) for _ in range(n))

    def forward(self, x: Tensor) -> Tensor:
        y = list(self.cv1(x).chunk(2, 1))
        for m in self.m:
            y.append(m(y[-1]))
        return self.cv2(torch.cat(y, 1))


class SPPF(nn.Module):
    """Spatial pyramid pooling (fast): three chained 5x5 max-pools, concatenated."""

    def __init__(self, c1: int, c2: int) -> None:
        super().__init__()
        c = c1 // 2
        self.cv1, self.cv2 = Conv(c1, c, 1), Conv(c * 4, c2, 1)
        self.m = nn.MaxPool2d(5, 1, 2)

    def forward(self, x: Tensor) -> Tensor:
        x = self.cv1(x)
        y1 = self.m(x)
        y2 = self.m(y1)
        return self.cv2(torch.cat([x, y1, y2, self.m(y2)], 1))


class DFL(nn.Module):
    """Distribution focal loss integral: expected distance from reg_max bins."""

    def __init__(self, reg_max: int) -> None:
        super().__init__()
        self.bins: Tensor
        self.register_buffer("bins", torch.arange(reg_max, dtype=torch.float32), persistent=False)
        self.reg_max = reg_max

    def forward(self, x: Tensor) -> Tensor:
        # x: (B, 4 * reg_max, N) -> (B, 4, N)
        b, _, n = x.shape
        p = x.view(b, 4, self.reg_max, n).softmax(2)
        return (p * self.bins.view(1, 1, -1, 1)).sum(2)


class Detector(nn.Module):
    """The whole detector (see the module docstring for shapes)."""

    P2_MODULES = ("td2", "box_head_p2", "cls_head_p2")  # the stride-4 level's modules (``ModelConfig.p2``)

    def __init__(self, cfg: ModelConfig) -> None:
        super().__init__()
        self.cfg = cfg
        self.strides: tuple[int, ...] = (4, 8, 16, 32) if cfg.p2 else (8, 16, 32)
        # in eval mode, the autocast dtype of the features (None: float32); the boxes are decoded in float32 always
        self.serve_dtype: torch.dtype | None = None
        wm, dm, cmax = SIZES[cfg.size]

        def ch(c: int) -> int:
            return int(min(c, cmax) * wm)

        def depth(n: int) -> int:
            return max(round(n * dm), 1)

        self.stem = nn.Sequential(Conv(3, ch(64), 3, 2), Conv(ch(64), ch(128), 3, 2),
                                  C2f(ch(128), ch(128), depth(3), True))
        self.p3 = nn.Sequential(Conv(ch(128), ch(256), 3, 2), C2f(ch(256), ch(256), depth(6), True))
        self.p4 = nn.Sequential(Conv(ch(256), ch(512), 3, 2), C2f(ch(512), ch(512), depth(6), True))
        self.p5 = nn.Sequential(Conv(ch(512), ch(1024), 3, 2), C2f(ch(1024), ch(1024), depth(3), True),
                                SPPF(ch(1024), ch(1024)))
        self.up = nn.Upsample(scale_factor=2, mode="nearest")
        self.td4 = C2f(ch(1024) + ch(512), ch(512), depth(3))
        self.td3 = C2f(ch(512) + ch(256), ch(256), depth(3))
        self.down3 = Conv(ch(256), ch(256), 3, 2)
        self.bu4 = C2f(ch(256) + ch(512), ch(512), depth(3))
        self.down4 = Conv(ch(512), ch(512), 3, 2)
        self.bu5 = C2f(ch(512) + ch(1024), ch(1024), depth(3))
        chans = (ch(256), ch(512), ch(1024))
        r = cfg.reg_max
        c2 = max(16, chans[0] // 4, 4 * r)
        c3 = max(chans[0], min(cfg.nc, 100))
        self.box_head = nn.ModuleList(nn.Sequential(Conv(c, c2, 3), Conv(c2, c2, 3), nn.Conv2d(c2, 4 * r, 1))
                                      for c in chans)
        self.cls_head = nn.ModuleList(nn.Sequential(Conv(c, c3, 3), Conv(c3, c3, 3), nn.Conv2d(c3, cfg.nc, 1))
                                      for c in chans)
        if cfg.p2:
            c = ch(128)
            self.td2 = C2f(ch(256) + c, c, depth(3))
            c2p, c3p = max(16, c // 4, 4 * r), max(c, min(cfg.nc, 100))
            self.box_head_p2 = nn.Sequential(Conv(c, c2p, 3), Conv(c2p, c2p, 3), nn.Conv2d(c2p, 4 * r, 1))
            self.cls_head_p2 = nn.Sequential(Conv(c, c3p, 3), Conv(c3p, c3p, 3), nn.Conv2d(c3p, cfg.nc, 1))
        self.dfl = DFL(r)
        self._init_biases()

    def _init_biases(self) -> None:
        import math

        for box, cls, s in zip(self.box_heads(), self.cls_heads(), self.strides, strict=True):
            box_out, cls_out = box[-1], cls[-1]  # type: ignore[index]
            assert isinstance(box_out, nn.Conv2d) and isinstance(cls_out, nn.Conv2d)
            nn.init.constant_(box_out.bias, 1.0)  # type: ignore[arg-type]
            # Prior: about 5 objects per 640 px image, spread over the cells of this stride.
            nn.init.constant_(cls_out.bias, math.log(5 / self.cfg.nc / (640 / s) ** 2))  # type: ignore[arg-type]

    def box_heads(self) -> list[nn.Module]:
        """The box heads, one per stride, finest first."""
        return ([self.box_head_p2] if self.cfg.p2 else []) + list(self.box_head)

    def cls_heads(self) -> list[nn.Module]:
        """The class heads, one per stride, finest first."""
        return ([self.cls_head_p2] if self.cfg.p2 else []) + list(self.cls_head)

    def fuse(self) -> Detector:
        """Fold every batch norm into its convolution for faster inference (the model must be in eval mode)."""
        if self.training:
            raise RuntimeError("fuse() is for inference: call .eval() first")
        for m in self.modules():
            if isinstance(m, Conv):
                m.fuse()
        return self

    def features(self, x: Tensor) -> list[Tensor]:
        """Raw head outputs per stride: (B, 4 * reg_max + nc, H/s, W/s)."""
        x2 = self.stem(x)
        p3 = self.p3(x2)
        p4 = self.p4(p3)
        p5 = self.p5(p4)
        t4 = self.td4(torch.cat([self.up(p5), p4], 1))
        n3 = self.td3(torch.cat([self.up(t4), p3], 1))
        n4 = self.bu4(torch.cat([self.down3(n3), t4], 1))
        n5 = self.bu5(torch.cat([self.down4(n4), p5], 1))
        levels = [n3, n4, n5]
        if self.cfg.p2:
            levels.insert(0, self.td2(torch.cat([self.up(n3), x2], 1)))
        return [torch.cat([b(f), c(f)], 1) for f, b, c in zip(levels, self.box_heads(), self.cls_heads(),
                                                               strict=True)]

    @property
    def serve_precision(self) -> str:
        """The dtype its features are served in, as logs name it: float32, bfloat16 or float16."""
        return str(self.serve_dtype or torch.float32).removeprefix("torch.")

    def forward(self, x: Tensor) -> Tensor | list[Tensor]:
        if self.training or self.serve_dtype is None:
            feats = self.features(x)
            return feats if self.training else self.decode(feats)
        with torch.autocast(x.device.type, dtype=self.serve_dtype):
            feats = self.features(x)
        # anchors and strides in bfloat16 would round cell centres past 256 to 2 cells (mAP50 0.49 against 0.77)
        with torch.autocast(x.device.type, enabled=False):
            return self.decode([f.float() for f in feats])

    def decode(self, feats: list[Tensor]) -> Tensor:
        """(B, N, 4 + nc): xyxy boxes in input pixels and class probabilities."""
        anchors, strides = make_anchors(feats, self.strides)
        b = feats[0].shape[0]
        x = torch.cat([f.view(b, f.shape[1], -1) for f in feats], 2)  # (B, 4r + nc, N)
        r = self.cfg.reg_max
        dist = self.dfl(x[:, : 4 * r])  # (B, 4, N) in stride units
        boxes = decode_ltrb(anchors[None], dist.transpose(1, 2)) * strides[None]
        return torch.cat([boxes, x[:, 4 * r:].sigmoid().transpose(1, 2)], 2)


def make_anchors(feats: list[Tensor], strides: tuple[int, ...]) -> tuple[Tensor, Tensor]:
    """Anchor points (N, 2) at cell centres in stride units, and the stride of each (N, 1)."""
    points, out_strides = [], []
    for f, s in zip(feats, strides, strict=True):
        h, w = f.shape[2:]
        ys = torch.arange(h, device=f.device, dtype=f.dtype) + 0.5
        xs = torch.arange(w, device=f.device, dtype=f.dtype) + 0.5
        gy, gx = torch.meshgrid(ys, xs, indexing="ij")
        points.append(torch.stack([gx, gy], -1).view(-1, 2))
        out_strides.append(torch.full((h * w, 1), float(s), device=f.device, dtype=f.dtype))
    return torch.cat(points), torch.cat(out_strides)


def p2_tensors(state: dict[str, Any]) -> list[str]:
    """The names of a state dict's tensors that belong to the stride-4 level (``ModelConfig.p2``); none for a
    three-level model's."""
    prefixes = tuple(f"{m}." for m in Detector.P2_MODULES)
    return [k for k in state if k.startswith(prefixes)]


WIDENS = {"n": "s"}  # the sizes :func:`widen_state` grows a checkpoint between: every channel count doubles


def state_digest(state: dict[str, Tensor]) -> str:
    """The first 12 hex digits of a sha256 over a state dict's names and float32 values: the same weights give
    the same digest whatever file, dtype of storage or path they come from."""
    h = hashlib.sha256()
    for name in sorted(state):
        v = state[name]
        h.update(name.encode())
        h.update((v.float() if v.is_floating_point() else v).contiguous().cpu().numpy().tobytes())
    return h.hexdigest()[:12]


@dataclass(frozen=True)
class Widening:
    """Where a model's weights were widened from: ``train --init`` of the narrower checkpoint ``source``, of model
    ``size``, whose weights have the :func:`state_digest` ``digest``, the copies' shares drawn with ``seed``
    (:func:`widen_state`). Checkpoints keep it as :meth:`to_dict` under ``widened``, through later runs from them,
    resumes and exports, so ``export --blend-base`` can widen that very checkpoint again. ``digest`` is None only in
    records written before it was kept (nothing to check a base against)."""

    source: str
    size: str
    seed: int
    digest: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """The record as a checkpoint stores it (:meth:`from_dict` reads it back)."""
        return {"from": self.source, "size": self.size, "seed": self.seed,
                **({"digest": self.digest} if self.digest is not None else {})}

    @classmethod
    def from_dict(cls, d: Any, name: str, path: str) -> Widening | None:
        """A checkpoint's ``widened`` record ``d`` (None: its weights were not widened). A malformed one is refused,
        named by the option ``name`` that gave the checkpoint and its ``path``."""
        if d is None:
            return None
        fields = ("from", "size", "seed", "digest")
        ok = (isinstance(d, dict) and all(isinstance(d.get(k), str) for k in ("from", "size"))
              and isinstance(d.get("seed"), int) and not isinstance(d.get("seed"), bool)
              and isinstance(d.get("digest", ""), str) and set(d) <= set(fields))
        if not ok:
            raise ParameterError(name, path, f"a checkpoint whose 'widened' record holds from, size (text), seed (an "
                                             f"integer) and optionally digest (text), nothing else; it holds {d!r}")
        return cls(d["from"], d["size"], d["seed"], d.get("digest"))


def widen_state(state: dict[str, Tensor], cfg: ModelConfig | dict[str, Any], size: str,
                seed: int, name: str = "--init") -> dict[str, Tensor]:
    """The weights of a ``size`` model that computes what ``state`` (a ``cfg`` model's) computes: a
    function-preserving widening (Net2WiderNet, Chen et al. 2016) from ``n`` to ``s``, whose every feature map has
    twice the channels (the same depth, head outputs and box-branch width).

    Feature channel ``k`` of the wide model is channel ``k // 2`` of the narrow one (interleaved copies, which
    commute with the C2f's split and every concatenation). A convolution's output channels and a batch norm's
    statistics are copied; where its input channels were doubled, each pair of copies shares the old weight
    ``w`` as ``a * w`` and ``(1 - a) * w``, with ``a`` drawn per weight from U(0.25, 0.75) by ``seed``: the
    sum, so the function, is unchanged (up to rounding), and the unequal shares give each copy its own gradient,
    so the copies part as the wide model trains. Stride-4 tensors (``p2``) widen like the rest. ``name``: the
    option that gave ``state``, for errors."""
    src = cfg if isinstance(cfg, ModelConfig) else ModelConfig.from_dict(cfg)
    if WIDENS.get(src.size) != size:
        pairs = ", ".join(f"{a} -> {b}" for a, b in WIDENS.items())
        raise ParameterError("--model", size, f"{WIDENS[src.size]!r}, the size a {src.size!r} checkpoint widens to "
                             f"(widenings: {pairs})" if src.size in WIDENS else
                             f"none: a {src.size!r} checkpoint does not widen (widenings: {pairs})")
    target = Detector(ModelConfig(**{**asdict(src), "size": size})).state_dict()
    if set(target) != set(state):
        bad = sorted(set(target) ^ set(state))
        raise ParameterError(name, f"{len(bad)} tensor(s) of another name, first {bad[0]}",
                             f"the tensors of a model of size {src.size!r} with the same classes and levels")
    gen = torch.Generator().manual_seed(int(seed))
    out: dict[str, Tensor] = {}
    for key, t in target.items():  # in the model's own order: the same seed gives the same shares
        v = state[key].float() if state[key].is_floating_point() else state[key]
        if v.shape == t.shape:
            out[key] = v.clone()
            continue
        ratios = [b / a for a, b in zip(v.shape, t.shape, strict=True)] if v.ndim == t.ndim else []
        if not ratios or any(r not in (1, 2) for r in ratios[:2]) or any(r != 1 for r in ratios[2:]):
            raise ParameterError(name, f"{key} of shape {tuple(v.shape)}",
                                 f"the shape {tuple(t.shape)} or half of it in its channel dimensions")
        if ratios[0] == 2:  # output channels (or a batch norm's): copies
            v = v.repeat_interleave(2, 0)
        if len(ratios) > 1 and ratios[1] == 2:  # input channels: each copy a share of the old weight
            a = 0.25 + 0.5 * torch.rand(v.shape, generator=gen)
            v = torch.stack([a * v, (1.0 - a) * v], 2).flatten(1, 2)
        out[key] = v
    return out


def build_model(cfg: ModelConfig | dict[str, Any]) -> Detector:
    """A detector from a config (or its dict, as stored in checkpoints)."""
    return Detector(cfg if isinstance(cfg, ModelConfig) else ModelConfig.from_dict(cfg))


def count_parameters(model: nn.Module) -> int:
    """Number of parameters."""
    return sum(p.numel() for p in model.parameters())
