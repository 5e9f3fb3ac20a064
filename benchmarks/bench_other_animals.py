"""Benchmark: how well weights with an ``other_animal`` class (``train --other-animals``) find the animals of other
species in a generated set (the synthetic side of BENCHMARKS.md, "A second class: other animals").

    python benchmarks/bench_other_animals.py WEIGHTS [WEIGHTS ...] --data datasets/s2r_3000/images/val [--imgsz 1088]

For each weights: the animals of other species in the set's annotations (at least 40 visible pixels, as training
labels them), how many of them an other_animal detection at conf 0.25 overlaps at IoU >= 0.5, the other_animal
detections in all, and the zebra mAP50 of the same run. Prints one line per weights (``--json``: also as JSON).
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
from typing import Any

import numpy as np
import torch

from zebra_sim_ros.detection.checkpoint import load_model
from zebra_sim_ros.detection.data import other_species_boxes
from zebra_sim_ros.detection.evaluate import make_loader, predictions, score
from zebra_sim_ros.detection.metrics import iou_matrix
from zebra_sim_ros.detection.model import OTHER_ANIMAL

CONF = 0.25  # the detector node's default threshold


def measure(weights: str, data: Path, imgsz: int) -> dict[str, Any]:
    model, _ = load_model(weights, torch.device("cpu"))
    if OTHER_ANIMAL not in model.cfg.names:
        raise SystemExit(f"{weights}: no {OTHER_ANIMAL} class (its classes: {list(model.cfg.names)})")
    cls = model.cfg.names.index(OTHER_ANIMAL)
    animals = found = dets = 0
    for p in predictions(model, make_loader(data, imgsz, batch=4), cls=cls):
        boxes = other_species_boxes(Path(p.file)).astype(np.float64)
        d = p.detections[p.detections[:, 4] >= CONF]
        animals, dets = animals + len(boxes), dets + len(d)
        if len(boxes) and len(d):
            found += int((iou_matrix(boxes, d[:, :4]).max(1) >= 0.5).sum())
    zebra = score(predictions(model, make_loader(data, imgsz, batch=4)))
    return {"weights": weights, "data": str(data), "imgsz": imgsz, "animals": animals, "found": found,
            "found_share": round(found / max(animals, 1), 4), "other_animal_detections": dets,
            "zebra_mAP50": round(zebra.map50, 4)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    ap.add_argument("weights", nargs="+", help="checkpoints with an other_animal class")
    ap.add_argument("--data", type=Path, required=True, help="a generated set's image folder (with annotations/)")
    ap.add_argument("--imgsz", type=int, default=1088, help="inference long side, px (default 1088: the shipped "
                    "serving size of 640 px frames)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    torch.set_num_threads(max(1, int(os.environ.get("OMP_NUM_THREADS", os.cpu_count() or 1))))
    rows = [measure(w, args.data, args.imgsz) for w in args.weights]
    for r in rows:
        print(f"{r['weights']}: {r['found']} of {r['animals']} other animals found as {OTHER_ANIMAL} "
              f"({100 * r['found_share']:.0f}%), {r['other_animal_detections']} {OTHER_ANIMAL} detections, "
              f"zebra mAP50 {r['zebra_mAP50']:.3f} at {r['imgsz']} px")
    if args.json:
        print(json.dumps(rows))


if __name__ == "__main__":
    main()
