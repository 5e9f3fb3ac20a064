"""Benchmark: how well and how fast the locator places boxes on the map (``geometry.locate.locate_boxes``).

Renders ``--steps`` steps of the default world (the placer's defaults, three cameras, ``--size``, the camera node's
photographic sensor), takes every
labelled zebra's visible box of at least ``--min-pixels`` pixels as a perfect detection, places it with the
rendered depth and the camera's pose, and compares the point with the zebra's own 3D box centre (``box3d_map``):
the distance (3D and on the ground), by the camera's distance to the zebra. Also the milliseconds per frame of the
placing against the milliseconds of that frame's render, measured in the same run. With ``--detector``, the
shipped weights' boxes (conf 0.25, as the node serves them) are placed as well, each against the nearest placed
zebra's box centre on the map (the placer's ``zebra_sim/zebras``): how far the whole chain, detector included,
puts an animal from where it stands; in a herd packed a metre or two apart the nearest zebra flatters a misplaced
box, so each box that overlaps a labelled zebra (IoU 0.5 or more, its visible box) is also measured against that
zebra's own 3D box. With ``--ground``, the same boxes are also placed without depth (``locate_on_ground``, the
locator's ``place_by: ground``), on the ground (x, y) against the zebra's box centre: on one level plane per step at
the terrain's height under the placement rectangle's centre (what a map of the site gives) with the default centre
height, and on the level of each zebra's own centre (its ground and height known exactly: the best a ground model
can do).

    python benchmarks/bench_locate.py [--steps 3] [--size 1280x720] [--strategy S] [--detector] [--ground] [--json]
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
from bench_census import box_owners, detected_zebras, rendered_cameras, shipped_detector  # the same render loop

from zebra_sim_ros.geometry.locate import CENTRE_HEIGHT_M, locate_boxes, locate_on_ground
from zebra_sim_ros.placement.config import PlacerConfig
from zebra_sim_ros.world.world import load_world


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=3)
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--min-pixels", type=int, default=150)
    ap.add_argument("--detector", action="store_true", help="also place the shipped detector's boxes")
    ap.add_argument("--strategy", help="the placer's camera strategy (default: its default)")
    ap.add_argument("--ground", action="store_true", help="also place the boxes without depth, on the ground")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    pc = PlacerConfig()
    terrain = load_world(pc.world, pc.terrain_prim, pc.world_seed).terrain if args.ground else None
    by_ground: dict[str, list[float]] = {"site plane": [], "each zebra's level": []}
    model = shipped_detector() if args.detector else None
    err3d: list[float] = []
    err_ground: list[float] = []
    ranges: list[float] = []
    render_ms: list[float] = []
    locate_ms: list[float] = []
    det_err: list[float] = []
    det_own: list[float] = []
    det_counts = {"placed": 0, "unplaced": 0}
    for r in rendered_cameras(args.size, args.steps, strategy=args.strategy):
        render_ms.append(r.render_ms)
        position, orientation = np.array(r.cam.position), np.array(r.cam.orientation_xyzw)
        zebras = [z for z in r.frame.labels.kept if z.visible_pixels >= args.min_pixels]
        boxes = np.array([z.box_visible for z in zebras], np.float64).reshape(-1, 4)
        t0 = time.perf_counter()
        got = locate_boxes(boxes, r.frame.view.depth, r.k, position, orientation)
        locate_ms.append((time.perf_counter() - t0) * 1e3)
        centres = np.array([z.box3d_map.center for z in zebras], np.float64).reshape(-1, 3)
        ok = got.valid
        d = got.points[ok] - centres[ok]
        err3d += np.linalg.norm(d, axis=1).tolist()
        err_ground += np.linalg.norm(d[:, :2], axis=1).tolist()
        if terrain is not None and len(boxes):
            site = float(terrain.height_at(*r.scene.rectangle_center))
            under = terrain.height_at(centres[:, 0], centres[:, 1])
            for key, z, c in (("site plane", site, CENTRE_HEIGHT_M),
                              ("each zebra's level", under, centres[:, 2] - under)):
                flat = locate_on_ground(boxes, r.k, position, orientation, z, c)
                by_ground[key] += np.where(flat.valid, np.linalg.norm(flat.points[:, :2] - centres[:, :2], axis=1),
                                           np.inf).tolist()
        ranges += np.linalg.norm(centres[ok] - position, axis=1).tolist()
        if model is not None:
            every = np.array([a.box.center for a in r.scene.zebras if a.species == "zebra"],
                             np.float64).reshape(-1, 3)  # every placed zebra, seen or not
            found = detected_zebras(model, r.frame.view.rgb)
            placed = locate_boxes(found[:, :4], r.frame.view.depth, r.k, position, orientation)
            det_counts["placed"] += int(placed.valid.sum())
            det_counts["unplaced"] += int((~placed.valid).sum())
            if len(every):
                gaps = np.linalg.norm(placed.points[placed.valid][:, None] - every[None], axis=2)
                det_err += gaps.min(axis=1).tolist()
            seen = r.frame.labels.zebras  # kept or not: each with its visible box and its own 3D box
            owner = box_owners(found[:, :4], seen)
            for i in np.flatnonzero(placed.valid & (owner >= 0)):
                own = np.array(seen[int(owner[i])].box3d_map.center, np.float64)
                det_own.append(float(np.linalg.norm(placed.points[i] - own)))
    e3, eg, rg = np.array(err3d), np.array(err_ground), np.array(ranges)
    out: dict[str, Any] = {
        "date": time.strftime("%Y-%m-%d"), "machine": f"{platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} cores", "steps": args.steps, "size": args.size, "strategy": args.strategy or "default",
        "zebras": len(e3),
        "range_m": [round(float(np.percentile(rg, q)), 1) for q in (5, 50, 95)] if len(rg) else [],
        "error_3d_m": {f"p{q}": round(float(np.percentile(e3, q)), 3) for q in (50, 90, 99)} if len(e3) else {},
        "error_ground_m": {f"p{q}": round(float(np.percentile(eg, q)), 3) for q in (50, 90, 99)} if len(eg) else {},
        "locate_ms_per_frame": round(statistics.median(locate_ms), 2),
        "render_ms_per_frame": round(statistics.median(render_ms), 1),
        "locate_over_render": round(statistics.median(a / b for a, b in zip(locate_ms, render_ms, strict=True)), 4)}
    if det_err:
        de = np.array(det_err)
        out["detector"] = {**det_counts, "nearest_zebra_m": {f"p{q}": round(float(np.percentile(de, q)), 3)
                                                             for q in (50, 90, 99)},
                           "within_0.5_m": round(float(np.mean(de <= 0.5)), 3),
                           "within_1_m": round(float(np.mean(de <= 1.0)), 3)}
        if det_own:
            do = np.array(det_own)
            out["detector"]["own_zebra"] = {"boxes": len(do), **{f"p{q}_m": round(float(np.percentile(do, q)), 3)
                                                                 for q in (50, 90, 99)},
                                            "within_1_m": round(float(np.mean(do <= 1.0)), 3)}
    if terrain is not None:
        out["without_depth_ground_m"] = {
            key: {"boxes": len(v), "unplaced": int(np.sum(~np.isfinite(v))),
                  **{f"p{q}": round(float(np.percentile(v, q)), 3) for q in (50, 90, 99)},
                  "within_1_m": round(float(np.mean(np.array(v) <= 1.0)), 3)} for key, v in by_ground.items() if v}
    if len(rg):
        near = rg <= np.median(rg)
        out["error_3d_m_by_range"] = {"near half": round(float(np.median(e3[near])), 3),
                                      "far half": round(float(np.median(e3[~near])), 3)}
    print(json.dumps(out, indent=1) if args.json else "\n".join(f"{k}: {v}" for k, v in out.items()))


if __name__ == "__main__":
    main()
