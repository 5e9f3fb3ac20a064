"""Training loss: task-aligned assignment, then BCE classification, CIoU box and distribution focal losses.

The assigner (TOOD, Feng et al. 2021) scores every candidate anchor point of a ground-truth box by
``score^alpha * IoU^beta`` of its prediction, keeps the top k per box, resolves points claimed by several
boxes by IoU, and uses the normalised alignment as the soft classification target. Candidates are the
points inside the box and, so that zebras smaller than a grid cell still get points, those within one stride
of the box centre (as YOLOX's centre sampling); most zebras seen from far away are under 8 px wide.

Don't-care boxes (targets of class -1: zebras seen but dropped by the label filters) are never assigned; the
points they would have as candidates, unless assigned to a real box, are left out of the classification loss,
so a model is not taught that a zebra of 24 visible pixels is background while one of 25 is a zebra.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F  # noqa: N812
from torch import Tensor

from zebra_sim_ros.detection.boxes import box_iou, ciou, decode_ltrb, encode_ltrb
from zebra_sim_ros.detection.data import DONT_CARE
from zebra_sim_ros.detection.model import Detector, make_anchors


def candidates(anchors: Tensor, strides: Tensor, boxes: Tensor) -> Tensor:
    """(M, N): anchor points (N, 2) px inside each xyxy box (M, 4), or within one of their strides (N,) of its
    centre in both axes."""
    inside = ((anchors[None, :, 0] > boxes[:, None, 0]) & (anchors[None, :, 0] < boxes[:, None, 2])
              & (anchors[None, :, 1] > boxes[:, None, 1]) & (anchors[None, :, 1] < boxes[:, None, 3]))
    centre = (boxes[:, None, :2] + boxes[:, None, 2:]) / 2
    return inside | ((anchors[None] - centre).abs() <= strides[None, :, None]).all(-1)


class TaskAlignedAssigner:
    """Assign ground truth to anchor points (one image at a time, vectorised over boxes and points)."""

    def __init__(self, topk: int = 10, alpha: float = 0.5, beta: float = 6.0) -> None:
        self.topk, self.alpha, self.beta = topk, alpha, beta

    @torch.no_grad()
    def __call__(self, scores: Tensor, boxes: Tensor, anchors: Tensor, strides: Tensor, gt_cls: Tensor,
                 gt_boxes: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        """For one image: scores (N, nc) probabilities, boxes (N, 4) predicted xyxy px, anchors (N, 2) px and
        their strides (N,), gt_cls (M,), gt_boxes (M, 4). Returns target boxes (N, 4), target scores (N, nc),
        foreground (N,)."""
        n, nc = scores.shape
        m = len(gt_boxes)
        if m == 0:
            return torch.zeros_like(boxes), torch.zeros_like(scores), torch.zeros(n, dtype=torch.bool,
                                                                                  device=boxes.device)
        inside = candidates(anchors, strides, gt_boxes)
        iou = box_iou(gt_boxes, boxes).clamp(min=0) * inside  # (M, N)
        s = scores[:, gt_cls].T  # (M, N)
        align = s.pow(self.alpha) * iou.pow(self.beta) * inside
        k = min(self.topk, n)
        top = align.topk(k, dim=1).indices  # (M, k)
        cand = torch.zeros_like(align, dtype=torch.bool)
        cand.scatter_(1, top, True)
        cand &= inside & (align > 0)
        # A point claimed by several boxes goes to the one it overlaps most.
        multi = cand.sum(0) > 1
        if multi.any():
            best = iou.argmax(0)
            one_hot = F.one_hot(best, m).T.bool()
            cand = torch.where(multi[None], one_hot & inside, cand)
        fg = cand.any(0)
        gt_idx = cand.float().argmax(0)  # (N,)
        target_boxes = gt_boxes[gt_idx]
        # Soft targets: alignment normalised per box so its best point reaches that box's best IoU.
        align = align * cand
        max_align = align.amax(1, keepdim=True)
        max_iou = (iou * cand).amax(1, keepdim=True)
        # A tiny epsilon: early in training alignments are ~1e-12 (boxes barely overlap), and a 1e-9 epsilon (as
        # is common) would zero every target and stall learning on small objects.
        norm = (align * max_iou / (max_align + 1e-30)).amax(0)  # (N,)
        target_scores = torch.zeros_like(scores)
        target_scores[fg, gt_cls[gt_idx[fg]]] = norm[fg]
        return target_boxes, target_scores, fg


class DetectionLoss:
    """Loss of a :class:`Detector` on a batch; returns (total, components [box, cls, dfl] detached)."""

    def __init__(self, model: Detector, box: float = 7.5, cls: float = 0.5, dfl: float = 1.5) -> None:
        self.model = model
        self.gains = (box, cls, dfl)
        self.assigner = TaskAlignedAssigner()
        self.reg_max = model.cfg.reg_max
        self.nc = model.cfg.nc

    def __call__(self, feats: list[Tensor], targets: Tensor) -> tuple[Tensor, Tensor]:
        """``targets``: (T, 6) rows [image index, class, x0, y0, x1, y1] in input pixels; class
        :data:`~zebra_sim_ros.detection.data.DONT_CARE` marks a don't-care box."""
        r = self.reg_max
        b = feats[0].shape[0]
        x = torch.cat([f.view(b, f.shape[1], -1) for f in feats], 2).transpose(1, 2)  # (B, N, 4r + nc)
        pred_dist, pred_cls = x[..., : 4 * r], x[..., 4 * r:]
        anchors, strides = make_anchors(feats, self.model.strides)
        dist = self.model.dfl(pred_dist.transpose(1, 2)).transpose(1, 2)  # (B, N, 4) stride units
        pred_boxes = decode_ltrb(anchors[None], dist)  # stride units
        anchors_px = anchors * strides
        scores = pred_cls.detach().sigmoid()
        tb = torch.zeros_like(pred_boxes)
        ts = torch.zeros_like(pred_cls)
        fg = torch.zeros(pred_boxes.shape[:2], dtype=torch.bool, device=x.device)
        care = torch.ones_like(fg)  # points whose classification counts
        for i in range(b):
            t = targets[targets[:, 0] == i]
            real = t[:, 1] != DONT_CARE
            boxes_i, scores_i, fg_i = self.assigner(scores[i], (pred_boxes[i].detach() * strides), anchors_px,
                                                    strides[:, 0], t[real, 1].long(), t[real, 2:6])
            tb[i], ts[i], fg[i] = boxes_i / strides, scores_i, fg_i
            if not real.all():
                care[i] = fg_i | ~candidates(anchors_px, strides[:, 0], t[~real, 2:6]).any(0)
        ts_sum = ts.sum().clamp(min=1.0)
        bce = F.binary_cross_entropy_with_logits(pred_cls, ts, reduction="none")
        loss_cls = (bce * care[..., None]).sum() / ts_sum
        if fg.any():
            w = ts.sum(-1)[fg]
            loss_box = ((1.0 - ciou(pred_boxes[fg], tb[fg])) * w).sum() / ts_sum
            target_ltrb = encode_ltrb(anchors[None].expand_as(pred_boxes[..., :2])[fg], tb[fg], r)
            dfl = self._dfl(pred_dist[fg].view(-1, r), target_ltrb.view(-1)).view(-1, 4).mean(-1)
            loss_dfl = (dfl * w).sum() / ts_sum
        else:
            loss_box = loss_dfl = pred_dist.sum() * 0.0
        g = self.gains
        parts = torch.stack([loss_box * g[0], loss_cls * g[1], loss_dfl * g[2]])
        return parts.sum() * b, parts.detach()

    @staticmethod
    def _dfl(logits: Tensor, target: Tensor) -> Tensor:
        """Distribution focal loss: cross-entropy towards the two bins around a continuous target."""
        left = target.long()
        right = left + 1
        wl = right.float() - target
        wr = 1 - wl
        return (F.cross_entropy(logits, left, reduction="none") * wl
                + F.cross_entropy(logits, right.clamp(max=logits.shape[1] - 1), reduction="none") * wr)
