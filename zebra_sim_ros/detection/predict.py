"""Inference: letterbox, forward, NMS, boxes back in the original image's pixels."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import torch
from numpy.typing import NDArray

from zebra_sim_ros.detection.boxes import postprocess
from zebra_sim_ros.detection.config import NATIVE, scaled_size
from zebra_sim_ros.detection.data import letterbox, rect_shape
from zebra_sim_ros.detection.metrics import MAX_DETECTIONS
from zebra_sim_ros.detection.model import Detector, ModelConfig
from zebra_sim_ros.messages import Detection, Detections, Stamp

if TYPE_CHECKING:
    from zebra_sim_ros.detection.verify import Verifier


def inference_size(cfg: ModelConfig, long_side: int, imgsz: int | None = None, scale: float = 0.0) -> int:
    """The one rule for the inference size of a frame (or a batch) whose long side is ``long_side`` px, shared
    by ``val``, ``bag eval``, the detector node and ``up``:

    - ``scale`` > 0: ``long_side * scale``, rounded up to a multiple of 32 (within 64..4096);
    - else ``imgsz`` > 0: that size, whatever the frame; :data:`NATIVE` (-1) is scale 1;
    - else (the default) the checkpoint's own rule, :meth:`ModelConfig.serve_size`: the scale it serves at
      (``config.imgsz / config.frame``, its serving size over its training frames' long side) times the frame's
      side. Far zebras are a few pixels tall, so a frame twice the training size wants twice the input size.
    """
    if scale:
        return scaled_size(long_side, scale)
    if imgsz == NATIVE:
        return scaled_size(long_side, 1.0)
    return imgsz or cfg.serve_size(long_side)


def describe_size(cfg: ModelConfig, imgsz: int | None = None, scale: float = 0.0) -> str:
    """How :func:`inference_size` sizes frames under these settings, for logs and summaries."""
    if scale or imgsz == NATIVE:
        return f"{scale or 1.0:g} x each frame's long side (rounded up to a multiple of 32)"
    if imgsz:
        return f"{imgsz} px for every frame"
    if not cfg.frame:
        return f"{cfg.imgsz} px for every frame (the checkpoint's; its training frame size is not recorded)"
    return (f"the checkpoint's scale, {cfg.imgsz / cfg.frame:.3g} x each frame's long side ({cfg.imgsz} px for "
            f"its {cfg.frame} px training frames)")


def preprocess(images: Sequence[NDArray[np.uint8]], imgsz: int,
               rect: bool = True) -> tuple[torch.Tensor, list[tuple[float, int, int]]]:
    """RGB uint8 images to a letterboxed batch and each image's (scale, left, top). The long side becomes
    ``imgsz``; ``rect`` pads only to the next multiple of the largest stride (32), so a 16:9 frame costs about
    0.56 of a square one; otherwise the batch is (B, 3, imgsz, imgsz)."""
    shape = None
    if rect:
        sizes = [rect_shape(i.shape[0], i.shape[1], imgsz) for i in images]
        shape = (max(h for h, _ in sizes), max(w for _, w in sizes))
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
           iou: float = 0.7, max_det: int = MAX_DETECTIONS, rect: bool = True,
           scale: float = 0.0, verifier: Verifier | None = None) -> list[NDArray[np.float32]]:
    """Per image (n, 6) [x0, y0, x1, y1, score, class] in its own pixels (pixel-edge coordinates). The batch's
    long side is resized to :func:`inference_size` of the batch's longest side under ``imgsz`` and ``scale``
    (default: the checkpoint's rule) and padded as :func:`preprocess` says. With a ``verifier``, the zebra boxes
    it looks at score conf x p(zebra) and those now under ``conf`` are dropped
    (:func:`zebra_sim_ros.detection.verify.rescore`)."""
    if not images:
        return []
    size = inference_size(model.cfg, max(max(i.shape[:2]) for i in images), imgsz, scale)
    dev = next(model.parameters()).device
    x, meta = preprocess(images, size, rect)
    pred = model(x.to(dev).contiguous(memory_format=torch.channels_last))
    out = []
    for det, img, (r, left, top) in zip(postprocess(pred, conf, iou, max_det), images, meta, strict=True):
        out.append(unletterbox(det, r, left, top, img.shape[1], img.shape[0]).cpu().numpy().astype(np.float32))
    if verifier is not None:
        from zebra_sim_ros.detection.model import ZEBRA
        from zebra_sim_ros.detection.verify import rescore

        out = [rescore(verifier, img, d, conf, ZEBRA) for img, d in zip(images, out, strict=True)]
    return out


def detections_message(stamp: Stamp, frame_id: str, width: int, height: int, dets: np.ndarray,
                       names: Sequence[str]) -> Detections:
    """The typed message of ``detect``'s (n, 6) rows for one image (boxes to 0.01 px, scores to 1e-4)."""
    return Detections(stamp, frame_id, width, height, tuple(
        Detection((round(float(d[0]), 2), round(float(d[1]), 2), round(float(d[2]), 2), round(float(d[3]), 2)),
                  round(float(d[4]), 4), int(d[5]), names[int(d[5])]) for d in dets))
