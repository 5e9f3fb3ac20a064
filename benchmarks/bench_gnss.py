"""Benchmark: what the drones' GNSS fixes cost the placer per step, white or wandering, against the step itself.

Scenes come from the placer's own core (``Placer.scene``, the default world and its three drones, seeded). Per
time constant (``--taus``, in steps; 0 = white): the median over ``--steps`` consecutive steps of the fixes of
the scene's cameras (``NavNoise.fixes``: the error by its recursion, one draw a step, and the conversion to
latitude, longitude and height), the time of the first step computed alone (``start_step``: the weighted sum of
up to 28 time constants of draws, paid once), and each as a ratio to the median ``Placer.scene`` of the same run.

    python benchmarks/bench_gnss.py [--taus 0 60 600 3600] [--steps 50] [--start 100000] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time

from zebra_sim_ros.placement.config import PlacerConfig
from zebra_sim_ros.placement.placer import Placer
from zebra_sim_ros.world.world import load_world
from zebra_sim_ros.zebra.asset import load_library


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--taus", type=float, nargs="+", default=[0.0, 60.0, 600.0, 3600.0],
                    help="time constants in steps (0: white)")
    ap.add_argument("--steps", type=int, default=50, help="consecutive steps timed per time constant")
    ap.add_argument("--start", type=int, default=100_000, help="the first step, computed alone")
    ap.add_argument("--json", action="store_true", help="print the rows as JSON")
    args = ap.parse_args()
    if args.steps < 2:
        ap.error(f"--steps {args.steps}: want 2 or more (the first is timed alone)")

    cfg = PlacerConfig.from_params({"seed": 3})
    placer = Placer(cfg, load_world(cfg.world, cfg.terrain_prim, cfg.world_seed), load_library())
    scenes, scene_s = [], []
    for k in range(args.start, args.start + args.steps):
        t0 = time.perf_counter()
        scenes.append(placer.scene(k))
        scene_s.append(time.perf_counter() - t0)
    step_s = statistics.median(scene_s)
    rows = []
    for tau in args.taus:
        noise = PlacerConfig.from_params({"fix_sigma_m": 2.5, "fix_vertical_sigma_m": 5.0,
                                          "fix_correlation_s": tau}).gnss_noise()
        times = []
        for scene in scenes:
            assert scene.datum is not None
            t0 = time.perf_counter()
            noise.fixes([c.position for c in scene.cameras], scene.datum, scene.seed, scene.step)
            times.append(time.perf_counter() - t0)
        seq = statistics.median(times[1:])
        rows.append({"tau_steps": tau, "first_step_alone_ms": times[0] * 1e3, "per_step_ms": seq * 1e3,
                     "per_step_of_scene": seq / step_s, "first_of_scene": times[0] / step_s})
    print(f"# {time.strftime('%Y-%m-%d')} {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs; "
          f"Placer.scene median {step_s * 1e3:.1f} ms over {args.steps} steps")
    if args.json:
        print(json.dumps(rows, indent=1))
        return 0
    print("| time constant (steps) | fixes per step (median) | of a placer step | first step alone | of a step |")
    print("| --- | --- | --- | --- | --- |")
    for r in rows:
        print(f"| {r['tau_steps']:g} | {r['per_step_ms']:.3f} ms | {r['per_step_of_scene']:.4f} | "
              f"{r['first_step_alone_ms']:.1f} ms | {r['first_of_scene']:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
