"""Deployment exports: ONNX (optional dependency: ``pip install onnx onnxruntime``) and serving checkpoints.

The exported graph is the whole model up to decoded boxes and class probabilities: input ``images``
(B, 3, S, S) float RGB in [0, 1], output ``predictions`` (B, N, 4 + nc) xyxy pixels of the letterboxed input.
NMS stays outside the graph (:func:`zebra_sim_ros.detection.boxes.postprocess`, or any runtime's own).

A serving checkpoint (``--format pt``) is what the package ships: the EMA weights in float16, no optimizer state,
``config.imgsz`` set to the inference size for frames of its training size (``config.frame``, their long side),
which every loader scales to the frames it is given (``zebra-sim val``, the detector node, ``bag eval``, ``up``:
:meth:`~zebra_sim_ros.detection.model.ModelConfig.serve_size`); the training arguments, epoch and metrics of the
source are kept, so ``train_args.imgsz`` still says the size it was trained at.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import torch
from torch import Tensor

from zebra_sim_ros.detection.checkpoint import SHIPPED, load_model, read_checkpoint, save_checkpoint
from zebra_sim_ros.detection.data import generate_settings
from zebra_sim_ros.detection.model import WIDENS, Widening, build_model, p2_tensors, state_digest, widen_state
from zebra_sim_ros.errors import DependencyError, ParameterError


def export_onnx(weights: str | Path | None, out: str | Path, imgsz: int | None = None, opset: int = 17) -> Path:
    """Write the ONNX model of a checkpoint (default: the shipped weights); returns the path."""
    try:
        import onnx  # noqa: F401
    except ImportError as exc:
        raise DependencyError("ONNX export needs the optional packages: pip install onnx onnxruntime") from exc
    model, _ = load_model(weights, "cpu")
    size = imgsz or model.cfg.imgsz
    path = Path(out)
    path.parent.mkdir(parents=True, exist_ok=True)
    x = torch.zeros(1, 3, size, size)
    torch.onnx.export(model, (x,), str(path), input_names=["images"], output_names=["predictions"],
                      dynamic_axes={"images": {0: "batch"}, "predictions": {0: "batch"}}, opset_version=opset,
                      dynamo=False)
    return path


def blend_weights(weights: dict[str, Tensor], base: dict[str, Tensor], alpha: float) -> dict[str, Tensor]:
    """``(1 - alpha) * base + alpha * weights``, tensor by tensor (float32), for two state dicts of the same
    architecture: a weight-space ensemble of a model and the model it was fine-tuned from (WiSE-FT, Wortsman et
    al. 2022), which keeps much of what the fine-tuning gained and of what it forgot. Integer tensors (batch
    norms' counters) are taken from ``weights``, and so is a stride-4 level (``train --p2``) that ``base`` lacks:
    a P2 run started from a three-level checkpoint blends with it on every other tensor."""
    if not 0.0 <= alpha <= 1.0:
        raise ParameterError("--blend", alpha, "0..1 (the fine-tuned weights' share)")
    shared = set(weights) - (set() if p2_tensors(base) else set(p2_tensors(weights)))
    if shared != set(base) or any(weights[k].shape != base[k].shape for k in shared):
        bad = sorted(shared ^ set(base)) or sorted(k for k in shared if weights[k].shape != base[k].shape)
        raise ParameterError("--blend-base", f"{len(bad)} tensor(s) of another name or shape, first {bad[0]}",
                             "weights of the same architecture and classes")
    return {k: ((1.0 - alpha) * base[k].float() + alpha * v.float()) if v.dtype.is_floating_point and k in shared
            else v for k, v in weights.items()}


def export_checkpoint(weights: str | Path | None, out: str | Path, imgsz: int | None = None,
                      frame: int | None = None, recipe: str | None = None, blend_base: str | Path | None = None,
                      blend: float = 1.0) -> Path:
    """Write a serving checkpoint of ``weights`` (default: the shipped ones) that serves frames whose long side
    is ``frame`` px (default: the training frames' size it records) at ``imgsz`` (default: unchanged), and
    other frames at the same scale; returns the path. ``recipe``: text kept verbatim in the checkpoint (how the
    weights were made: the commands, seeds and times), else the source's own. ``blend_base``: a checkpoint
    ``weights`` was fine-tuned from; the output's tensors are then :func:`blend_weights` of the two with
    ``blend`` the fine-tuned share (the rest of the record is ``weights``'). A base of the narrower size that
    ``train --init`` widened (``n`` under an ``s`` run) is widened again with the seed ``weights`` record
    (``widened``, carried on through later runs from them), so it blends with the very weights the widening made."""
    source = str(weights or SHIPPED)
    src = read_checkpoint(source)
    cfg = dict(src["config"])
    if imgsz:
        cfg["imgsz"] = imgsz
    if frame:
        cfg["frame"] = frame
    model = build_model(cfg)
    state = {k: v.float() for k, v in src["model"].items()}
    blended = None
    if blend_base is not None:
        base = read_checkpoint(blend_base, "--blend-base")
        base_state, record = base["model"], None
        if WIDENS.get(base["config"].get("size")) == cfg.get("size"):  # the size it was widened from (train --init)
            record = Widening.from_dict(src.get("widened"), "--weights", source)
            if record is None:
                raise ParameterError("--weights", source, "weights that record the "
                                     f"{base['config'].get('size')} checkpoint they were widened from (train --init), "
                                     f"to blend with one; or a --blend-base of size {cfg.get('size')!r}")
            digest = state_digest(base_state)
            if record.digest not in (None, digest):  # records written before the digest was kept: not checked
                raise ParameterError("--blend-base", str(blend_base), f"the weights the run was widened from "
                                     f"({record.source}, digest {record.digest}; these are {digest})")
            base_state = widen_state(base_state, base["config"], str(cfg.get("size")), record.seed, "--blend-base")
        state = blend_weights(state, base_state, blend)
        blended = {"base": str(blend_base), "base_config": base["config"], "alpha": blend}
        if record is not None:
            blended["widened_with_seed"] = record.seed
    model.load_state_dict(state)
    extra: dict[str, Any] = {k: src[k] for k in ("epoch", "metrics", "train_args", "best_fitness", "data_generate",
                                                 "recipe", "widened") if k in src}
    if "data_generate" not in extra and "data" in extra.get("train_args", {}):  # checkpoints before it was kept
        extra["data_generate"] = generate_settings(extra["train_args"]["data"])
    if recipe:
        extra["recipe"] = recipe
    if blended:
        extra["blended"] = blended
    save_checkpoint(out, model.half(), **extra, exported={"from_config_imgsz": int(src["config"]["imgsz"]),
                                                          "imgsz": int(cfg["imgsz"]),
                                                          "frame": int(cfg.get("frame", 0)),
                                                          "previous": src.get("exported")})
    return Path(out)
