"""Benchmark: where a generated set's mAP is lost, by how many pixels of each zebra are visible.

    python benchmarks/bench_visibility.py SET [SET ...] [--weights shipped] [--floors 0 20 40 100] [--scale 0]
        [--amp off] [--by lighting strategy camera] [--json]

``SET``: a ``zebra-sim generate`` folder (its ``annotations/`` hold each zebra's ``visible_pixels``); several are
pooled into one evaluation. The weights run once over its images (served as ``zebra-sim val`` serves them: the
checkpoint's rule, or ``--scale``); then, for each floor, the labelled zebras with fewer visible pixels than the
floor become don't-care boxes (neither found nor missed, as COCO scores crowd regions, and as the label filters'
drops already are) and the same detections are scored again. Floor 0 is the set as labelled: its mAP is ``zebra-sim
val``'s. The table gives each floor's labelled zebras and mAP50 / mAP50-95, and the AP50 of each band of visible
pixels on its own. A last line counts the detections on animals of other species (IoU >= 0.3 with one's visible box,
< 0.5 with every zebra, don't-care ones included) and gives the mAP50 with them left out: what confusing the other
species costs.
``--by``: the same detections scored again per group of frames, by what each frame's annotation records: its light
(``lighting``: day, low sun and night, :func:`zebra_sim_ros.placement.sun.light_band`), its camera ``strategy`` (far,
closeby, ...) or its ``camera``.
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
from zebra_sim_ros.detection.metrics import iou_matrix
from zebra_sim_ros.detection.predict import inference_size
from zebra_sim_ros.placement.sun import light_band


def zebras(p: ImagePredictions) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """From an image's annotation: its labelled zebras' visible boxes (n, 4) and visible pixels (n,), and the
    visible boxes (m, 4) of the animals of other species in it."""
    rec = json.loads(annotation_path(Path(p.file)).read_text())
    kept = [z for z in rec["labels"]["zebras"] if z.get("kept") and z.get("species", "zebra") == "zebra"]
    boxes = np.asarray([z["box_visible"] for z in kept], np.float64).reshape(-1, 4)
    others = np.asarray([z["box_visible"] for z in rec["labels"]["zebras"]
                         if z.get("species", "zebra") != "zebra" and z.get("box_visible")], np.float64).reshape(-1, 4)
    return boxes, np.asarray([int(z["visible_pixels"]) for z in kept], np.int64), others


def on_other_species(p: ImagePredictions, others: np.ndarray) -> np.ndarray:
    """Which detections of ``p`` lie on an animal of another species: IoU >= 0.3 with one of ``others``, < 0.5 with
    every labelled zebra and every don't-care zebra."""
    d = p.detections[:, :4]
    if not len(d) or not len(others):
        return np.zeros(len(d), bool)
    on = iou_matrix(d, others).max(1) >= 0.3
    zebras = np.concatenate([p.labels, p.ignore]).astype(np.float64).reshape(-1, 4)
    if len(zebras):
        on &= iou_matrix(d, zebras).max(1) < 0.5
    return np.asarray(on, bool)


def condition(p: ImagePredictions, by: str) -> str:
    """The group of ``p``'s frame under ``by`` (see the module's docstring), from its annotation."""
    rec = json.loads(annotation_path(Path(p.file)).read_text())
    if by == "lighting":
        return light_band(rec["lighting"]["sun_elevation_deg"])
    if by == "strategy":
        return str(rec["strategy"])
    return str(rec["camera"]["name"])


