"""Benchmark: pose 250 zebras for one frame (vertices, joints, keypoints, oriented boxes).

Compares, in the same run, posing from the baked cache (what the placer and cameras do) against
skinning the same 250 zebras from scratch with linear-blend skinning. Prints medians and the ratio;
with --json, one summary line last.

    python benchmarks/bench_pose.py [--zebras 250] [--repeats 30] [--json]
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import time

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.geometry.rotations import euler_zyx, rigid, rot_y, rot_z
from zebra_sim_ros.zebra.animation import CLIPS
from zebra_sim_ros.zebra.asset import ZebraLibrary, load_library
from zebra_sim_ros.zebra.mesh import ZebraMesh, build_mesh
from zebra_sim_ros.zebra.skeleton import MORPHS, bind_positions, forward_kinematics
from zebra_sim_ros.zebra.skinning import skin, skinning_matrices

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


def _pose_from_scratch(lib: ZebraLibrary, meshes: dict[str, ZebraMesh], binds: dict[str, FloatArray],
                       morph: IntArray, frame: IntArray, scale: FloatArray, rot: FloatArray, t: FloatArray) -> None:
    """The cache's work done from scratch: forward kinematics and skinning of each zebra's frame, then its box."""
    clip_of = np.searchsorted(lib.clip_start, frame, side="right") - 1
    for i in range(len(morph)):
        clip = CLIPS[int(clip_of[i])]
        pose = clip.pose(int(frame[i] - lib.clip_start[clip_of[i]]))
        name = lib.morphs[int(morph[i])]
        ang = np.radians(pose.angles)
        g = forward_kinematics(binds[name], euler_zyx(ang[:, 0], ang[:, 1], ang[:, 2]),
                               rigid(rot_y(np.radians(pose.root_pitch)), np.zeros(3)))
        msh = meshes[name]
        v = skin(msh.vertices, msh.joint_indices, msh.joint_weights, skinning_matrices(g, binds[name]))
        v = (v * scale[i]) @ rot[i].T + t[i]
        v.min(axis=0), v.max(axis=0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--zebras", type=int, default=250)
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()

    lib = load_library()
    rng = np.random.default_rng(args.seed)
    n = args.zebras
    # Warm the page cache of the memory-mapped arrays once, as a long-running node would be.
    for key in ("vertices_lod0", "joints", "keypoints", "boxes"):
        np.asarray(lib._a[key]).sum()

    cached, lbs = [], []
    meshes = {name: build_mesh(m, 0) for name, m in MORPHS.items()}
    binds = {name: bind_positions(m) for name, m in MORPHS.items()}
    for _ in range(args.repeats):
        morph = rng.integers(0, len(lib.morphs), n)
        frame = rng.integers(0, lib.n_frames, n)
        scale = rng.uniform(0.4, 1.0, n)
        rot = rot_z(rng.uniform(-np.pi, np.pi, n))
        t = np.column_stack([rng.uniform(-60, 60, (n, 2)), rng.uniform(0, 5, n)])

        t0 = time.perf_counter()
        posed = lib.pose(morph, frame, scale, rot, t)
        cached.append(time.perf_counter() - t0)
        assert posed.vertices.shape[0] == n

        t0 = time.perf_counter()
        _pose_from_scratch(lib, meshes, binds, morph, frame, scale, rot, t)
        lbs.append(time.perf_counter() - t0)

    med_cached = statistics.median(cached) * 1000
    med_lbs = statistics.median(lbs) * 1000
    summary = {
        "benchmark": "pose_zebras",
        "zebras": n,
        "repeats": args.repeats,
        "vertices_per_zebra": int(lib.bind_vertices(0).shape[0]),
        "cached_ms_median": round(med_cached, 2),
        "cached_ms_p90": round(float(np.percentile(cached, 90)) * 1000, 2),
        "skinning_ms_median": round(med_lbs, 2),
        "speedup_cached_over_skinning": round(med_lbs / med_cached, 1),
        "machine": f"{platform.machine()} {platform.processor() or ''} cpus={__import__('os').cpu_count()}".strip(),
    }
    print(f"pose {n} zebras (cache, vertices+joints+keypoints+boxes): median {med_cached:.1f} ms")
    print(f"pose {n} zebras (forward kinematics + skinning from scratch): median {med_lbs:.1f} ms")
    print(f"cache is {med_lbs / med_cached:.1f}x faster")
    if args.json:
        print(json.dumps(summary))


if __name__ == "__main__":
    main()
