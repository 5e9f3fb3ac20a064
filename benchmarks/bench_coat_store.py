"""Benchmark: the whole graph (``zebra-sim up``) with each camera baking its own coats, against the cameras sharing
them through the coat store (empty at the start of the run, then filled by an earlier run).

Three arms, in rounds, each ``zebra-sim up --frames N`` on the same world and seed (the same animals, so the same
coats), its config folder a copy of the repository's with the cameras' ``coat_store`` set:

- ``own``: ``coat_store: false``, every camera bakes every coat it sees (the graph before the store);
- ``shared, empty``: ``coat_store: true`` and the store's folder emptied first;
- ``shared, filled``: ``coat_store: true`` right after ``shared, empty``: a second run of the same experiment.

Every run uses a zebra cache of its own in a temporary folder (``ZEBRA_SIM_CACHE``, built before the first round), so
the user's cache and coat store are neither read nor touched.

Prints per arm the median over rounds of the run's seconds, steps per second, the median render time per step,
and the coats baked and read by the three cameras (from their logs); and each shared arm's steps/s over ``own``'s.

    python benchmarks/bench_coat_store.py [--frames 10] [--rounds 2] [--world savanna] [--seed 0] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from zebra_sim_ros.zebra.asset import build_library
from zebra_sim_ros.zebra.coat_store import CoatStore

ARMS = ("own", "shared, empty", "shared, filled")
REPO = Path(__file__).resolve().parents[1]


def _config(root: Path, store: bool) -> Path:
    cfg = root / f"config_{'shared' if store else 'own'}"
    shutil.copytree(REPO / "config", cfg)
    cam = cfg / "camera.yaml"
    text = cam.read_text()
    new = re.sub(r"coat_store: (true|false)", f"coat_store: {'true' if store else 'false'}", text)
    if "coat_store:" not in text:
        raise SystemExit(f"{cam} has no coat_store line")
    cam.write_text(new)
    return cfg


def _coats(logs: Path) -> tuple[int, int]:
    baked = read = 0
    for log in logs.glob("drone_*_camera.log"):
        m = re.findall(r"coats baked (\d+), read from the store (\d+)", log.read_text())
        if not m:
            raise SystemExit(f"{log} has no coat count: did the camera stop cleanly?")
        baked, read = baked + int(m[-1][0]), read + int(m[-1][1])
    return baked, read


def _up(root: Path, cfg: Path, args: argparse.Namespace, tag: str) -> dict[str, Any]:
    out = root / tag
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ZEBRA_SIM_CACHE=str(root / "cache"))
    run = subprocess.run([sys.executable, "-m", "zebra_sim_ros.cli", "up", "--frames", str(args.frames),
                          "--world", args.world, "--seed", str(args.seed), "--out", str(out), "--config", str(cfg),
                          "--domain-id", str(150 + os.getpid() % 50), "--json"],
                         env=env, capture_output=True, text=True, timeout=3600)
    if run.returncode != 0:
        raise SystemExit(f"zebra-sim up failed ({run.returncode}):\n{run.stdout[-3000:]}\n{run.stderr[-2000:]}")
    up = json.loads(run.stdout.strip().splitlines()[-1])
    baked, read = _coats(out / "logs")
    shutil.rmtree(out, ignore_errors=True)
    return {"seconds": up["seconds"], "steps_per_s": up["steps_per_s"], "render_ms": up["median_ms"]["render"],
            "baked": baked, "read": read, "mAP50": up["scores"]["all"]["mAP50"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=10, help="steps of each graph run")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--world", default="savanna")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    root = Path(tempfile.mkdtemp(prefix="bench_coat_store_"))
    build_library(root / "cache")
    store_dir = CoatStore(root / "cache", enabled=False).dir
    runs: dict[str, list[dict[str, Any]]] = {a: [] for a in ARMS}
    try:
        own, shared = _config(root, False), _config(root, True)
        for k in range(args.rounds):
            runs["own"].append(_up(root, own, args, f"own{k}"))
            shutil.rmtree(store_dir, ignore_errors=True)
            runs["shared, empty"].append(_up(root, shared, args, f"empty{k}"))
            runs["shared, filled"].append(_up(root, shared, args, f"filled{k}"))
            for a in ARMS:
                print(f"round {k + 1}, {a}: {runs[a][-1]}", file=sys.stderr, flush=True)
    finally:
        shutil.rmtree(root, ignore_errors=True)
    med = {a: {key: statistics.median(r[key] for r in rs) for key in rs[0]} for a, rs in runs.items()}
    result = {"machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
              "frames": args.frames, "rounds": args.rounds, "world": args.world, "seed": args.seed, "median": med,
              "steps_per_s_over_own": {a: round(med[a]["steps_per_s"] / med["own"]["steps_per_s"], 3)
                                       for a in ARMS[1:]}}
    if args.json:
        print(json.dumps(result))
        return
    print(f"machine: {result['machine']}; {args.frames} steps of {args.world}, seed {args.seed}, {args.rounds} rounds")
    print("| arm | seconds | steps/s | render ms per step | coats baked / read (3 cameras) | mAP50 "
          "| steps/s over own |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for a in ARMS:
        m = med[a]
        ratio = result["steps_per_s_over_own"].get(a, 1.0)
        print(f"| {a} | {m['seconds']:.1f} | {m['steps_per_s']:.3f} | {m['render_ms']:.0f} | "
              f"{m['baked']:.0f} / {m['read']:.0f} | {m['mAP50']:.4f} | {ratio:.3f}x |")


if __name__ == "__main__":
    main()
