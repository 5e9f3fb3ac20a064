"""Detection metrics with COCO's definition: AP at IoU 0.50:0.05:0.95, 101-point interpolated.

Matching follows pycocotools' COCOeval for boxes (area range "all", at most ``max_det`` detections per
image by score): in score order, each detection takes the unmatched ground truth it overlaps most at or above
the threshold. Precision is made monotone, sampled at 101 recall points and averaged. Precision and recall are
also given at the confidence that maximises F1 at IoU 0.5, as YOLO tools print them.

Don't-care regions (``ignores``) are COCO's crowd annotations: objects that are there but not labelled (here,
zebras below the labeller's visibility filters). A detection that matches no labelled box but covers an ignore
box (intersection over the detection's own area at or above the threshold) counts neither as a true nor as a
false positive; ignore boxes are never missed and may take any number of detections.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.errors import ParameterError

IOU_THRESHOLDS = np.linspace(0.5, 0.95, 10)
# Detections per image that count, by score (pycocotools' maxDets). COCO's 100 fits its photos (at most a few
# dozen objects) but not ours: a placement holds up to 250 zebras and a frame may show over 180 of them, so 100
# would cap recall below what the detector finds. 300 is also the detector's own default (``max_det``): a frame is
# scored on every detection the node publishes for it.
MAX_DETECTIONS = 300
RECALL_POINTS = np.linspace(0.0, 1.0, 101)


def _overlaps(a: NDArray[np.float64],
              b: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Intersection areas (N, M) of xyxy boxes, and the areas of ``a`` (N,) and ``b`` (M,)."""
    lt = np.maximum(a[:, None, :2], b[None, :, :2])
    rb = np.minimum(a[:, None, 2:], b[None, :, 2:])
    inter = np.clip(rb - lt, 0, None).prod(2)
    return inter, (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1]), (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])


