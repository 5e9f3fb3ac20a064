"""Boxes: IoU (plain and complete), the distance codec and batched non-maximum suppression.

Format: ``xyxy`` = (x_min, y_min, x_max, y_max) in pixels; a box is encoded relative to an anchor point as
distances (left, top, right, bottom) to its sides, in units of the stride.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from torch import Tensor


def encode_ltrb(anchors: Tensor, boxes: Tensor, reg_max: int) -> Tensor:
    """Distances (..., 4) from anchor points (..., 2) to the sides of xyxy boxes, clamped to [0, reg_max - 0.01]."""
    lt = anchors - boxes[..., :2]
    rb = boxes[..., 2:] - anchors
    return torch.cat([lt, rb], dim=-1).clamp(0, reg_max - 0.01)


def decode_ltrb(anchors: Tensor, dist: Tensor) -> Tensor:
    """xyxy boxes from anchor points (..., 2) and distances (..., 4) (inverse of :func:`encode_ltrb`)."""
    return torch.cat([anchors - dist[..., :2], anchors + dist[..., 2:]], dim=-1)


def box_iou(a: Tensor, b: Tensor) -> Tensor:
    """Pairwise IoU (N, M) of xyxy boxes a (N, 4) and b (M, 4)."""
    area_a = (a[:, 2] - a[:, 0]).clamp(min=0) * (a[:, 3] - a[:, 1]).clamp(min=0)
    area_b = (b[:, 2] - b[:, 0]).clamp(min=0) * (b[:, 3] - b[:, 1]).clamp(min=0)
    lt = torch.max(a[:, None, :2], b[None, :, :2])
    rb = torch.min(a[:, None, 2:], b[None, :, 2:])
    inter = (rb - lt).clamp(min=0).prod(dim=2)
    return inter / (area_a[:, None] + area_b[None, :] - inter + 1e-9)


def ciou(a: Tensor, b: Tensor, eps: float = 1e-7) -> Tensor:
    """Complete IoU of matching xyxy boxes (..., 4): IoU minus centre-distance and aspect penalties."""
    w1, h1 = a[..., 2] - a[..., 0], (a[..., 3] - a[..., 1]).clamp(min=eps)
    w2, h2 = b[..., 2] - b[..., 0], (b[..., 3] - b[..., 1]).clamp(min=eps)
    inter = ((torch.min(a[..., 2], b[..., 2]) - torch.max(a[..., 0], b[..., 0])).clamp(min=0)
             * (torch.min(a[..., 3], b[..., 3]) - torch.max(a[..., 1], b[..., 1])).clamp(min=0))
    union = w1 * h1 + w2 * h2 - inter + eps
    iou = inter / union
    cw = torch.max(a[..., 2], b[..., 2]) - torch.min(a[..., 0], b[..., 0])
    ch = torch.max(a[..., 3], b[..., 3]) - torch.min(a[..., 1], b[..., 1])
    c2 = cw**2 + ch**2 + eps
    rho2 = ((b[..., 0] + b[..., 2] - a[..., 0] - a[..., 2]) ** 2
            + (b[..., 1] + b[..., 3] - a[..., 1] - a[..., 3]) ** 2) / 4
    v = (4 / math.pi**2) * (torch.atan(w2 / h2) - torch.atan(w1 / h1)) ** 2
    with torch.no_grad():
        alpha = v / (v - iou + (1 + eps))
    return iou - (rho2 / c2 + v * alpha)


def nms(boxes: Tensor, scores: Tensor, iou_threshold: float) -> Tensor:
    """Indices of the boxes kept by greedy non-maximum suppression, highest score first."""
    if boxes.numel() == 0:
        return torch.zeros(0, dtype=torch.long, device=boxes.device)
    order = scores.argsort(descending=True)
    boxes = boxes[order]
    # Greedy in score order; the IoU matrix is computed once, the loop only reads it (in numpy: a torch
    # operation per box costs ~50 us of overhead, numpy's ~2 us).
    suppress = (box_iou(boxes, boxes) > iou_threshold).triu(diagonal=1).cpu().numpy()
    keep = np.ones(len(boxes), dtype=bool)
    for i in range(len(boxes)):
        if keep[i]:
            keep &= ~suppress[i]
    return order[torch.from_numpy(keep).to(order.device)]


def batched_nms(boxes: Tensor, scores: Tensor, groups: Tensor, iou_threshold: float) -> Tensor:
    """NMS within groups (images and/or classes) at once, by offsetting each group's boxes apart."""
    if boxes.numel() == 0:
        return torch.zeros(0, dtype=torch.long, device=boxes.device)
    offset = groups.to(boxes.dtype)[:, None] * (boxes.max() + 1)
    return nms(boxes + offset, scores, iou_threshold)


NMS_CANDIDATES_PER_DETECTION = 10
"""Candidates NMS considers per detection it may keep: :func:`postprocess` caps them at this times ``max_det``."""


def postprocess(pred: Tensor, conf: float = 0.25, iou: float = 0.7, max_det: int = 300,
                max_nms: int | None = None, agnostic: bool = True) -> list[Tensor]:
    """Per image (n, 6) [x0, y0, x1, y1, score, class] from decoded predictions (B, N, 4 + nc).

    Image by image: each point's best class and its score, candidates above ``conf``, at most ``max_nms`` of them by
    score (so a barely trained model's flood of low scores cannot make the IoU matrix huge; default
    :data:`NMS_CANDIDATES_PER_DETECTION` times ``max_det``: a frame of 250 zebras, each found by several anchor
    points, keeps them all), NMS, at most ``max_det`` kept. NMS is class-agnostic by default: an animal is of one
    species, so where a model with an ``other_animal`` class finds a buffalo, its stronger "other animal" box
    suppresses a weaker "zebra" box on the same animal (with one class, as the same thing); ``agnostic=False``
    suppresses within each class only.
    """
    if max_nms is None:
        max_nms = NMS_CANDIDATES_PER_DETECTION * max_det
    out = []
    for p in pred:
        scores, cls = p[:, 4:].max(dim=-1)
        keep = scores > conf
        boxes, s, c = p[keep, :4], scores[keep], cls[keep]
        if len(s) > max_nms:
            top = s.topk(max_nms).indices
            boxes, s, c = boxes[top], s[top], c[top]
        k = (nms(boxes, s, iou) if agnostic else batched_nms(boxes, s, c, iou))[:max_det]
        out.append(torch.cat([boxes[k], s[k, None], c[k, None].to(boxes.dtype)], dim=1))
    return out
