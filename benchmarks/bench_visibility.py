"""Benchmark: where a generated set's mAP is lost, by how many pixels of each zebra are visible.

    python benchmarks/bench_visibility.py SET [--weights shipped] [--floors 0 20 40 100] [--scale 0] [--json]

``SET``: a ``zebra-sim generate`` folder (its ``annotations/`` hold each zebra's ``visible_pixels``). The weights
run once over its images (served as ``zebra-sim val`` serves them: the checkpoint's rule, or ``--scale``); then,
for each floor, the labelled zebras with fewer visible pixels than the floor become don't-care boxes (neither
found nor missed, as COCO scores crowd regions, and as the label filters' drops already are) and the same
detections are scored again. Floor 0 is the set as labelled: its mAP is ``zebra-sim val``'s. The table gives
each floor's labelled zebras and mAP50 / mAP50-95, and the AP50 of each band of visible pixels on its own.
A floor here is a question asked of the data, not a change to the labels: the sets keep every zebra of 10
visible pixels or more (the labeller's default ``min_visible_pixels``).
"""

from __future__ import annotations

import argparse
import json
import platform
from pathlib import Path

import numpy as np
import torch

from zebra_sim_ros.detection.checkpoint import load_model
from zebra_sim_ros.detection.data import annotation_path, resolve_split
from zebra_sim_ros.detection.evaluate import ImagePredictions, make_loader, predictions, score
from zebra_sim_ros.detection.predict import inference_size


def zebras(p: ImagePredictions) -> tuple[np.ndarray, np.ndarray]:
    """The labelled zebras of an image from its annotation: visible boxes (n, 4) and visible pixels (n,)."""
    rec = json.loads(annotation_path(Path(p.file)).read_text())
    kept = [z for z in rec["labels"]["zebras"] if z.get("kept") and z.get("species", "zebra") == "zebra"]
    boxes = np.asarray([z["box_visible"] for z in kept], np.float64).reshape(-1, 4)
    return boxes, np.asarray([int(z["visible_pixels"]) for z in kept], np.int64)


def split(per: list[ImagePredictions], keep: list[tuple[np.ndarray, np.ndarray]], lo: int,
          hi: int | None) -> list[ImagePredictions]:
    """The same detections, with the zebras of ``lo`` <= visible pixels < ``hi`` labelled, the rest don't-care."""
    out = []
    for p, (boxes, vis) in zip(per, keep, strict=True):
        inside = (vis >= lo) & (vis < hi if hi is not None else True)
        out.append(p._replace(labels=boxes[inside], ignore=np.concatenate([p.ignore, boxes[~inside]])))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("set", type=Path, help="a zebra-sim generate folder")
    ap.add_argument("--split", default="train", help="its split to score (generate's held-out sets: train)")
    ap.add_argument("--weights", default="shipped")
    ap.add_argument("--floors", type=int, nargs="+", default=[0, 20, 40, 100])
    ap.add_argument("--scale", type=float, default=0.0, help="inference size as a multiple of the long side "
                                                             "(0: the checkpoint's rule)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    model, _ = load_model(None if args.weights == "shipped" else args.weights, torch.device("cpu"))
    folder = resolve_split(args.set, args.split)
    per = predictions(model, make_loader(folder, lambda s: inference_size(model.cfg, s, None, args.scale), 4))
    keep = [zebras(p) for p in per]
    n_files = sum(len(p.labels) for p in per)
    n_ann = sum(len(b) for b, _ in keep)
    if n_files != n_ann:
        raise SystemExit(f"bench_visibility: {folder} has {n_files} labelled zebras in labels/ but {n_ann} in "
                         "annotations/: not the same set")
    floors = sorted(set(args.floors))
    rows = []
    for k, lo in enumerate(floors):
        m_all = score(split(per, keep, lo, None))
        hi = floors[k + 1] if k + 1 < len(floors) else None
        m_band = score(split(per, keep, lo, hi))
        rows.append({"floor": lo, "zebras": m_all.instances, "mAP50": round(m_all.map50, 4),
                     "mAP50-95": round(m_all.map50_95, 4), "band": f"{lo}-{hi - 1 if hi else ''}",
                     "band_zebras": m_band.instances, "band_AP50": round(m_band.map50, 4)})
    print(f"{args.weights} on {folder} ({len(per)} images, served at {sorted({p.imgsz for p in per})}), "
          f"{platform.processor() or platform.machine()}")
    print("| zebras scored | labelled zebras | mAP50 | mAP50-95 | band of visible px | its zebras | its AP50 |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        band_ap = f"{r['band_AP50']:.3f}" if r["band_zebras"] else "-"
        print(f"| >= {r['floor']} visible px | {r['zebras']} | {r['mAP50']:.3f} | {r['mAP50-95']:.3f} | "
              f"{r['band']} | {r['band_zebras']} | {band_ap} |")
    if args.json:
        print(json.dumps({"weights": args.weights, "set": str(folder), "rows": rows}))


if __name__ == "__main__":
    main()
