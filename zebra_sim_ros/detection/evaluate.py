"""Validation: run a model over a YOLO-format set and compute COCO-style metrics.

``run(model=..., loader=...)`` is what training calls every epoch; :func:`evaluate` opens a checkpoint and a
dataset for ``zebra-sim val``. Works on any YOLO-format labelled set, real images included.
"""

from __future__ import annotations

import re
import time
from collections import defaultdict
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
import torch
from numpy.typing import NDArray
from torch.utils.data import DataLoader

from zebra_sim_ros.detection.boxes import postprocess
from zebra_sim_ros.detection.checkpoint import load_model, select_device
from zebra_sim_ros.detection.data import ImageMeta, YoloDataset, collate, resolve_split
from zebra_sim_ros.detection.metrics import (
    MAX_DETECTIONS,
    DetectionMetrics,
    MatchedImage,
    ap_by_size,
    count_errors,
    evaluate_detections,
    interval95,
    match_images,
    metrics_of,
    paired_bootstrap,
)
from zebra_sim_ros.detection.model import ZEBRA, Detector
from zebra_sim_ros.detection.predict import describe_size, inference_size, unletterbox
from zebra_sim_ros.detection.scoring import COUNT_CONF

if TYPE_CHECKING:
    from zebra_sim_ros.detection.verify import Verifier


def make_loader(folder: str | Path | Sequence[str | Path], imgsz: int | Callable[[int], int], batch: int = 8,
                workers: int = 0) -> DataLoader[Any]:
    """A validation loader (letterbox only, in file order) at ``imgsz``, or at ``imgsz(long side)`` per image."""
    ds = (YoloDataset(folder, imgsz) if isinstance(imgsz, int) else YoloDataset(folder, size_for=imgsz))
    return DataLoader(ds, batch_size=batch, shuffle=False, num_workers=workers, collate_fn=collate)


class ImagePredictions(NamedTuple):
    """One image's detections and ground truth, all in the image's own pixels."""

    file: str
    detections: NDArray[np.float64]  # (n, 5) [x0, y0, x1, y1, score]
    labels: NDArray[np.float64]  # (m, 4) xyxy
    ignore: NDArray[np.float64]  # (k, 4) xyxy don't-care boxes
    imgsz: int  # the inference size it was letterboxed to (long side), px


def predictions(model: Detector, loader: DataLoader[Any], conf: float = 0.001, iou: float = 0.7,
                max_det: int = MAX_DETECTIONS, cls: int = ZEBRA, verifier: Verifier | None = None,
                batch_seconds: list[tuple[float, int]] | None = None) -> list[ImagePredictions]:
    """Per image of ``loader``: its detections of class ``cls`` (zebras; a model's other classes are left out),
    labels and don't-care boxes. ``batch_seconds``, if given, gets (seconds, images) per batch, reading included."""
    return predictions_by_class(model, loader, (cls,), conf, iou, max_det, verifier, batch_seconds)[cls]


@torch.no_grad()
def predictions_by_class(model: Detector, loader: DataLoader[Any], classes: tuple[int, ...], conf: float = 0.001,
                         iou: float = 0.7, max_det: int = MAX_DETECTIONS, verifier: Verifier | None = None,
                         batch_seconds: list[tuple[float, int]] | None = None) -> dict[int, list[ImagePredictions]]:
    """:func:`predictions` for each of ``classes`` from one pass over ``loader`` (the same detections as one call
    per class: NMS runs before the split). With a ``verifier`` the zebra detections are rescored as
    :func:`~zebra_sim_ros.detection.predict.detect` rescores them, on crops of the image file itself."""
    from zebra_sim_ros.detection.verify import read_rgb, rescore

    was_training = model.training
    model.eval()
    out: dict[int, list[ImagePredictions]] = {c: [] for c in classes}
    t0 = time.perf_counter()
    for imgs, _, metas in loader:
        for det, meta in zip(_forward(model, imgs, metas, conf, iou, max_det), metas, strict=True):
            h, w = meta.shape
            left, top = meta.pad
            labels, ignore = meta.labels[:, 1:].astype(np.float64), meta.ignore[:, 1:].astype(np.float64)
            for c in classes:
                d = unletterbox(det[det[:, 5] == c], meta.scale, left, top, w, h).cpu().numpy()
                if verifier is not None and c == ZEBRA and len(d):
                    d = rescore(verifier, read_rgb(meta.file), d, conf)
                out[c].append(ImagePredictions(meta.file, d[:, :5].astype(np.float64),  # labels read once, by the
                                               labels, ignore, meta.imgsz))  # loader
        if batch_seconds is not None:
            t1 = time.perf_counter()
            batch_seconds.append((t1 - t0, len(metas)))
            t0 = t1
    if was_training:
        model.train()
    return out


