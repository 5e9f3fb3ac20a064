"""Inference: letterbox, forward, NMS, boxes back in the original image's pixels."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from numpy.typing import NDArray

from zebra_sim_ros.detection.boxes import postprocess
from zebra_sim_ros.detection.config import NATIVE, STRIDE, scaled_size
from zebra_sim_ros.detection.data import letterbox, letterbox_size
from zebra_sim_ros.detection.model import Detector


def native_size(images: Sequence[NDArray[np.uint8]], scale: float = 1.0) -> int:
    """The images' longest side times ``scale``, rounded up to a multiple of 32, within 64..4096: far zebras are
    a few pixels tall, so detecting at (or above) the frames' own resolution keeps them (a 1280x720 frame at
    416 px loses most)."""
    return scaled_size(max(max(i.shape[:2]) for i in images), scale)


def preprocess(images: Sequence[NDArray[np.uint8]], imgsz: int,
               rect: bool = True) -> tuple[torch.Tensor, list[tuple[float, int, int]]]:
    """RGB uint8 images to a letterboxed batch and each image's (scale, left, top). The long side becomes
    ``imgsz``; ``rect`` pads only to the next multiple of the largest stride (32), so a 16:9 frame costs about
    0.56 of a square one; otherwise the batch is (B, 3, imgsz, imgsz)."""
    shape = None
    if rect:
        sizes = [letterbox_size(i.shape[0], i.shape[1], imgsz) for i in images]
        shape = (-(-max(h for h, _ in sizes) // STRIDE) * STRIDE, -(-max(w for _, w in sizes) // STRIDE) * STRIDE)
    batch, meta = [], []
    for img in images:
        lb, r, (left, top) = letterbox(img, imgsz, shape)
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
           iou: float = 0.7, max_det: int = 300, rect: bool = True, scale: float = 0.0) -> list[NDArray[np.float32]]:
    """Per image (n, 6) [x0, y0, x1, y1, score, class] in its own pixels (pixel-edge coordinates); the long side
    is resized to ``imgsz`` (default: the checkpoint's; :data:`NATIVE`: :func:`native_size`) or, if ``scale`` is
    set, to :func:`native_size` with that scale, padded as :func:`preprocess` says."""
    if not images:
        return []
    scale = scale or (1.0 if imgsz == NATIVE else 0.0)  # NATIVE is scale 1
    size = native_size(images, scale) if scale else (imgsz or model.cfg.imgsz)
    dev = next(model.parameters()).device
    x, meta = preprocess(images, size, rect)
    pred = model(x.to(dev).contiguous(memory_format=torch.channels_last))
    out = []
    for det, img, (r, left, top) in zip(postprocess(pred, conf, iou, max_det), images, meta, strict=True):
        out.append(unletterbox(det, r, left, top, img.shape[1], img.shape[0]).cpu().numpy().astype(np.float32))
    return out
