"""Benchmark: one placement of 250 zebras with collision checks and ground heights.

Measures, in the same run and on the same draws:
- ``HerdPlacer.place`` (batched separating-axis tests against placed zebras and trees/rocks, slope
  look-up, ground plane fit), with the number of zebras asked for fixed at 250;
- a plain reference that tests one candidate against one box at a time in Python, which must place
  exactly the same zebras at the same spots (a cross-check), and is the ratio's denominator;
- a whole step (placement + three cameras + lighting + scene JSON), as the placer node runs it.

    python benchmarks/bench_place.py [--world savanna] [--repeats 30] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time

import numpy as np

from zebra_sim_ros.geometry.boxes import box_axes
from zebra_sim_ros.placement.config import PlacerConfig
from zebra_sim_ros.placement.herd import HerdPlacer, ZebraPool
from zebra_sim_ros.placement.placer import Placer
from zebra_sim_ros.world.world import generate_world
from zebra_sim_ros.zebra.asset import load_library


def reference_place(hp: HerdPlacer, rng: np.random.Generator, pool: ZebraPool, clip_ids: np.ndarray,
                    attempts: int) -> np.ndarray:
    """One candidate and one box at a time; returns the footprint centres of the placed zebras (K, 2)."""
    d = hp.draw(rng, pool, (250, 250), (0.4, 1.0), (40.0, 120.0), clip_ids, attempts)
    morph = pool.morph[d.ids]
    half = hp._box_half_xy[morph, d.global_frame] * d.scale[:, None]
    off_l = hp._box_center_xy[morph, d.global_frame] * d.scale[:, None]
    axes = box_axes(d.yaw)
    boxes: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = [
        (c, np.array([r, r]), np.eye(2)) for c, r in zip(hp.obstacle_xy, hp.obstacle_radius, strict=True)]
    out = []
    for k in range(len(d.ids)):
        off = off_l[k, 0] * axes[k, 0] + off_l[k, 1] * axes[k, 1]
        for a in range(attempts):
            c = d.candidates[k, a] + off
            if not hp._slope_ok_at(d.candidates[k, a][None])[0]:
                continue
            clear = True
            for c2, e2, a2 in boxes:
                dvec = c2 - c
                for ax in (axes[k, 0], axes[k, 1], a2[0], a2[1]):
                    r1 = half[k, 0] * abs(axes[k, 0] @ ax) + half[k, 1] * abs(axes[k, 1] @ ax)
                    r2 = e2[0] * abs(a2[0] @ ax) + e2[1] * abs(a2[1] @ ax)
                    if abs(dvec @ ax) >= r1 + r2:
                        break
                else:
                    clear = False
                    break
            if clear:
                boxes.append((c, half[k], axes[k]))
                out.append(c)
                break
    return np.array(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", default="savanna")
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--reference-repeats", type=int, default=3)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()

    world = generate_world(args.world, 0)
    lib = load_library()
    cfg = PlacerConfig.from_params({"count_min": 250, "count_max": 250})
    placer = Placer(cfg, world, lib)
    hp, pool, clips = placer.herds, placer.pool, placer.clip_ids
    fast, placed = [], []
    for r in range(args.repeats):
        rng = np.random.default_rng([1, r])
        t0 = time.perf_counter()
        herd = hp.place(rng, pool, (250, 250), (0.4, 1.0), (40.0, 120.0), clips, 100)
        fast.append(time.perf_counter() - t0)
        placed.append(herd.count)
    ref = []
    for r in range(args.reference_repeats):
        t0 = time.perf_counter()
        centres = reference_place(hp, np.random.default_rng([1, r]), pool, clips, 100)
        ref.append(time.perf_counter() - t0)
        herd = hp.place(np.random.default_rng([1, r]), pool, (250, 250), (0.4, 1.0), (40.0, 120.0), clips, 100)
        assert np.allclose(centres, herd.footprint_center), "reference and fast placement disagree"
    steps = []
    for k in range(args.repeats):
        t0 = time.perf_counter()
        placer.scene(k * cfg.camera_rerolls).to_json()  # a new placement every time
        steps.append(time.perf_counter() - t0)
    med, med_ref, med_step = (statistics.median(x) * 1000 for x in (fast, ref, steps))
    summary = {
        "benchmark": "place_250", "world": args.world, "repeats": args.repeats,
        "placed_median": statistics.median(placed), "requested": 250,
        "place_ms_median": round(med, 2), "place_ms_p90": round(float(np.percentile(fast, 90)) * 1000, 2),
        "placements_per_s": round(1000 / med, 1), "reference_ms_median": round(med_ref, 1),
        "speedup_over_reference": round(med_ref / med, 1), "step_ms_median": round(med_step, 2),
        "obstacles": int(len(world.obstacles.radii)),
        "machine": f"{platform.machine()} cpus={os.cpu_count()}",
    }
    print(f"{args.world}: place 250 zebras: median {med:.1f} ms ({1000 / med:.0f} placements/s), "
          f"{statistics.median(placed):.0f} placed; reference {med_ref:.0f} ms ({med_ref / med:.0f}x slower); "
          f"whole step with cameras and JSON {med_step:.1f} ms")
    if args.json:
        print(json.dumps(summary))


if __name__ == "__main__":
    main()
