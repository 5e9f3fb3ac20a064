"""Checkpoints: weights with the model config beside them, loaded safely (``weights_only=True``).

A checkpoint is a dict of plain types and tensors: ``format`` ("zebra_sim_ros/detector"), ``version``,
``config`` (:class:`~zebra_sim_ros.detection.model.ModelConfig` as a dict), ``model`` (state dict; EMA weights,
fp16 in shipped files), ``epoch``, ``metrics``, ``train_args`` and, for resuming, ``optimizer`` and ``ema_updates``.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Any

import torch

from zebra_sim_ros.detection.config import AMP_MODES, SCALE_RANGE, imgsz_ok
from zebra_sim_ros.detection.model import Detector, ModelConfig, build_model
from zebra_sim_ros.errors import AssetError, ParameterError

FORMAT = "zebra_sim_ros/detector"
VERSION = 1
SHIPPED = Path(__file__).resolve().parent / "weights" / "zebra_yolo_n.pt"
# oneDNN's instruction-set caps (ONEDNN_MAX_CPU_ISA) as its dnnl_cpu_isa_t bit masks (oneDNN 3.x); AVX512_CORE_BF16's
# bits are the ones native bfloat16 convolutions need. A name not listed (newer ones, AVX10_2 and on) is no cap here.
_ONEDNN_ISA = {"SSE41": 0x1, "AVX": 0x3, "AVX2": 0x7, "AVX2_VNNI": 0xF, "AVX2_VNNI_2": 0x1F, "AVX512_CORE": 0x27,
               "AVX512_CORE_VNNI": 0x67, "AVX512_CORE_BF16": 0xE7, "AVX10_1_512": 0x1EF, "AVX512_CORE_FP16": 0x1EF,
               "AVX10_1_512_AMX": 0xFEF, "AVX512_CORE_AMX": 0xFEF, "AVX10_1_512_AMX_FP16": 0x1FEF,
               "AVX512_CORE_AMX_FP16": 0x1FEF}
_BF16_BITS = _ONEDNN_ISA["AVX512_CORE_BF16"]


def onednn_allows_bf16() -> bool:
    """False where ONEDNN_MAX_CPU_ISA (or its older name DNNL_MAX_CPU_ISA) caps oneDNN below AVX512_CORE_BF16: its
    convolutions then emulate bfloat16 even on a CPU that has the instructions. Unset, DEFAULT (oneDNN 3) or ALL
    (oneDNN 2): True. Case is ignored, as oneDNN ignores it."""
    cap = (os.environ.get("ONEDNN_MAX_CPU_ISA") or os.environ.get("DNNL_MAX_CPU_ISA") or "").upper()
    if cap in ("", "ALL", "DEFAULT"):
        return True
    return _ONEDNN_ISA.get(cap, _BF16_BITS) & _BF16_BITS == _BF16_BITS  # a name not listed: not a cap


def amp_dtype(mode: str, device: torch.device, name: str = "--amp") -> torch.dtype | None:
    """The autocast dtype of the forward pass, or None for float32.

    auto: float16 on CUDA (with a gradient scaler); on a CPU with bfloat16 instructions (AVX512-BF16 or AMX),
    bfloat16, which trained 2x faster than float32 on a 2-core EPYC with AVX512-BF16; elsewhere float32 (emulated
    bfloat16 measured 8.5x slower: BENCHMARKS.md), as where ONEDNN_MAX_CPU_ISA keeps oneDNN from those
    instructions (:func:`onednn_allows_bf16`). The loss is always computed in float32, and a served model's
    boxes too (:attr:`~zebra_sim_ros.detection.model.Detector.serve_dtype`). ``name``: the option or parameter
    that set ``mode``, for the error.
    """
    if mode not in AMP_MODES:
        raise ParameterError(name, mode, " or ".join(AMP_MODES))
    if mode == "off":
        return None
    if mode == "auto":
        if device.type == "cuda":
            return torch.float16
        has_bf16 = torch.cpu._is_avx512_bf16_supported() or torch.cpu._is_amx_tile_supported()
        fast_bf16 = has_bf16 and onednn_allows_bf16()
        return torch.bfloat16 if device.type == "cpu" and fast_bf16 else None
    if mode == "fp16" and device.type != "cuda":
        raise ParameterError(name, mode, "bf16 or off on a CPU (float16 autocast wants CUDA)")
    return torch.float16 if mode == "fp16" else torch.bfloat16


def save_checkpoint(path: str | Path, model: Detector, **extra: Any) -> None:
    """Write ``model`` (its state dict, as is) with its config and ``extra`` fields."""
    ckpt = {"format": FORMAT, "version": VERSION, "config": model.cfg.to_dict(), "model": model.state_dict(), **extra}
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.with_name(p.name + ".tmp")
    torch.save(ckpt, tmp)
    tmp.replace(p)


def file_sha256(path: str | Path) -> str:
    """The sha256 (hex) of a file's bytes: how records and benchmark tables name the weights they used."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def load_weights(module: torch.nn.Module, state: dict[str, torch.Tensor], misfit: str) -> None:
    """``state`` (any float dtype) into ``module``; weights that do not fit it are an :class:`AssetError` that
    starts with ``misfit`` and names the first problem of those torch lists, and counts them."""
    try:
        module.load_state_dict({k: v.float() for k, v in state.items()})
    except RuntimeError as exc:
        lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip().startswith(("size mismatch", "Missing",
                                                                                      "Unexpected"))]
        raise AssetError(f"{misfit}: {len(lines)} problem(s), first: {lines[0] if lines else exc}") from exc


