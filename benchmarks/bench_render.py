"""Benchmark: render the three drone views of a 250-zebra scene with vegetation.

For each resolution (1280x720, 1920x1080, 640x640) renders the same steps (250 zebras asked for, the
placer's far cameras) and reports the median seconds per three-camera frame (RGB + depth + instance mask
read back), the split between preparation, shadow pass, drawing and read-back, and the ratio of each
resolution to 1280x720 measured in the same run. Coats are baked before timing (a running camera bakes
each individual's coat once, the first time it is seen).

    python benchmarks/bench_render.py [--world savanna] [--steps 8] [--json]
    python benchmarks/bench_render.py --looks [--steps 8] [--json]

``--looks`` compares, at 1280x720 in one run over the same scenes, the plain look (flat ground colours, bare
coats, no contact shadows), the photographic look under a clear sky (procedural ground detail, foliage, contact
shadows, coat shading), the same with the scene's weather and randomised look (cloud cover at least 0.6, so the
cloud layer and its shadows are paid for in every frame) and that plus the per-frame camera model
(``rendering.effects.SensorModel``, applied to
each view's RGB on the CPU), with the split per pass and the ratios to plain.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from dataclasses import replace
from typing import Any

import numpy as np

from zebra_sim_ros.placement.config import PlacerConfig
from zebra_sim_ros.placement.placer import Placer
from zebra_sim_ros.rendering.effects import SensorModel
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
    ap.add_argument("--looks", action="store_true", help="plain vs photographic look vs + camera model, 1280x720")
    args = ap.parse_args()
    world = generate_world(args.world, 0)
    lib = load_library()
    placer = Placer(PlacerConfig.from_params({"count_min": 250, "count_max": 250, "strategy": args.strategy,
                                              "night_fraction": 0.0}), world, lib)
    scenes = [placer.scene(k * 3) for k in range(args.steps)]
    if args.looks:
        looks(world, lib, scenes, args)
        return
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


def _timed(r: Renderer, lib: Any, scenes: list[Any], sensor: SensorModel | None,
           weather: bool = False) -> dict[str, Any]:
    """Median seconds per three-camera frame; ``weather``: each scene's look and sky with a cloud cover of at least
    0.6 (so every frame pays for the cloud layer and its shadows)."""
    per_frame: list[float] = []
    parts: dict[str, list[float]] = {"prepare": [], "shadow": [], "draw": [], "read": [], "sensor": []}
    for k, sc in enumerate(scenes):
        zs, light, views = zebras_from_scene(sc, lib), sc.lighting, views_from_scene(sc)
        ground, sky = (sc.ground, replace(sc.weather, cloud_cover=max(sc.weather.cloud_cover, 0.6))) if weather \
            else (None, None)
        r.render(zs, light, views[:1], ground, sky)  # warm
        t0 = time.perf_counter()
        outs = r.render(zs, light, views, ground, sky)
        t1 = time.perf_counter()
        if sensor is not None:
            for j, o in enumerate(outs):
                rng = np.random.default_rng([sc.seed, sc.step, j, 0x5E50])
                o.rgb = sensor.apply(o.rgb, sensor.draw(rng), rng)
        t2 = time.perf_counter()
        per_frame.append(t2 - t0)
        for key in ("prepare", "shadow", "draw", "read"):
            parts[key].append(sum(o.timings[key] for o in outs))
        parts["sensor"].append(t2 - t1)
        del k
    return {"s_per_3cam_frame_median": round(statistics.median(per_frame), 3),
            "split_median_s": {k: round(statistics.median(v), 3) for k, v in parts.items()}}


def looks(world: Any, lib: Any, scenes: list[Any], args: argparse.Namespace) -> None:
    """The ``--looks`` comparison (module docstring)."""
    res: dict[str, dict[str, Any]] = {}
    info: dict[str, str] = {}
    for name, detail, sensor, weather in (("plain", False, None, False), ("photo, clear sky", True, None, False),
                                          ("photo+weather", True, None, True),
                                          ("photo+weather+camera", True, SensorModel(), True)):
        r = Renderer(world, lib, RenderOptions(width=1280, height=720, detail=detail, contact_shadows=detail))
        info = r.info
        res[name] = _timed(r, lib, scenes, sensor, weather)
        r.release()
    base = res["plain"]["s_per_3cam_frame_median"]
    for v in res.values():
        v["ratio_to_plain"] = round(v["s_per_3cam_frame_median"] / base, 2)
    summary = {"benchmark": "render_looks", "world": args.world, "strategy": args.strategy, "steps": args.steps,
               "size": "1280x720", "renderer": info.get("GL_RENDERER"),
               "machine": f"{platform.machine()} cpus={os.cpu_count()}", "results": res}
    for name, v in res.items():
        print(f"{name}: {v['s_per_3cam_frame_median']:.3f} s per three-camera frame ({v['ratio_to_plain']}x plain), "
              f"split {v['split_median_s']}")
    if args.json:
        print(json.dumps(summary))


if __name__ == "__main__":
    main()
