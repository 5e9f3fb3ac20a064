"""ONNX export (optional dependency: ``pip install onnx onnxruntime``).

The exported graph is the whole model up to decoded boxes and class probabilities: input ``images``
(B, 3, S, S) float RGB in [0, 1], output ``predictions`` (B, N, 4 + nc) xyxy pixels of the letterboxed input.
NMS stays outside the graph (:func:`zebra_sim_ros.detection.boxes.postprocess`, or any runtime's own).
"""

from __future__ import annotations

from pathlib import Path

import torch

from zebra_sim_ros.detection.checkpoint import load_model
from zebra_sim_ros.errors import DependencyError


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
