"""Benchmark: what one report of the ``scorer`` node costs, with each frame matched once against matching every
frame of the window again (``score_drones`` on the window, as a bag is scored).

Three cameras' windows are filled with synthetic frames of a default drone frame's density (``--zebras`` labelled
zebras, their boxes 8-40 px, and as many detections jittered by 2 px with random scores; no rendering: the cost
is in the scoring, not in what the boxes show). Per window size, the median of ``--repeats`` reports: the node's
steady state (one new frame per camera since the last report, the rest matched already) and the full scoring of the
same frames; the ratio of the two, measured in the same run; and what of a report is the zebra count
(``count_errors`` over each camera's matched frames and over all, as ``score_drones`` takes it).

    python benchmarks/bench_scorer.py [--windows 100 300] [--zebras 95] [--repeats 5] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from typing import Any

import numpy as np

from zebra_sim_ros.detection.metrics import count_errors
from zebra_sim_ros.detection.scoring import COUNT_CONF, DroneFrames, LiveScores, score_drones
from zebra_sim_ros.messages import Labels

DRONES = ("drone_0", "drone_1", "drone_2")


def labels(sec: int, boxes: np.ndarray) -> Labels:
    return Labels.from_json(json.dumps({
        "schema": "zebra_sim_ros/labels", "version": 1, "stamp": {"sec": sec, "nanosec": 0},
        "zebras": [{"id": i, "box_visible": [float(v) for v in b], "kept": True, "visible_pixels": 900}
                   for i, b in enumerate(boxes)]}))


def add_frame(live: LiveScores, sec: int, zebras: int, rng: np.random.Generator) -> None:
    for d in DRONES:
        xy = rng.uniform(0, 1200, (zebras, 2))
        boxes = np.c_[xy, xy + rng.uniform(8, 40, (zebras, 2))]
        live.add_labels(d, labels(sec, boxes))
        live.add_detections(d, sec * 10**9, np.c_[boxes + rng.normal(0, 2, boxes.shape),
                                                  rng.uniform(0.2, 1.0, zebras)])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--windows", type=int, nargs="+", default=[100, 300])
    ap.add_argument("--zebras", type=int, default=95)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    out: dict[str, Any] = {"date": time.strftime("%Y-%m-%d"), "machine": f"{platform.processor() or platform.machine()}"
                           f", {os.cpu_count()} cores", "zebras_per_frame": args.zebras, "windows": {}}
    for window in args.windows:
        rng = np.random.default_rng(window)
        live = LiveScores(window)
        sec = 0
        for sec in range(window):
            add_frame(live, sec, args.zebras, rng)
        live.scores()  # the window matched once, as the node has when it reaches steady state
        steady, full, count = [], [], []
        for _ in range(args.repeats):
            sec += 1
            add_frame(live, sec, args.zebras, rng)
            t0 = time.perf_counter()
            live.scores()
            steady.append(time.perf_counter() - t0)
            per_camera = [list(frames.values()) for frames in live.matched.values()]
            t0 = time.perf_counter()
            for images in [*per_camera, [x for frames in per_camera for x in frames]]:
                count_errors(images, COUNT_CONF)
            count.append(time.perf_counter() - t0)
            frames = {d: DroneFrames(dict(f.labels), dict(f.detections)) for d, f in live.drones.items()}
            t0 = time.perf_counter()
            score_drones(frames)
            full.append(time.perf_counter() - t0)
        ratio = statistics.median(s / f for s, f in zip(steady, full, strict=True))
        out["windows"][str(window)] = {"steady_ms": round(statistics.median(steady) * 1e3, 1),
                                       "full_ms": round(statistics.median(full) * 1e3, 1),
                                       "steady_over_full": round(ratio, 3),
                                       "count_ms": round(statistics.median(count) * 1e3, 1),
                                       "count_share": round(statistics.median(
                                           c / s for c, s in zip(count, steady, strict=True)), 3)}
    if args.json:
        print(json.dumps(out, indent=1))
        return
    print(f"{out['machine']}; {args.zebras} zebras per frame, three cameras")
    print("| window (frames per camera) | report, each frame matched once (ms) | all matched again (ms) | ratio "
          "| of a report, the count (ms, share) |")
    print("| --- | --- | --- | --- | --- |")
    for w, r in out["windows"].items():
        print(f"| {w} | {r['steady_ms']} | {r['full_ms']} | {r['steady_over_full']} | {r['count_ms']} "
              f"({r['count_share']}) |")


if __name__ == "__main__":
    main()
