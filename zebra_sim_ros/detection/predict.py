"""Inference: letterbox, forward, NMS, boxes back in the original image's pixels."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from numpy.typing import NDArray

from zebra_sim_ros.detection.boxes import postprocess
from zebra_sim_ros.detection.data import letterbox
from zebra_sim_ros.detection.model import Detector


def preprocess(images: Sequence[NDArray[np.uint8]], imgsz: int) -> tuple[torch.Tensor, list[tuple[float, int, int]]]:
    """RGB uint8 images to a letterboxed batch (B, 3, imgsz, imgsz) and each image's (scale, left, top)."""
    batch, meta = [], []
    for img in images:
        lb, r, (left, top) = letterbox(img, imgsz)
        batch.append(torch.from_numpy(np.ascontiguousarray(lb.transpose(2, 0, 1))))
        meta.append((r, left, top))
    return torch.stack(batch).float() / 255.0, meta


def unletterbox(det: torch.Tensor, scale: float, left: int, top: int, width: int, height: int) -> torch.Tensor:
    """Boxes of letterboxed input back to the original image, clipped to it."""
    out = det.clone()
    out[:, [0, 2]] = ((det[:, [0, 2]] - left) / scale).clamp(0, width)
    out[:, [1, 3]] = ((det[:, [1, 3]] - top) / scale).clamp(0, height)
    return out


@torch.no_grad()
def detect(model: Detector, images: Sequence[NDArray[np.uint8]], imgsz: int | None = None, conf: float = 0.25,
           iou: float = 0.7, max_det: int = 300) -> list[NDArray[np.float32]]:
    """Per image (n, 6) [x0, y0, x1, y1, score, class] in its own pixels (pixel-edge coordinates)."""
    if not images:
        return []
    size = imgsz or model.cfg.imgsz
    dev = next(model.parameters()).device
    x, meta = preprocess(images, size)
    pred = model(x.to(dev))
    out = []
    for det, img, (r, left, top) in zip(postprocess(pred, conf, iou, max_det), images, meta, strict=True):
        out.append(unletterbox(det, r, left, top, img.shape[1], img.shape[0]).cpu().numpy().astype(np.float32))
    return out
