"""Validation: run a model over a YOLO-format set and compute COCO-style metrics.

``run(model=..., loader=...)`` is what training calls every epoch; :func:`evaluate` opens a checkpoint and a
dataset for ``zebra-sim val``. Works on any YOLO-format labelled set, real images included.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
import torch
from numpy.typing import NDArray
from torch.utils.data import DataLoader

from zebra_sim_ros.detection.boxes import postprocess
from zebra_sim_ros.detection.checkpoint import load_model, select_device
from zebra_sim_ros.detection.data import YoloDataset, collate, resolve_split
from zebra_sim_ros.detection.metrics import DetectionMetrics, evaluate_detections
from zebra_sim_ros.detection.model import Detector
from zebra_sim_ros.detection.predict import unletterbox


def make_loader(folder: str | Path, imgsz: int, batch: int = 8, workers: int = 0) -> DataLoader[Any]:
    """A validation loader (letterbox only, in file order)."""
    return DataLoader(YoloDataset(folder, imgsz), batch_size=batch, shuffle=False, num_workers=workers,
                      collate_fn=collate)


@torch.no_grad()
def predictions(model: Detector, loader: DataLoader[Any], conf: float = 0.001, iou: float = 0.7,
                max_det: int = 100) -> list[tuple[str, NDArray[np.float64], NDArray[np.float64]]]:
    """Per image of ``loader``: (file, detections (n, 5) [x0, y0, x1, y1, score], ground truth (m, 4)), both in
    the image's own pixels."""
    was_training = model.training
    model.eval()
    dev = next(model.parameters()).device
    out: list[tuple[str, NDArray[np.float64], NDArray[np.float64]]] = []
    for imgs, _, metas in loader:
        raw = model(imgs.to(dev).contiguous(memory_format=torch.channels_last))  # the serving layout
        for det, meta in zip(postprocess(raw, conf, iou, max_det), metas, strict=True):
            h, w = meta["shape"]
            left, top = meta["pad"]
            d = unletterbox(det, meta["scale"], left, top, w, h).cpu().numpy()
            out.append((meta["file"], d[:, :5].astype(np.float64),
                        meta["labels"][:, 1:].astype(np.float64)))  # labels in the image's own pixels, read once
    if was_training:
        model.train()
    return out


def run(model: Detector, loader: DataLoader[Any], conf: float = 0.001, iou: float = 0.7,
        max_det: int = 100) -> DetectionMetrics:
    """Metrics of ``model`` on ``loader`` (boxes compared in each image's original pixels)."""
    per_image = predictions(model, loader, conf, iou, max_det)
    return evaluate_detections([p for _, p, _ in per_image], [g for _, _, g in per_image], max_det)


def evaluate(weights: str | Path | None, data: str | Path, split: str = "val", imgsz: int | None = None,
             batch: int = 8, device: str = "auto", conf: float = 0.001, iou: float = 0.7,
             workers: int = 0) -> tuple[DetectionMetrics, dict[str, Any]]:
    """Open the checkpoint and the set, validate; returns the metrics and facts about the run."""
    dev = select_device(device)
    model, ckpt = load_model(weights, dev)
    size = imgsz or model.cfg.imgsz
    folder = resolve_split(data, split)
    loader = make_loader(folder, size, batch, workers)
    t0 = time.perf_counter()
    m = run(model, loader, conf, iou)
    return m, {"weights": str(weights or "shipped"), "data": str(folder), "imgsz": size, "device": str(dev),
               "seconds": round(time.perf_counter() - t0, 2), "epoch": ckpt.get("epoch")}
