"""Benchmark: frames per hour of ``zebra-sim generate`` at 1280x720 with labels (the paper's 36K frames goal).

Runs the same generation (SF: far and closeby, savanna, paper's randomisation) with one worker and with two
workers in the same run, each into a fresh folder, and reports frames/s, frames/hour, the hours the paper's
36K frames would take, and the time split between placing, rendering, labelling and writing (summed over
workers). The first frames include start-up (world, renderer, coats), as a real run does.

    python benchmarks/bench_generate.py [--frames 90] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import tempfile
from pathlib import Path

from zebra_sim_ros.dataset.generate import GenerateConfig, generate


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=90)
    ap.add_argument("--world", default="savanna")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    results = {}
    root = Path(tempfile.mkdtemp(prefix="bench_generate_"))
    try:
        for workers in (1, 2):
            cfg = GenerateConfig(out=str(root / f"w{workers}"), frames=args.frames, strategy="both",
                                 worlds=(args.world,), workers=workers)
            s = generate(cfg, progress=lambda *a: None)
            results[f"workers_{workers}"] = {
                "frames": s["frames_written"], "seconds": s["seconds"], "frames_per_s": s["frames_per_s"],
                "frames_per_hour": round(s["frames_per_s"] * 3600),
                "hours_for_36k": round(36000 / s["frames_per_s"] / 3600, 2),
                "time_split_s": s["time_split_s"], "zebras_labelled": s["zebras_labelled"]}
            print(f"{workers} worker(s): {s['frames_per_s']:.2f} frames/s ({s['frames_per_s'] * 3600:.0f}/h, "
                  f"36K frames in {36000 / s['frames_per_s'] / 3600:.1f} h); split {s['time_split_s']}")
    finally:
        shutil.rmtree(root, ignore_errors=True)
    ratio = results["workers_2"]["frames_per_s"] / results["workers_1"]["frames_per_s"]
    print(f"two workers / one worker: {ratio:.2f}x")
    if args.json:
        print(json.dumps({"benchmark": "generate", "world": args.world, "resolution": "1280x720",
                          "machine": f"{platform.machine()} cpus={os.cpu_count()}", "results": results,
                          "ratio_2_over_1": round(ratio, 2)}))


if __name__ == "__main__":
    main()
