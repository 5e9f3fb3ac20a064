"""Benchmark: render the three drone views of a 250-zebra scene with vegetation.

For each resolution (1280x720, 1920x1080, 640x640) renders the same steps (250 zebras asked for, the
placer's far cameras) and reports the median seconds per three-camera frame (RGB + depth + instance mask
read back), the split between preparation, shadow pass, drawing and read-back, and the ratio of each
resolution to 1280x720 measured in the same run. Coats are baked before timing (a running camera bakes
each individual's coat once, the first time it is seen).

    python benchmarks/bench_render.py [--world savanna] [--steps 8] [--json]
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

from zebra_sim_ros.placement.config import PlacerConfig
from zebra_sim_ros.placement.placer import Placer
from zebra_sim_ros.rendering.renderer import Renderer, RenderOptions
from zebra_sim_ros.rendering.views import views_from_scene, zebras_from_scene
from zebra_sim_ros.world.world import generate_world
from zebra_sim_ros.zebra.asset import load_library

SIZES = ((1280, 720), (1920, 1080), (640, 640))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", default="savanna")
    ap.add_argument("--strategy", default="far")
    ap.add_argument("--steps", type=int, default=8)
    ap.add_argument("--no-shadows", action="store_true")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    world = generate_world(args.world, 0)
    lib = load_library()
    placer = Placer(PlacerConfig.from_params({"count_min": 250, "count_max": 250, "strategy": args.strategy,
                                              "night_fraction": 0.0}), world, lib)
    scenes = [placer.scene(k * 3) for k in range(args.steps)]
    results: dict[str, dict[str, Any]] = {}
    info: dict[str, str] = {}
    for w, h in SIZES:
        r = Renderer(world, lib, RenderOptions(width=w, height=h, shadows=not args.no_shadows))
        info = r.info
        per_frame: list[float] = []
        parts: dict[str, list[float]] = {"prepare": [], "shadow": [], "draw": [], "read": []}
        zebras_drawn = []
        for i, sc in enumerate(scenes):
            zs, light, views = zebras_from_scene(sc, lib), sc.lighting, views_from_scene(sc)
            r.render(zs, light, views[:1])  # warm: bakes this step's coats, uploads buffers
            t0 = time.perf_counter()
            outs = r.render(zs, light, views)
            per_frame.append(time.perf_counter() - t0)
            for k in parts:
                parts[k].append(sum(o.timings[k] for o in outs))
            zebras_drawn.append(sum(o.timings["zebras_lod0"] + o.timings["zebras_lod1"] for o in outs) / 3)
            del i
        r.release()
        results[f"{w}x{h}"] = {
            "s_per_3cam_frame_median": round(statistics.median(per_frame), 3),
            "split_median_s": {k: round(statistics.median(v), 3) for k, v in parts.items()},
            "zebras_drawn_per_view_median": round(statistics.median(zebras_drawn), 1),
        }
    base = results["1280x720"]["s_per_3cam_frame_median"]
    for v in results.values():
        v["ratio_to_1280x720"] = round(v["s_per_3cam_frame_median"] / base, 2)
    summary = {"benchmark": "render_3_views", "world": args.world, "strategy": args.strategy, "steps": args.steps,
               "zebras_requested": 250, "shadows": not args.no_shadows, "renderer": info.get("GL_RENDERER"),
               "device": info.get("device"), "machine": f"{platform.machine()} cpus={os.cpu_count()}",
               "results": results}
    for size, v in results.items():
        print(f"{size}: {v['s_per_3cam_frame_median']:.3f} s per three-camera frame ({v['ratio_to_1280x720']}x), "
              f"split {v['split_median_s']}, zebras drawn per view {v['zebras_drawn_per_view_median']}")
    if args.json:
        print(json.dumps(summary))
    _ = np


if __name__ == "__main__":
    main()
