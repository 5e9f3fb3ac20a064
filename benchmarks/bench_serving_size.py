"""Benchmark: what the inference size costs, end to end, on the frames the detector is served.

The shipped model through :func:`~zebra_sim_ros.detection.predict.detect` (letterbox to the next multiple of 32,
forward, NMS, boxes back to the frame) on one frame of ``--frame`` WxH (a rendered zebra scene when ``--image`` is
given, else noise), batch 1, at each ``--sizes``, interleaved in one run with the same thread count; median ms.

    python benchmarks/bench_serving_size.py --image out/heldout/x/images/train/a.jpg --sizes 640 960 [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time

import cv2
import numpy as np
import torch
from numpy.typing import NDArray

from zebra_sim_ros.cli import size_arg
from zebra_sim_ros.detection.checkpoint import load_model
from zebra_sim_ros.detection.predict import detect


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--image", default="", help="an RGB frame to detect on (default: noise of --frame)")
    ap.add_argument("--frame", default="640x360", type=size_arg, help="WxH of the noise frame")
    ap.add_argument("--sizes", type=int, nargs="+", default=[640, 960])
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    img: NDArray[np.uint8]
    if args.image:
        bgr = cv2.imread(args.image, cv2.IMREAD_COLOR)
        if bgr is None:
            raise SystemExit(f"--image {args.image!r} is not a readable image")
        img = np.ascontiguousarray(bgr[..., ::-1], dtype=np.uint8)
    else:
        w, h = args.frame
        img = np.random.default_rng(0).integers(0, 256, (h, w, 3), dtype=np.uint8)
    model, _ = load_model(None, "cpu")
    times: dict[int, list[float]] = {s: [] for s in args.sizes}
    for s in args.sizes:  # warm-up
        detect(model, [img], s)
    for _ in range(args.repeats):
        for s in args.sizes:
            t0 = time.perf_counter()
            detect(model, [img], s)
            times[s].append((time.perf_counter() - t0) * 1000)
    med = {s: round(statistics.median(v), 1) for s, v in times.items()}
    base = args.sizes[0]
    result = {"machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
              "threads": args.threads, "frame": list(img.shape[1::-1]), "median_ms": med,
              "ratio_to_first": {s: round(med[s] / med[base], 2) for s in args.sizes}}
    if args.json:
        print(json.dumps(result))
        return
    for s in args.sizes:
        print(f"imgsz {s:5d}: {med[s]:7.1f} ms per frame ({result['ratio_to_first'][s]:.2f}x imgsz {base})")


if __name__ == "__main__":
    main()
