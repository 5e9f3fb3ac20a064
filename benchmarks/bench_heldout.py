"""Benchmark: detector quality on freshly generated held-out sets, with a breakdown by world and light.

Generates (once, cached under --cache, keyed by the animal asset's digest) a YOLO set of ``--frames`` frames
(``--size``, default 640x360, the size of the training sets; the cameras' own default is 1280x720) over ``--worlds``
with a seed never used for training data (``--seed``, default 777), then scores every ``--weights`` on it with our
COCO metrics (mAP50, mAP50-95 at each ``--imgsz``, by default each checkpoint's own; conf 0.001), overall, per world
and by light (day: sun above 15 degrees; low sun: 0..15; night: below the horizon). Zebras seen but below the label
filters are don't-care regions; the score with them counted as false positives is given too. Several weights are
scored on the same frames in the same run, so they can be compared directly. The issue's goal on a larger held-out
set: mAP50 0.95, mAP50-95 0.7.

    python benchmarks/bench_heldout.py --worlds snowy_highland --frames 120 --weights shipped runs/x/best.pt
    python benchmarks/bench_heldout.py --worlds training --frames 210 --json
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import torch

from zebra_sim_ros.cli import size_arg
from zebra_sim_ros.dataset.generate import GenerateConfig, generate
from zebra_sim_ros.detection.checkpoint import load_model
from zebra_sim_ros.detection.data import resolve_split
from zebra_sim_ros.detection.evaluate import make_loader, predictions
from zebra_sim_ros.detection.evaluate import score as score_images
from zebra_sim_ros.detection.predict import inference_size
from zebra_sim_ros.labels.config import LabelFilters
from zebra_sim_ros.placement.sun import light_band
from zebra_sim_ros.zebra.asset import appearance_digest

TRAINING_WORLDS = ("savanna", "grassland", "meadow", "woodland", "moorland", "scrubland", "farmland")


def held_out_set(root: Path, worlds: tuple[str, ...], frames: int, seed: int, size: tuple[int, int] = (640, 360)
                 ) -> Path:
    """Generate (or reuse) the set; returns its dataset.yaml. At 640x360, the same settings as the CI tests' sets."""
    if not (root / "dataset.yaml").exists():
        generate(GenerateConfig(out=str(root), frames=frames, strategy="both", worlds=worlds, seed=seed,
                                width=size[0], height=size[1], val_fraction=0.0, depth="none",
                                filters=LabelFilters(min_visible_pixels=25), workers=2), progress=lambda *a: None)
    return root / "dataset.yaml"


def score(weights: str, data: Path, imgsz: int) -> dict[str, Any]:
    model, _ = load_model(None if weights == "shipped" else weights, torch.device("cpu"))
    t0 = time.perf_counter()
    per_image = predictions(model, make_loader(resolve_split(data, "train"),
                                               lambda long_side: inference_size(model.cfg, long_side, imgsz or None)))
    size = sorted({p.imgsz for p in per_image})
    groups: dict[str, list[int]] = defaultdict(list)
    for i, p in enumerate(per_image):
        meta = json.loads((data.parent / "annotations" / f"{Path(p.file).stem}.json").read_text())
        groups["all"].append(i)
        groups[f"world {meta['world']['name']}"].append(i)
        groups[f"light {light_band(meta['lighting']['sun_elevation_deg'])}"].append(i)
    out: dict[str, Any] = {"weights": weights, "imgsz": size, "seconds": round(time.perf_counter() - t0, 1)}
    for name, idx in sorted(groups.items(), key=lambda kv: (kv[0] != "all", kv[0])):
        subset = [per_image[i] for i in idx]
        m = score_images(subset)
        plain = score_images([p._replace(ignore=np.zeros((0, 4))) for p in subset])  # don't-care as false positives
        out[name] = {"images": len(idx), "instances": m.instances, "mAP50": round(m.map50, 3),
                     "mAP50-95": round(m.map50_95, 3), "P": round(m.precision, 3), "R": round(m.recall, 3),
                     "plain mAP50": round(plain.map50, 3), "plain mAP50-95": round(plain.map50_95, 3)}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", default="snowy_highland", help="comma-separated presets, or 'training' (the seven "
                    "worlds the shipped weights were trained on)")
    ap.add_argument("--frames", type=int, default=120)
    ap.add_argument("--seed", type=int, default=777)
    ap.add_argument("--weights", nargs="+", default=["shipped"], help="checkpoints ('shipped': the package's own)")
    ap.add_argument("--size", default="640x360", type=size_arg, help="frame size WxH of the generated set, px")
    ap.add_argument("--imgsz", type=int, nargs="+", default=[0], help="inference sizes, each weights scored at each "
                    "(0: the checkpoint's rule, as zebra-sim val)")
    ap.add_argument("--cache", type=Path, default=Path("out/heldout"))
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    worlds = TRAINING_WORLDS if args.worlds == "training" else tuple(args.worlds.split(","))
    size: tuple[int, int] = args.size
    root = args.cache / (f"{args.worlds.replace(',', '+')}_{args.frames}_{args.seed}"
                         + ("" if size == (640, 360) else f"_{size[0]}x{size[1]}") + f"_{appearance_digest()[:8]}")
    data = held_out_set(root, worlds, args.frames, args.seed, size)
    results: dict[str, Any] = {"machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
               "set": {"worlds": list(worlds), "frames": args.frames, "seed": args.seed, "size": list(size),
                       "imgsz": args.imgsz},
               "scores": [score(w, data, n) for w in args.weights for n in args.imgsz]}
    if args.json:
        print(json.dumps(results, indent=1))
        return
    for r in results["scores"]:
        print(f"{r['weights']} at imgsz {r['imgsz']} ({r['seconds']} s)")
        for k, v in r.items():
            if isinstance(v, dict):
                print(f"  {k:24s} {v['images']:4d} images {v['instances']:5d} zebras  mAP50 {v['mAP50']:.3f}  "
                      f"mAP50-95 {v['mAP50-95']:.3f}  P {v['P']:.3f}  R {v['R']:.3f}  (don't-care as false "
                      f"positives: {v['plain mAP50']:.3f} / {v['plain mAP50-95']:.3f})")


if __name__ == "__main__":
    main()
