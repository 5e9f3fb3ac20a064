"""Benchmark: what the crop verifier costs the detector per image, as the node runs it (conf 0.25).

    python benchmarks/bench_verifier.py FOLDER [FOLDER ...] [--imgsz 256] [--images 60] [--verifier shipped]

For the first ``--images`` images of each folder (sorted), ``detect`` runs one image at a time, alternately
without and with the verifier, three times each; it prints per folder the median milliseconds per image of both,
their ratio (measured in the same run, so machines' speeds cancel) and how many boxes per image the verifier
looked at. Then the verifier's own time per image it judged boxes in (``zebra_probability`` on them; boxes of every
class, where ``detect`` rescores the zebra boxes only: the same for a one-class detector), as served
(batch norms folded, channels-last: ``load_verifier``'s default) and unfused (as trained), alternately, five times
each, medians and their ratio. ``--imgsz 0``: the checkpoint's rule (drone frames), 256: how photographs are
served.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from pathlib import Path

import numpy as np
import torch

from zebra_sim_ros.detection.checkpoint import load_model
from zebra_sim_ros.detection.data import IMAGE_EXTS
from zebra_sim_ros.detection.predict import detect
from zebra_sim_ros.detection.verify import judged_side, load_verifier, read_rgb, zebra_probability


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="+", type=Path)
    ap.add_argument("--imgsz", type=int, default=256, help="inference long side (0: the checkpoint's rule)")
    ap.add_argument("--images", type=int, default=60, help="images per folder")
    ap.add_argument("--verifier", default="shipped")
    ap.add_argument("--conf", type=float, default=0.25)
    args = ap.parse_args()
    if args.images < 1:
        raise SystemExit(f"--images must be 1 or more, got {args.images}")
    model, _ = load_model(None)
    net, _ = load_verifier(args.verifier, "cpu", "--verifier")
    unfused, _ = load_verifier(args.verifier, "cpu", "--verifier", fuse=False)
    print(f"bench_verifier.py {time.strftime('%Y-%m-%d')}, {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} cores, torch threads {torch.get_num_threads()}; conf {args.conf}, imgsz "
          f"{args.imgsz or 'rule'}")
    print("| folder | images | detector alone, ms/img (median) | with the verifier, ms/img | ratio | boxes looked at "
          "per image | the verifier's own ms/img: served / unfused (ratio) |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for folder in args.folders:
        files = sorted(p for p in folder.rglob("*") if p.suffix.lower() in IMAGE_EXTS)[: args.images]
        if not files:
            raise SystemExit(f"{folder}: no images")
        images = [read_rgb(f) for f in files]
        plain: list[float] = []
        verified: list[float] = []
        looked = 0
        judged: list[tuple[np.ndarray, np.ndarray]] = []  # (image, the boxes the verifier judged in it)
        detect(model, images[:1], args.imgsz or None, args.conf, verifier=net)  # warm-up
        for rep in range(3):
            for img in images:
                for v, times in ((None, plain), (net, verified)):
                    t0 = time.perf_counter()
                    d = detect(model, [img], args.imgsz or None, args.conf, verifier=v)[0]
                    times.append(1000 * (time.perf_counter() - t0))
                    if v is None and rep == 0 and len(d):
                        big = d[(d[:, 2:4] - d[:, 0:2]).max(1) >= judged_side(net.cfg, img.shape)]
                        looked += len(big)
                        if len(big):
                            judged.append((img, big))
        own: dict[str, list[float]] = {"served": [], "unfused": []}
        for _ in range(5):
            for img_, big in judged:
                for name, v in (("served", net), ("unfused", unfused)):
                    t0 = time.perf_counter()
                    zebra_probability(v, img_, big)
                    own[name].append(1000 * (time.perf_counter() - t0))
        a, b = statistics.median(plain), statistics.median(verified)
        s, u = (statistics.median(own[k]) if own[k] else 0.0 for k in ("served", "unfused"))
        print(f"| {folder} | {len(images)} | {a:.1f} | {b:.1f} | {b / a:.2f} | {looked / len(images):.2f} | "
              f"{s:.2f} / {u:.2f} ({s / u if u else float('nan'):.2f}) |")


if __name__ == "__main__":
    main()