def _forward(model: Detector, imgs: torch.Tensor, metas: list[ImageMeta], conf: float, iou: float,
             max_det: int) -> list[torch.Tensor]:
    """Detections of a validation batch. Images of another input size than the batch's largest were padded at
    the bottom and right by :func:`~zebra_sim_ros.detection.data.collate`: each size runs on its own, cropped
    back, so every image sees exactly the input inference would give it."""
    dev = next(model.parameters()).device
    groups: dict[tuple[int, int], list[int]] = defaultdict(list)
    for k, meta in enumerate(metas):
        groups[meta.input].append(k)
    out: list[torch.Tensor] = [torch.zeros(0)] * len(metas)
    for (h, w), idx in groups.items():
        x = imgs[idx, :, :h, :w] if len(groups) > 1 else imgs
        raw = model(x.to(dev).contiguous(memory_format=torch.channels_last))  # the serving layout
        for k, det in zip(idx, postprocess(raw, conf, iou, max_det), strict=True):
            out[k] = det
    return out


def run(model: Detector, loader: DataLoader[Any], conf: float = 0.001, iou: float = 0.7,
        max_det: int = MAX_DETECTIONS) -> DetectionMetrics:
    """Metrics of ``model`` on ``loader`` (boxes compared in each image's original pixels)."""
    return score(predictions(model, loader, conf, iou, max_det), max_det)


def score(per_image: list[ImagePredictions], max_det: int = MAX_DETECTIONS) -> DetectionMetrics:
    """COCO metrics of :func:`predictions` (or a subset of them), don't-care boxes honoured."""
    return evaluate_detections([p.detections for p in per_image], [p.labels for p in per_image], max_det,
                               [p.ignore for p in per_image])


def matched(per_image: Sequence[ImagePredictions], max_det: int = MAX_DETECTIONS) -> list[MatchedImage]:
    """:func:`predictions` matched image by image (:func:`~zebra_sim_ros.detection.metrics.match_images`), for
    :func:`~zebra_sim_ros.detection.metrics.paired_bootstrap`."""
    return match_images([p.detections for p in per_image], [p.labels for p in per_image], max_det,
                        [p.ignore for p in per_image])


def placement(file: str | Path) -> str:
    """The placement an image of a generated set shows, the key its views share in a bootstrap: the file's name
    without its drone (``savanna_far_1234_000003_drone_1`` -> ``savanna_far_1234_000003``); an image named
    otherwise is a placement of its own."""
    return re.sub(r"_drone_\d+$", "", Path(file).stem)


def bootstrap_interval(per_image: Sequence[ImagePredictions], samples: int, seed: int = 0,
                       max_det: int = MAX_DETECTIONS) -> dict[str, Any]:
    """95% intervals of mAP50 and mAP50-95 over ``samples`` resamples of the set's placements (:func:`placement`;
    the views of one placement drawn together), seeded: how far the figures would move on new placements."""
    groups = [placement(p.file) for p in per_image]
    ap = paired_bootstrap([matched(per_image, max_det)], groups, samples, seed)[:, 0]
    return {"samples": samples, "seed": seed, "placements": len(set(groups)),
            "mAP50 95%": [round(x, 4) for x in interval95(ap[:, 0])],
            "mAP50-95 95%": [round(x, 4) for x in interval95(ap.mean(1))]}


