"""Benchmark: the whole graph (``zebra-sim up``) at 1280x720 on this machine: steps and frames per second, the
median time of each stage per step and the end-to-end latency from scene to detections.

Runs ``zebra-sim up --frames N`` (seven processes over DDS on a private domain, lockstep, recorder on) and, in
the same run, the in-process pipeline (``zebra-sim generate``: place, render three views, label, write, no DDS,
no detector) on the same world, so the graph's cost can be read as a ratio of the plain pipeline's.

    python benchmarks/bench_graph.py [--frames 20] [--size 1280x720] [--detect-scale 0] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from zebra_sim_ros.cli import size_arg
from zebra_sim_ros.dataset.generate import GenerateConfig, generate


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=20, help="steps of the graph (three images each)")
    ap.add_argument("--size", default="1280x720", type=size_arg, help="camera size WxH, px")
    ap.add_argument("--world", default="savanna")
    ap.add_argument("--detect-scale", default="0",
                    help="up's --detect-scale (detector size over the cameras'; 0: the checkpoint's rule)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    w, h = args.size
    size = f"{w}x{h}"
    root = Path(tempfile.mkdtemp(prefix="bench_graph_"))
    try:
        env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
        domain = str(150 + os.getpid() % 50)
        run = subprocess.run([sys.executable, "-m", "zebra_sim_ros.cli", "up", "--frames", str(args.frames),
                              "--size", size, "--world", args.world, "--out", str(root / "up"),
                              "--domain-id", domain, "--detect-scale", args.detect_scale,
                              "--json"], env=env, capture_output=True, text=True, timeout=3600)
        if run.returncode != 0:
            raise SystemExit(f"zebra-sim up failed ({run.returncode}):\n{run.stdout[-3000:]}\n{run.stderr[-2000:]}")
        up = json.loads(run.stdout.strip().splitlines()[-1])
        gen = generate(GenerateConfig(out=str(root / "gen"), frames=3 * args.frames, strategy="far",
                                      worlds=(args.world,), width=w, height=h, workers=1, depth="none"),
                       progress=lambda *a: None)
        result = {
            "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, {platform.platform()}",
            "size": size, "detect_imgsz": up["detect_imgsz"], "steps": up["steps"], "frames": up["frames"],
            "graph": {"seconds": up["seconds"], "steps_per_s": up["steps_per_s"], "frames_per_s": up["frames_per_s"],
                      "ready_s": up["ready_s"], "median_ms": up["median_ms"],
                      "scores": up["scores"]["all"]},
            "pipeline_in_process": {"frames_per_s": gen["frames_per_s"], "seconds": gen["seconds"]},
            "graph_over_pipeline_fps": round(up["frames_per_s"] / gen["frames_per_s"], 3),
        }
    finally:
        shutil.rmtree(root, ignore_errors=True)
    if args.json:
        print(json.dumps(result))
        return
    g = result["graph"]
    print(f"machine: {result['machine']}")
    print(f"graph at {size}, detector at {result['detect_imgsz']}: {result['steps']} steps in {g['seconds']} s: "
          f"{g['steps_per_s']} steps/s, "
          f"{g['frames_per_s']} frames/s (ready after {g['ready_s']} s)")
    print(f"median per step (ms): {g['median_ms']}")
    print(f"in-process pipeline (no DDS, no detector): {result['pipeline_in_process']['frames_per_s']} frames/s; "
          f"graph / pipeline = {result['graph_over_pipeline_fps']}")
    print(f"detector vs live ground truth: {g['scores']}")


if __name__ == "__main__":
    main()
