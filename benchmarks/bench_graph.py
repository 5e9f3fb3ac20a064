"""Benchmark: the whole graph (``zebra-sim up``) at 1280x720 on this machine: steps and frames per second, the
median time of each stage per step and the end-to-end latency from scene to detections.

Runs ``zebra-sim up --frames N`` (a process per camera and five more over DDS on a private domain, lockstep,
recorder and scorer on)
and, in the same run, the in-process pipeline (``zebra-sim generate``: place, render as many views, label, write,
no DDS, no detector) on the same world, so the graph's cost can be read as a ratio of the plain pipeline's. With
``--drones 1 3`` both run once per count of cameras (``up --drones``, the placer's ``num_cameras``); with
``--bag-images raw jpeg`` the graph runs once per value too (``up --bag-images``), and each run says how many MB of
bag a step wrote.

    python benchmarks/bench_graph.py [--frames 20] [--drones 3] [--bag-images raw] [--size 1280x720]
        [--detect-scale 0] [--json]
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
from zebra_sim_ros.graph.spec import BAG_NAME


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=20, help="steps of the graph (three images each)")
    ap.add_argument("--size", default="1280x720", type=size_arg, help="camera size WxH, px")
    ap.add_argument("--world", default="savanna")
    ap.add_argument("--detect-scale", default="0",
                    help="up's --detect-scale (detector size over the cameras'; 0: the checkpoint's rule)")
    ap.add_argument("--drones", type=int, nargs="+", default=[3], help="up's --drones, one graph run per count")
    ap.add_argument("--bag-images", nargs="+", default=["raw"], help="up's --bag-images, one graph run per value "
                    "(and per --drones count)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    w, h = args.size
    size = f"{w}x{h}"
    root = Path(tempfile.mkdtemp(prefix="bench_graph_"))
    try:
        env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
        domain = str(150 + os.getpid() % 50)
        runs = {}
        for n in args.drones:
            for kind in args.bag_images:
                out = root / f"up{n}_{kind}"
                run = subprocess.run([sys.executable, "-m", "zebra_sim_ros.cli", "up", "--frames", str(args.frames),
                                      "--drones", str(n), "--bag-images", kind, "--size", size, "--world", args.world,
                                      "--out", str(out), "--domain-id", domain, "--detect-scale", args.detect_scale,
                                      "--json"], env=env, capture_output=True, text=True, timeout=3600)
                if run.returncode != 0:
                    raise SystemExit(f"zebra-sim up --drones {n} --bag-images {kind} failed ({run.returncode}):\n"
                                     f"{run.stdout[-3000:]}\n{run.stderr[-2000:]}")
                runs[n, kind] = json.loads(run.stdout.strip().splitlines()[-1])
                runs[n, kind]["bag_mb"] = (out / BAG_NAME).stat().st_size / 1e6
        gens = {n: generate(GenerateConfig(out=str(root / f"gen{n}"), frames=n * args.frames, strategy="far",
                                           worlds=(args.world,), width=w, height=h, workers=1, depth="none",
                                           placer={"num_cameras": n}), progress=lambda *a: None)
                for n in args.drones}  # the same views per placement as the graph's
        result = {
            "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, {platform.platform()}",
            "size": size, "detect_imgsz": next(iter(runs.values()))["detect_imgsz"],
            "graphs": [{"drones": n, "bag_images": kind, "steps": up["steps"], "seconds": up["seconds"],
                        "steps_per_s": up["steps_per_s"], "frames_per_s": up["frames_per_s"],
                        "ready_s": up["ready_s"], "median_ms": up["median_ms"], "scores": up["scores"]["all"],
                        "bag_mb_per_step": round(up["bag_mb"] / max(up["steps"], 1), 2),
                        "pipeline_frames_per_s": gens[n]["frames_per_s"],
                        "graph_over_pipeline_fps": round(up["frames_per_s"] / gens[n]["frames_per_s"], 3)}
                       for (n, kind), up in runs.items()],
        }
    finally:
        shutil.rmtree(root, ignore_errors=True)
    if args.json:
        print(json.dumps(result))
        return
    print(f"machine: {result['machine']}")
    for g in result["graphs"]:
        print(f"graph of {g['drones']} drone(s) at {size}, bag images {g['bag_images']}, detector at "
              f"{result['detect_imgsz']}: {g['bag_mb_per_step']} MB of bag per step; {g['steps']} steps in "
              f"{g['seconds']} s: {g['steps_per_s']} steps/s, {g['frames_per_s']} frames/s (ready after "
              f"{g['ready_s']} s); in-process pipeline of as many views (no DDS, no detector): "
              f"{g['pipeline_frames_per_s']} frames/s; graph / pipeline = {g['graph_over_pipeline_fps']}")
        print(f"  median per step (ms): {g['median_ms']}")
        print(f"  detector vs live ground truth: {g['scores']}")


if __name__ == "__main__":
    main()