def evaluate(weights: str | Path | None, data: str | Path, split: str = "val", imgsz: int | None = None,
             batch: int = 8, device: str = "auto", conf: float = 0.001, iou: float = 0.7,
             workers: int = 0, scale: float = 0.0, max_det: int = MAX_DETECTIONS, verifier: str | None = None,
             amp: str = "off", count_conf: float = COUNT_CONF) -> tuple[DetectionMetrics, dict[str, Any]]:
    """Open the checkpoint and the set, validate; returns the metrics and facts about the run. Each image is
    served at :func:`~zebra_sim_ros.detection.predict.inference_size` under ``imgsz`` and ``scale`` (default:
    the checkpoint's rule), as the detector node and ``bag eval`` serve it; ``verifier`` ('shipped' or a path)
    rescores the zebra boxes as the node's ``verifier`` parameter does; ``amp`` serves the features in mixed
    precision as its ``amp`` parameter does; the zebras are counted with the detections at ``count_conf`` or above,
    or at ``conf`` where it is higher: nothing under it is kept (facts' ``count``:
    :func:`~zebra_sim_ros.detection.metrics.count_errors`)."""
    dev = select_device(device)
    model, ckpt = load_model(weights, dev, amp=amp)
    net = None
    if verifier:
        from zebra_sim_ros.detection.verify import load_verifier

        net, _ = load_verifier(verifier, dev, "--verifier")
    folder = resolve_split(data, split)
    loader = make_loader(folder, lambda long_side: inference_size(model.cfg, long_side, imgsz, scale), batch, workers)
    t0 = time.perf_counter()
    batches: list[tuple[float, int]] = []
    per_image = predictions(model, loader, conf, iou, max_det, verifier=net, batch_seconds=batches)
    matches = matched(per_image, max_det)
    m = metrics_of(matches)
    sizes = sorted({p.imgsz for p in per_image})
    by_size = ap_by_size([p.detections for p in per_image], [p.labels for p in per_image], max_det,
                         ignores=[p.ignore for p in per_image])
    return m, {"weights": str(weights or "shipped"), "verifier": verifier or None, "data": str(folder),
               "ap_by_size": by_size, "count": count_errors(matches, max(count_conf, conf)),
               "per_image": per_image,
               "imgsz": sizes[0] if len(sizes) == 1 else sizes, "imgsz_rule": describe_size(model.cfg, imgsz, scale),
               "device": str(dev), "amp": model.serve_precision,
               "seconds": round(time.perf_counter() - t0, 2),
               "ms_per_image": round(steady_ms_per_image(batches), 1), "epoch": ckpt.get("epoch")}


def steady_ms_per_image(batches: list[tuple[float, int]]) -> float:
    """Milliseconds per image in the steady state: the batches' seconds over their images, the first batch left
    out when there are others (it pays the network's start-up: oneDNN primes its kernels on the first call of each
    input shape). 0.0 for no image."""
    steady = batches[1:] if len(batches) > 1 else batches
    images = sum(n for _, n in steady)
    return 1000 * sum(s for s, _ in steady) / images if images else 0.0


def write_plots(per_image: list[ImagePredictions], folder: Path, prefix: str = "", conf: float = 0.25,
                count: int = 16) -> dict[str, str]:
    """``<prefix>pr_curve.png`` (IoU 0.5) and ``<prefix>predictions.jpg`` (a grid of ``count`` images spread over
    the set: ground truth green, detections at ``conf`` or more red) in ``folder``; their paths."""
    import cv2

    from zebra_sim_ros.detection.draw import predictions_grid
    from zebra_sim_ros.detection.metrics import pr_curve_png

    folder.mkdir(parents=True, exist_ok=True)
    pr = folder / f"{prefix}pr_curve.png"
    pr_curve_png(score(per_image), str(pr))
    picks: list[int] = sorted({int(round(v)) for v in np.linspace(0, len(per_image) - 1, min(count, len(per_image)))}) \
        if per_image else []
    items = []
    for k in picks:
        p = per_image[int(k)]
        bgr = cv2.imread(p.file, cv2.IMREAD_COLOR)
        if bgr is not None:
            items.append((np.ascontiguousarray(bgr[..., ::-1], dtype=np.uint8), p.labels,
                          p.detections[p.detections[:, 4] >= conf]))
    grid = folder / f"{prefix}predictions.jpg"
    cv2.imwrite(str(grid), predictions_grid(items)[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, 90])
    return {"pr_curve": str(pr), "predictions": str(grid)}
