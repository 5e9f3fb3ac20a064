"""Benchmark: what a camera's lens distortion costs, and what undoing it is worth to the locator.

Renders ``--steps`` steps of the default world (the placer's defaults, three cameras, ``--size``) twice per step in
the same run, alternating which goes first: with an ideal pinhole and through ``--lens`` (plumb_bob k1 k2 p1 p2 k3;
default a wide-angle drone camera's barrel distortion). Per step it times the render of the three views and their
labels, and reports the medians and the median ratio lens / pinhole (the first step, which bakes coats, left out).
It also times the canvas a camera model needs once (the maps, made at the renderer's start and the labeller's first
frame of that model) and places every labelled zebra's visible box of at least ``--min-pixels`` pixels with the
rendered depth and the camera's pose, with and without undoing the lens, against the zebra's own 3D box centre.

    python benchmarks/bench_lens.py [--steps 3] [--size 1280x720] [--lens -0.3 0.1 0.002 -0.001 -0.01] [--json]
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

from zebra_sim_ros.cli.common import parse_size
from zebra_sim_ros.geometry.camera import PinholeCamera
from zebra_sim_ros.geometry.lens import Distortion, lens_canvas
from zebra_sim_ros.geometry.locate import locate_boxes
from zebra_sim_ros.placement.config import PlacerConfig
from zebra_sim_ros.placement.placer import Placer
from zebra_sim_ros.rendering.config import add_lens_option, parse_lens
from zebra_sim_ros.rendering.renderer import RenderOptions
from zebra_sim_ros.simulation import Simulator
from zebra_sim_ros.world.world import load_world
from zebra_sim_ros.zebra.asset import load_library


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=3)
    ap.add_argument("--size", default="1280x720")
    add_lens_option(ap)
    ap.set_defaults(lens=[-0.3, 0.1, 0.002, -0.001, -0.01])
    ap.add_argument("--min-pixels", type=int, default=150)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    width, height = parse_size(args.size)
    lens = parse_lens(args.lens)
    if lens.none:
        raise SystemExit("--lens: give a lens with some distortion to compare with the pinhole")
    pc = PlacerConfig.from_params({"camera_width": width, "camera_height": height})
    world = load_world(pc.world, pc.terrain_prim, pc.world_seed)
    library = load_library()
    placer = Placer(pc, world, library)
    cam = PinholeCamera(width, height, pc.camera_hfov_deg, lens)
    lens_canvas.cache_clear()
    t0 = time.perf_counter()
    canvas = lens_canvas(width, height, cam.fx, lens)
    canvas_s = time.perf_counter() - t0
    sims = {name: Simulator(world, library, RenderOptions(width=width, height=height, hfov_deg=pc.camera_hfov_deg,
                                                          distortion=d))
            for name, d in (("pinhole", Distortion()), ("lens", lens))}
    times: dict[str, dict[str, list[float]]] = {n: {"render": [], "label": []} for n in sims}
    errors: dict[str, list[float]] = {"undone": [], "not undone": [], "pinhole": []}
    try:
        for step in range(args.steps):
            scene = placer.scene(step)
            for name in (("pinhole", "lens") if step % 2 == 0 else ("lens", "pinhole")):
                sim = sims[name]
                t1 = time.perf_counter()
                views = sim.render(scene)
                t2 = time.perf_counter()
                labels = [sim.labeller.label(scene, v.name, v.instances, v.depth) for v in views]
                t3 = time.perf_counter()
                if step > 0:  # the first step builds coats and the labeller's canvas: not a frame's cost
                    times[name]["render"].append((t2 - t1) * 1e3)
                    times[name]["label"].append((t3 - t2) * 1e3)
                for v, lab, c in zip(views, labels, scene.cameras, strict=True):
                    zebras = [z for z in lab.kept if z.visible_pixels >= args.min_pixels]
                    boxes = np.array([z.box_visible for z in zebras], np.float64).reshape(-1, 4)
                    centres = np.array([z.box3d_map.center for z in zebras], np.float64).reshape(-1, 3)
                    where = (np.array(c.position), np.array(c.orientation_xyzw))
                    runs = ((("undone", Distortion.from_d(v.D)), ("not undone", None)) if name == "lens"
                            else (("pinhole", None),))
                    for key, undo in runs:
                        got = locate_boxes(boxes, v.depth, v.K, *where, distortion=undo)
                        errors[key] += np.linalg.norm(got.points[got.valid] - centres[got.valid], axis=1).tolist()
    finally:
        for sim in sims.values():
            sim.release()
    frame = {n: [r + lab for r, lab in zip(t["render"], t["label"], strict=True)] for n, t in times.items()}
    out: dict[str, Any] = {
        "date": time.strftime("%Y-%m-%d"), "machine": f"{platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} cores", "steps": args.steps, "size": args.size, "lens": list(lens.coefficients),
        "canvas": f"{canvas.canvas_width}x{canvas.canvas_height}", "canvas_seconds": round(canvas_s, 3),
        **{f"{n}_ms_per_step": {k: round(statistics.median(v), 1) for k, v in t.items()} for n, t in times.items()},
        "lens_over_pinhole": round(statistics.median(a / b for a, b in zip(frame["lens"], frame["pinhole"],
                                                                           strict=True)), 3),
        "locate_error_m": {k: {"boxes": len(v), "p50": round(float(np.percentile(v, 50)), 3),
                               "p90": round(float(np.percentile(v, 90)), 3)} for k, v in errors.items() if v}}
    print(json.dumps(out, indent=1) if args.json else "\n".join(f"{k}: {v}" for k, v in out.items()))


if __name__ == "__main__":
    main()