def split(per: list[ImagePredictions], keep: list[tuple[np.ndarray, np.ndarray, np.ndarray]], lo: int,
          hi: int | None) -> list[ImagePredictions]:
    """The same detections, with the zebras of ``lo`` <= visible pixels < ``hi`` labelled, the rest don't-care."""
    out = []
    for p, (boxes, vis, _) in zip(per, keep, strict=True):
        inside = (vis >= lo) & (vis < hi if hi is not None else True)
        out.append(p._replace(labels=boxes[inside], ignore=np.concatenate([p.ignore, boxes[~inside]])))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("set", type=Path, nargs="+", help="zebra-sim generate folders (several: pooled)")
    ap.add_argument("--split", default="train", help="their split to score (generate's held-out sets: train)")
    ap.add_argument("--weights", default="shipped")
    ap.add_argument("--floors", type=int, nargs="+", default=[0, 20, 40, 100])
    ap.add_argument("--scale", type=float, default=0.0, help="inference size as a multiple of the long side "
                                                             "(0: the checkpoint's rule)")
    ap.add_argument("--amp", default="off", help="the detector's amp: its features in mixed precision (off, auto, "
                                                 "bf16)")
    ap.add_argument("--by", nargs="+", default=[], choices=["lighting", "strategy", "camera"],
                    help="also score the frames in groups: by light, camera strategy or camera")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    model, _ = load_model(None if args.weights == "shipped" else args.weights, torch.device("cpu"), amp=args.amp)
    per: list[ImagePredictions] = []
    for root in args.set:
        folder = resolve_split(root, args.split)
        per += predictions(model, make_loader(folder, lambda side: inference_size(model.cfg, side, None, args.scale),
                                              4))
    keep = [zebras(p) for p in per]
    n_files = sum(len(p.labels) for p in per)
    n_ann = sum(len(b) for b, _, _ in keep)
    if n_files != n_ann:
        raise SystemExit(f"bench_visibility: {args.set} hold {n_files} labelled zebras in labels/ but {n_ann} in "
                         "annotations/: not the same sets")
    floors = sorted(set(args.floors))
    rows = []
    for k, lo in enumerate(floors):
        m_all = score(split(per, keep, lo, None))
        hi = floors[k + 1] if k + 1 < len(floors) else None
        m_band = score(split(per, keep, lo, hi))
        rows.append({"floor": lo, "zebras": m_all.instances, "mAP50": round(m_all.map50, 4),
                     "mAP50-95": round(m_all.map50_95, 4), "band": f"{lo}-{hi - 1 if hi else ''}",
                     "band_zebras": m_band.instances, "band_AP50": round(m_band.map50, 4)})
    on = [on_other_species(p, o) for p, (_, _, o) in zip(per, keep, strict=True)]
    others = {"detections": int(sum(x.sum() for x in on)),
              "at_0.25": int(sum((x & (p.detections[:, 4] >= 0.25)).sum() for x, p in zip(on, per, strict=True))),
              "animals": int(sum(len(o) for _, _, o in keep)),
              "mAP50_without": round(score([p._replace(detections=p.detections[~x])
                                            for p, x in zip(per, on, strict=True)]).map50, 4)}
    groups = []
    for by in args.by:
        members: dict[str, list[int]] = {}
        for i, p in enumerate(per):
            members.setdefault(condition(p, by), []).append(i)
        for name, idx in sorted(members.items()):
            sub, sub_keep = [per[i] for i in idx], [keep[i] for i in idx]
            m = score(sub)
            bands = [round(score(split(sub, sub_keep, lo, floors[k + 1] if k + 1 < len(floors) else None)).map50, 4)
                     for k, lo in enumerate(floors)]
            groups.append({"by": by, "group": name, "frames": len(idx), "zebras": m.instances,
                           "mAP50": round(m.map50, 4), "mAP50-95": round(m.map50_95, 4), "band_AP50": bands})
    names = ", ".join(str(s) for s in args.set)
    print(f"{args.weights} on {names} ({len(per)} images, served at {sorted({p.imgsz for p in per})}, features in "
          f"{model.serve_precision}), "
          f"{platform.processor() or platform.machine()}")
    print("| zebras scored | labelled zebras | mAP50 | mAP50-95 | band of visible px | its zebras | its AP50 |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        band_ap = f"{r['band_AP50']:.3f}" if r["band_zebras"] else "-"
        print(f"| >= {r['floor']} visible px | {r['zebras']} | {r['mAP50']:.3f} | {r['mAP50-95']:.3f} | "
              f"{r['band']} | {r['band_zebras']} | {band_ap} |")
    print(f"Detections on the {others['animals']} animals of other species: {others['detections']} "
          f"({others['at_0.25']} at conf 0.25 or more); mAP50 without them {others['mAP50_without']:.3f} "
          f"(with them {rows[0]['mAP50'] if floors[0] == 0 else '-'})")
    if groups:
        heads = " | ".join(f"{r['band']} px AP50" for r in rows)
        print(f"| by | group | frames | labelled zebras | mAP50 | mAP50-95 | {heads} |")
        print("| --- " * (6 + len(rows)) + "|")
        for g in groups:
            print(f"| {g['by']} | {g['group']} | {g['frames']} | {g['zebras']} | {g['mAP50']:.3f} | "
                  f"{g['mAP50-95']:.3f} | " + " | ".join(f"{b:.3f}" for b in g["band_AP50"]) + " |")
    if args.json:
        print(json.dumps({"weights": args.weights, "sets": [str(s) for s in args.set], "rows": rows,
                          "other_species": others, "groups": groups}))


if __name__ == "__main__":
    main()