def iou_matrix(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """IoU (N, M) of xyxy boxes."""
    if len(a) == 0 or len(b) == 0:
        return np.zeros((len(a), len(b)))
    inter, area_a, area_b = _overlaps(a, b)
    return np.asarray(inter / (area_a[:, None] + area_b[None, :] - inter + 1e-12))


@dataclass
class DetectionMetrics:
    """Results over a set: AP per IoU threshold and the summary numbers."""

    ap: NDArray[np.float64]  # (10,) AP at IoU 0.50, 0.55, ..., 0.95
    precision: float
    recall: float
    f1_confidence: float
    images: int
    instances: int
    pr_curve: tuple[NDArray[np.float64], NDArray[np.float64]] = field(
        default_factory=lambda: (np.zeros(0), np.zeros(0)))

    @property
    def map50(self) -> float:
        """AP at IoU 0.5."""
        return float(self.ap[0])

    @property
    def map50_95(self) -> float:
        """Mean AP over IoU 0.50:0.05:0.95."""
        return float(self.ap.mean())

    def to_dict(self) -> dict[str, float | int]:
        """Summary numbers."""
        return {"precision": round(self.precision, 4), "recall": round(self.recall, 4),
                "mAP50": round(self.map50, 4), "mAP50-95": round(self.map50_95, 4),
                "images": self.images, "instances": self.instances}


def coverage_matrix(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """(N, M): the share of each xyxy box of ``a`` that lies inside each box of ``b`` (COCO's IoU with a crowd
    box: intersection over the detection's area)."""
    if len(a) == 0 or len(b) == 0:
        return np.zeros((len(a), len(b)))
    inter, area_a, _ = _overlaps(a, b)
    return np.asarray(inter / (area_a[:, None] + 1e-12))


def _match_image(pred: NDArray[np.float64], gt: NDArray[np.float64], ign: NDArray[np.float64],
                 size_range: tuple[float, float] | None = None) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """COCO's greedy matching of one image's score-sorted detections at every IoU threshold: which are true
    positives, and which lie on a don't-care box instead (neither right nor wrong); both (thresholds, n).

    ``size_range`` (lo, hi) in px of sqrt(box area), COCO's area ranges: ground truth outside it is ignored (a
    detection may take it, and then counts for nothing, but only when no box in range is left), and so is an
    unmatched detection outside it."""
    t = len(IOU_THRESHOLDS)
    ious = iou_matrix(pred[:, :4], gt)
    cover = coverage_matrix(pred[:, :4], ign)
    max_cover = cover.max(1) if cover.shape[1] else np.zeros(len(pred))
    if size_range is None:
        gt_out = np.zeros(len(gt), dtype=bool)
        det_out = np.zeros(len(pred), dtype=bool)
    else:
        lo, hi = size_range
        gt_size = np.sqrt(np.clip((gt[:, 2] - gt[:, 0]) * (gt[:, 3] - gt[:, 1]), 0, None))
        det_size = np.sqrt(np.clip((pred[:, 2] - pred[:, 0]) * (pred[:, 3] - pred[:, 1]), 0, None))
        gt_out, det_out = (gt_size < lo) | (gt_size >= hi), (det_size < lo) | (det_size >= hi)
    gt_order = np.argsort(gt_out, kind="stable")  # boxes in range first, as pycocotools sorts ignored gt last
    tp = np.zeros((t, len(pred)), dtype=bool)
    ig = np.zeros((t, len(pred)), dtype=bool)
    # Each detection walks only its candidates: the boxes, in matching order, at the lowest threshold or above. A
    # box below a threshold is below best_iou (which starts at it) and was always skipped, so for finite IoUs the
    # picks are the same as walking every box, at a fraction of the cost on crowded frames. A NaN IoU (a box with a
    # non-finite coordinate) is no candidate: such a box never matches.
    ious_o = ious[:, gt_order]
    low = min(min(IOU_THRESHOLDS), 1 - 1e-10)
    cands = [list(zip(gt_order[row >= low].tolist(), row[row >= low].tolist(), strict=True)) for row in ious_o]
    out = gt_out.tolist()
    for ti, thr in enumerate(IOU_THRESHOLDS):
        taken = [False] * len(gt)
        limit = min(thr, 1 - 1e-10)
        for d in range(len(pred)):
            best, best_iou = -1, limit
            for g, v in cands[d]:
                if taken[g] or v < best_iou:
                    continue
                if best >= 0 and not out[best] and out[g]:
                    break  # a box in range is matched: ignored ones come after and never replace it
                best, best_iou = g, v
            if best >= 0:
                taken[best] = True
                if gt_out[best]:
                    ig[ti, d] = True
                else:
                    tp[ti, d] = True
            elif max_cover[d] >= limit or det_out[d]:  # on a don't-care zebra, or out of range: not counted
                ig[ti, d] = True
    return tp, ig


class MatchedImage(NamedTuple):
    """One image's detections after COCO's matching (:func:`match_images`): what AP is accumulated from."""

    scores: NDArray[np.float64]  # (n,) its detections' scores, highest first, at most ``max_det``
    tp: NDArray[np.bool_]  # (thresholds, n) true positives at each IoU threshold
    ignored: NDArray[np.bool_]  # (thresholds, n) on a don't-care box or out of range: neither right nor wrong
    n_gt: int  # ground-truth boxes that count


def match_images(preds: list[NDArray[np.float64]], gts: list[NDArray[np.float64]],
                 max_det: int = MAX_DETECTIONS, ignores: list[NDArray[np.float64]] | None = None,
                 size_range: tuple[float, float] | None = None) -> list[MatchedImage]:
    """Each image's detections matched to its ground truth (arguments as :func:`evaluate_detections`). Matching is
    per image, so any subset or resample of a set's images is scored from these without matching again."""
    out = []
    per_image_ignores = ignores if ignores is not None else [np.zeros((0, 4))] * len(gts)
    for pred, gt, ign in zip(preds, gts, per_image_ignores, strict=True):
        pred = np.asarray(pred, dtype=np.float64).reshape(-1, 5)
        gt = np.asarray(gt, dtype=np.float64).reshape(-1, 4)
        if size_range is None:
            n_gt = len(gt)
        else:
            side = np.sqrt(np.clip((gt[:, 2] - gt[:, 0]) * (gt[:, 3] - gt[:, 1]), 0, None))
            n_gt = int(np.sum((side >= size_range[0]) & (side < size_range[1])))
        pred = pred[np.argsort(-pred[:, 4], kind="mergesort")[:max_det]]
        tp, ig = _match_image(pred, gt, np.asarray(ign, dtype=np.float64).reshape(-1, 4), size_range)
        out.append(MatchedImage(pred[:, 4], tp, ig, n_gt))
    return out


def _accumulate(images: Sequence[MatchedImage],
                first_only: bool = False) -> tuple[NDArray[np.float64], tuple[NDArray[np.float64], NDArray[np.float64]],
                                                   tuple[float, float, float]]:
    """AP per IoU threshold (only the first, IoU 0.5, if ``first_only``; the others 0), the precision-recall curve
    at IoU 0.5 and (precision, recall, confidence) at its best F1, from matched images."""
    t = len(IOU_THRESHOLDS)
    n_gt = sum(m.n_gt for m in images)
    scores = np.concatenate([m.scores for m in images]) if images else np.zeros(0)
    tps = np.concatenate([m.tp for m in images], axis=1) if images else np.zeros((t, 0), dtype=bool)
    igs = np.concatenate([m.ignored for m in images], axis=1) if images else np.zeros((t, 0), dtype=bool)
    order = np.argsort(-scores, kind="mergesort")
    scores, tps, igs = scores[order], tps[:, order], igs[:, order]
    ap = np.zeros(t)
    pr = (np.zeros(0), np.zeros(0))
    best = (0.0, 0.0, 0.0)
    if n_gt and len(scores):
        for ti in range(1 if first_only else t):
            # an ignored detection adds to neither count (its entry repeats the previous point, as in pycocotools)
            tp_c = np.cumsum(tps[ti]).astype(np.float64)
            fp_c = np.cumsum(~tps[ti] & ~igs[ti]).astype(np.float64)
            rc = tp_c / n_gt
            pc = tp_c / (tp_c + fp_c + np.spacing(1))
            pm = np.maximum.accumulate(pc[::-1])[::-1]  # monotone: best precision at this recall or beyond
            idx = np.searchsorted(rc, RECALL_POINTS, side="left")
            q = np.where(idx < len(pm), pm[np.minimum(idx, len(pm) - 1)], 0.0)
            ap[ti] = q.mean()
            if ti == 0:
                pr = (rc, pc)
                f1 = 2 * pc * rc / (pc + rc + 1e-12)
                k = int(np.argmax(f1))
                best = (float(pc[k]), float(rc[k]), float(scores[k]))
    return ap, pr, best


def evaluate_detections(preds: list[NDArray[np.float64]], gts: list[NDArray[np.float64]],
                        max_det: int = MAX_DETECTIONS, ignores: list[NDArray[np.float64]] | None = None,
                        size_range: tuple[float, float] | None = None) -> DetectionMetrics:
    """Metrics of per-image predictions (n, 5) [x0, y0, x1, y1, score] against ground truths (m, 4) xyxy.

    Single class (zebra); boxes in the same pixel coordinates. ``ignores``: per image, don't-care boxes (k, 4)
    xyxy (pycocotools' ``iscrowd=1``: see the module's docstring); None for none. ``size_range``: only objects
    whose sqrt(area) in px lies in [lo, hi) count (COCO's area ranges; see :func:`_match_image`). With no ground
    truth at all, AP is 0.
    """
    return metrics_of(match_images(preds, gts, max_det, ignores, size_range))


def metrics_of(matched: Sequence[MatchedImage]) -> DetectionMetrics:
    """The metrics of images already matched (:func:`match_images`): any subset of them, without matching again
    (the ``scorer`` node keeps each frame's match while it stays in its window)."""
    ap, pr, (best_p, best_r, best_conf) = _accumulate(matched)
    return DetectionMetrics(ap=ap, precision=best_p, recall=best_r, f1_confidence=best_conf, images=len(matched),
                            instances=sum(m.n_gt for m in matched), pr_curve=pr)


def count_errors(matched: Sequence[MatchedImage], conf: float) -> dict[str, float | int | None]:
    """How well the detections at ``conf`` or above count the zebras, image by image, as an aerial census counts
    them: ``counted`` (detections not on a don't-care region: a zebra the labels drop is neither counted nor
    missed) against ``true`` (the zebras that count) over ``images``; ``mae`` and ``bias``, the mean absolute and
    signed error of an image's count (counted - true); ``relative``, the error of the whole count over the true
    total (None without zebras). A count says nothing of where: a miss and a false detection in one image cancel
    (mAP and recall tell them apart)."""
    if not 0.0 <= conf <= 1.0:
        raise ParameterError("count_conf", conf, "0..1")
    counted = np.array([int(np.sum((m.scores >= conf) & ~m.ignored[0])) for m in matched], np.int64)
    true = np.array([m.n_gt for m in matched], np.int64)
    err = counted - true
    total = int(true.sum())
    return {"conf": conf, "images": len(matched), "true": total, "counted": int(counted.sum()),
            "mae": round(float(np.abs(err).mean()), 4) if len(err) else 0.0,
            "bias": round(float(err.mean()), 4) if len(err) else 0.0,
            "relative": round(float(err.sum() / total), 4) if total else None}


def count_line(c: dict[str, Any]) -> str:
    """One line of :func:`count_errors`' figures."""
    rel = f" ({c['relative']:+.1%})" if c["relative"] is not None else ""
    return (f"count at conf {c['conf']:g}: {c['counted']} counted for {c['true']} zebras{rel}, per image mean absolute "
            f"error {c['mae']:.2f}, bias {c['bias']:+.2f}")


def interval95(draws: NDArray[np.float64]) -> tuple[float, float]:
    """The central 95% interval (2.5th and 97.5th percentiles) of bootstrap draws."""
    lo, hi = np.percentile(np.asarray(draws, dtype=np.float64), [2.5, 97.5])
    return float(lo), float(hi)


def paired_bootstrap(runs: Sequence[Sequence[MatchedImage]], groups: Sequence[Hashable], samples: int = 1000,
                     seed: int = 0, map50_only: bool = False) -> NDArray[np.float64]:
    """AP of every run on ``samples`` resamples of the same images: (samples, runs, thresholds).

    ``runs``: each a set's images matched (:func:`match_images`), the same images in the same order for every run
    (several detectors on one set). ``groups``: one key per image; images that share a key (the views of one
    placement, whose animals and light are the same) are drawn together, so the spread is that of a set of new
    placements. Every run is scored on the same draws (paired), so the spread of a difference between two runs leaves
    out what the draws change for both alike. ``map50_only``: only AP at IoU 0.5 (the other columns 0), about ten
    times faster. Seeded: the same arguments give the same draws."""
    if samples < 1:
        raise ParameterError("samples", samples, "1 or more")
    if seed < 0:
        raise ParameterError("seed", seed, "0 or more")
    n = len(groups)
    if not runs or any(len(r) != n for r in runs):
        raise ParameterError("runs", [len(r) for r in runs], f"one or more runs of {n} images each (one per group key)")
    by_key: dict[Hashable, list[int]] = {}
    for i, g in enumerate(groups):
        by_key.setdefault(g, []).append(i)
    members = list(by_key.values())  # in the order the keys first appear
    rng = np.random.default_rng(seed)
    out = np.zeros((samples, len(runs), len(IOU_THRESHOLDS)))
    for s in range(samples):
        picked = [i for k in rng.integers(0, len(members), len(members)) for i in members[k]]
        for r, run in enumerate(runs):
            out[s, r] = _accumulate([run[i] for i in picked], first_only=map50_only)[0]
    return out


# Object sizes (sqrt of box area, px) for AP by size: ours (half our zebras are under 12 px) and COCO's.
SIZE_BINS: dict[str, tuple[float, float]] = {
    "<8": (0.0, 8.0), "8-16": (8.0, 16.0), "16-32": (16.0, 32.0), "32-96": (32.0, 96.0), ">=96": (96.0, 1e9),
    "small": (0.0, 32.0), "medium": (32.0, 96.0), "large": (96.0, 1e9)}


def ap_by_size(preds: list[NDArray[np.float64]], gts: list[NDArray[np.float64]], max_det: int = MAX_DETECTIONS,
               ignores: list[NDArray[np.float64]] | None = None) -> dict[str, dict[str, float | int]]:
    """AP50, AP50-95 and the instance count in each of :data:`SIZE_BINS` (COCO's small/medium/large are sqrt
    areas under 32, 32-96 and over 96 px, i.e. areas of 32² and 96²); a bin with no instances has AP 0."""
    out: dict[str, dict[str, float | int]] = {}
    for name, rng in SIZE_BINS.items():
        m = evaluate_detections(preds, gts, max_det, ignores, rng)
        out[name] = {"mAP50": round(m.map50, 4), "mAP50-95": round(m.map50_95, 4), "instances": m.instances}
    return out


def precision_recall_at(preds: list[NDArray[np.float64]], gts: list[NDArray[np.float64]], conf: float,
                        ignores: list[NDArray[np.float64]] | None = None) -> tuple[float, float]:
    """Precision and recall at IoU 0.5 of the detections with score >= ``conf`` (what a deployed detector with
    that threshold reports), don't-care boxes honoured."""
    tp = fp = n_gt = 0
    per_image_ignores = ignores if ignores is not None else [np.zeros((0, 4))] * len(gts)
    for pred, gt, ign in zip(preds, gts, per_image_ignores, strict=True):
        pred = np.asarray(pred, dtype=np.float64).reshape(-1, 5)
        pred = pred[pred[:, 4] >= conf]
        pred = pred[np.argsort(-pred[:, 4], kind="mergesort")]
        gt = np.asarray(gt, dtype=np.float64).reshape(-1, 4)
        t, ig = _match_image(pred, gt, np.asarray(ign, dtype=np.float64).reshape(-1, 4))
        tp += int(t[0].sum())
        fp += int((~t[0] & ~ig[0]).sum())
        n_gt += len(gt)
    return tp / max(tp + fp, 1), tp / max(n_gt, 1)


def pr_curve_png(metrics: DetectionMetrics, path: str, title: str = "precision-recall, IoU 0.5") -> None:
    """Draw the precision-recall curve at IoU 0.5 into a PNG (OpenCV, no plotting library needed)."""
    import cv2

    w, h, m = 640, 480, 60
    img = np.full((h, w, 3), 255, np.uint8)
    cv2.rectangle(img, (m, 20), (w - 20, h - m), (0, 0, 0), 1)
    for k in range(0, 11, 2):
        x = int(m + (w - 20 - m) * k / 10)
        y = int(h - m - (h - m - 20) * k / 10)
        cv2.putText(img, f"{k / 10:.1f}", (x - 10, h - m + 20), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1)
        cv2.putText(img, f"{k / 10:.1f}", (m - 35, y + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1)
    rc, pc = metrics.pr_curve
    if len(rc):
        pts = np.stack([m + rc * (w - 20 - m), h - m - pc * (h - m - 20)], 1).astype(np.int32)
        cv2.polylines(img, [pts], False, (200, 80, 0), 2, cv2.LINE_AA)
    cv2.putText(img, "recall", (w // 2 - 20, h - 15), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1)
    cv2.putText(img, "precision", (5, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1)
    cv2.putText(img, f"{title}: AP50 {metrics.map50:.3f}, AP50-95 {metrics.map50_95:.3f}", (m + 10, 40),
                cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.imwrite(path, img)
