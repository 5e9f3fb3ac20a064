"""Benchmark: training on crops around zebras (``train --crop``) against whole frames, end to end.

Two ``zebra-sim train`` runs on the same data from the same starting weights, seed and augmentation, one after
the other in this process's machine: whole ``--imgsz`` frames for ``--whole-epochs``, then ``--crop`` windows for
``--crop-epochs`` (a crop run wants about 3x the epochs: per image it learns less). Both validate on whole
frames at ``--imgsz`` after their last epoch. The report: each run's images/s over the whole run (loading,
step and validation), its seconds and its val mAP50 / mAP50-95, and the ratios crop / whole. The figures in
BENCHMARKS.md ("Crops around zebras") came from the same two commands.

    python benchmarks/bench_crop.py --data DATASET.yaml [--init WEIGHTS] [--imgsz 640] [--crop 320]
        [--whole-epochs 2] [--crop-epochs 6] [--max-train-images 0] [--out runs/bench_crop] [--json]

A quick check of the mechanics: ``--max-train-images 128 --whole-epochs 1 --crop-epochs 3``.
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
from pathlib import Path
from typing import Any


def train(args: argparse.Namespace, name: str, epochs: int, crop: int) -> dict[str, Any]:
    """One ``zebra-sim train`` run; its JSON summary (the last line it prints)."""
    out = Path(args.out) / name
    cmd = [sys.executable, "-m", "zebra_sim_ros.cli", "train", "--data", args.data, "--model", args.model,
           "--imgsz", str(args.imgsz), "--crop", str(crop), "--epochs", str(epochs), "--batch", str(args.batch),
           "--workers", str(args.workers), "--lr0", str(args.lr0), "--warmup-epochs", "0.5",
           "--val-every", str(epochs), "--seed", str(args.seed), "--aug-zoom", str(args.aug_zoom),
           "--max-train-images", str(args.max_train_images), "--out", str(out), "--json"]
    if args.init:
        cmd += ["--init", args.init]
    print("$", " ".join(cmd[1:]), file=sys.stderr, flush=True)
    res = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if res.returncode != 0:
        raise SystemExit(f"bench_crop: the {name} run failed (exit {res.returncode}):\n{res.stderr[-2000:]}")
    return dict(json.loads(res.stdout.strip().splitlines()[-1]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True, help="dataset.yaml (a zebra-sim generate set)")
    ap.add_argument("--init", default="", help="starting weights for both runs (default: random)")
    ap.add_argument("--model", default="n")
    ap.add_argument("--imgsz", type=int, default=640)
    ap.add_argument("--crop", type=int, default=320)
    ap.add_argument("--whole-epochs", type=int, default=2)
    ap.add_argument("--crop-epochs", type=int, default=6)
    ap.add_argument("--batch", type=int, default=16)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--lr0", type=float, default=0.005)
    ap.add_argument("--aug-zoom", type=float, default=0.5)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--max-train-images", type=int, default=0)
    ap.add_argument("--out", default="runs/bench_crop")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    if not 0 < args.crop < args.imgsz:
        raise SystemExit(f"bench_crop: --crop {args.crop} must be above 0 and below --imgsz {args.imgsz}")
    runs = {"whole": train(args, "whole", args.whole_epochs, 0),
            "crop": train(args, "crop", args.crop_epochs, args.crop)}
    w, c = runs["whole"], runs["crop"]
    ratio = c["train_images_per_s"] / max(w["train_images_per_s"], 1e-9)
    print(f"machine: {platform.processor() or platform.machine()}, data {args.data}, init {args.init or 'random'}")
    print("| run | epochs | images/s (whole run) | seconds | val mAP50 / mAP50-95 |")
    print("| --- | --- | --- | --- | --- |")
    for name, r, ep in (("whole frames", w, args.whole_epochs), (f"{args.crop} px crops", c, args.crop_epochs)):
        f = r["final"]
        print(f"| {name} at {args.imgsz} | {ep} | {r['train_images_per_s']:.2f} | {r['seconds']:.0f} | "
              f"{f['mAP50']:.3f} / {f['mAP50-95']:.3f} |")
    print(f"crops / whole: {ratio:.2f}x the images per second, {c['seconds'] / max(w['seconds'], 1e-9):.2f}x the "
          f"time, val mAP50 {c['final']['mAP50'] - w['final']['mAP50']:+.3f}")
    if args.json:
        print(json.dumps({"whole": w, "crop": c, "images_per_s_ratio": round(ratio, 3)}))


if __name__ == "__main__":
    main()