def read_checkpoint(path: str | Path, name: str = "weights", fmt: str = FORMAT,
                    version: int | tuple[int, ...] = VERSION) -> dict[str, Any]:
    """The checkpoint dict of format ``fmt`` and ``version`` (or one of several); raises :class:`ParameterError`
    (naming the parameter ``name``) for a missing file, :class:`AssetError` for a bad one."""
    p = Path(path)
    if not p.is_file():
        raise ParameterError(name, str(p), "an existing checkpoint file")
    try:
        ckpt = torch.load(p, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many types for truncated or foreign files
        raise AssetError(f"{name} {p} cannot be read as a checkpoint ({type(exc).__name__}: {exc})") from exc
    if not isinstance(ckpt, dict) or ckpt.get("format") != fmt:
        raise AssetError(f"{name} {p}: not a {fmt} checkpoint")
    versions = version if isinstance(version, tuple) else (version,)
    if ckpt.get("version") not in versions:
        readable = " or ".join(map(str, versions))
        raise AssetError(f"{name} {p}: checkpoint version {ckpt.get('version')}; this build reads {readable}")
    return ckpt


def load_model(path: str | Path | None = None, device: str | torch.device = "cpu",
               fuse: bool = True, amp: str = "off", amp_name: str = "--amp") -> tuple[Detector, dict[str, Any]]:
    """Rebuild the model of a checkpoint (default: the shipped weights) in eval mode, float32, on ``device``, in
    the serving layout; batch norms are folded into the convolutions unless ``fuse`` is False. ``amp`` (a mode of
    :func:`amp_dtype`; ``amp_name`` names its option in errors) sets the dtype its features are served in."""
    serve_dtype = amp_dtype(amp, torch.device(device), amp_name)
    ckpt = read_checkpoint(path or SHIPPED)
    model = build_model(ckpt["config"])
    load_weights(model, ckpt["model"], f"weights {path or SHIPPED} do not fit their own config {ckpt['config']}")
    model = model.to(device).eval()
    if fuse:
        model = model.fuse()
    model.serve_dtype = serve_dtype
    return serving_layout(model), ckpt


def serving_layout(model: Detector) -> Detector:
    """Channels-last weights (NHWC): oneDNN's fast convolution layout on CPUs and tensor-core friendly on GPUs;
    2.2x faster than NCHW for the nano model on our 2-core CPU. :func:`~zebra_sim_ros.detection.predict.detect`
    feeds it channels-last input to match."""
    return model.to(memory_format=torch.channels_last)  # type: ignore[call-overload]


def check_imgsz(name: str, value: int | None, native: bool = False) -> None:
    """Raise :class:`ParameterError` unless ``value`` is None (the checkpoint's), a multiple of 32 in 64..4096,
    or, with ``native``, -1 (each frame's own size)."""
    if value is not None and not imgsz_ok(value, native):
        raise ParameterError(name, value, ("-1 or " if native else "") + "a multiple of 32 in 64..4096")


def check_scale(name: str, value: float) -> None:
    """Raise :class:`ParameterError` unless ``value`` is 0 (off: the checkpoint's rule) or in 0.25..4."""
    lo, hi = SCALE_RANGE
    if not (value == 0 or lo <= value <= hi):  # 0 is the exact 'off' a user types, not a computed float
        raise ParameterError(name, value, f"0 (off: the checkpoint's rule) or {lo:g}..{hi:g} (times the frame's "
                             "long side)")


def checkpoint_config(path: str | Path | None = None) -> ModelConfig:
    """The model config of a checkpoint (default: the shipped weights), without building the model."""
    return ModelConfig.from_dict(read_checkpoint(path or SHIPPED)["config"])


def select_device(name: str = "auto") -> torch.device:
    """``auto`` (CUDA when available), ``cpu``, ``cuda`` or ``cuda:N``."""
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name.startswith("cuda") and not torch.cuda.is_available():
        raise ParameterError("device", name, "cpu or auto (no CUDA device is available)")
    if name != "cpu" and not name.startswith("cuda"):
        raise ParameterError("device", name, "auto, cpu, cuda or cuda:N")
    return torch.device(name)
