"""Benchmark: frames per hour of ``zebra-sim generate`` with labels (the paper's 36K frames goal).

Runs the same generation (by default SF: far and closeby, savanna, 1280x720, the paper's randomisation) with one
worker and with two workers in the same run, each into a fresh folder and in its own process, and reports
frames/s, frames/hour, the hours the paper's 36K frames would take, and the time split between placing,
rendering, labelling and writing (summed over workers). The first frames include start-up (world, renderer,
coats), as a real run does.

``--baseline DIR`` also runs every arm with the code of another checkout (``git worktree add DIR REV``), round
after round alternating with this one, and reports this tree's frames/s over the baseline's (median of
``--rounds``), and whether both wrote the same bytes (images, masks, labels, annotations but for their
appearance digest).

    python benchmarks/bench_generate.py [--frames 90] [--worlds savanna] [--strategy both] [--size 1280 720]
                                        [--workers 1 2] [--baseline DIR] [--rounds 1] [--json]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parents[1]

_CHILD = """
import json, sys
from zebra_sim_ros.dataset.generate import GenerateConfig, generate
a = json.loads(sys.argv[1])
cfg = GenerateConfig(out=a["out"], frames=a["frames"], strategy=a["strategy"], worlds=tuple(a["worlds"]),
                     workers=a["workers"], width=a["width"], height=a["height"], depth=a["depth"])
print(json.dumps(generate(cfg, progress=lambda *x: None)))
"""


def _digest(out: Path) -> str:
    """One md5 over every written image, mask, label and annotation file (names and bytes, in name order). An
    annotation's ``appearance_digest`` is left out: it hashes the coats' source code, so a change that draws the
    same coats, byte for byte, changes it; the pixels and the rest of the annotation say whether they are the same."""
    h = hashlib.md5()
    for sub in ("images", "masks", "labels", "ignore", "annotations"):
        for f in sorted((out / sub).rglob("*")) if (out / sub).exists() else []:
            if f.is_file():
                h.update(str(f.relative_to(out)).encode())
                data = f.read_bytes()
                if sub == "annotations":
                    ann = json.loads(data)
                    ann.pop("appearance_digest", None)
                    data = json.dumps(ann, sort_keys=True).encode()
                h.update(data)
    return h.hexdigest()


def _run(tree: Path, out: Path, args: argparse.Namespace, workers: int) -> dict[str, Any]:
    spec = {"out": str(out), "frames": args.frames, "strategy": args.strategy, "worlds": args.worlds,
            "workers": workers, "width": args.size[0], "height": args.size[1], "depth": args.depth}
    env = {**os.environ, "PYTHONPATH": str(tree)}
    done = subprocess.run([sys.executable, "-c", _CHILD, json.dumps(spec)], env=env, cwd=tree, check=True,
                          capture_output=True, text=True)
    stats: dict[str, Any] = json.loads(done.stdout.strip().splitlines()[-1])
    stats["digest"] = _digest(out)
    shutil.rmtree(out, ignore_errors=True)
    return stats


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=90)
    ap.add_argument("--worlds", nargs="+", default=["savanna"])
    ap.add_argument("--strategy", default="both")
    ap.add_argument("--size", type=int, nargs=2, default=[1280, 720], metavar=("W", "H"))
    ap.add_argument("--depth", default="float32", help="depth images: float32 (generate's default) or none")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--baseline", type=Path, help="another checkout to run the same arms with, alternating")
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    if args.frames < 1 or args.rounds < 1 or min(args.workers) < 1:
        ap.error(f"--frames {args.frames}, --rounds {args.rounds} and --workers {args.workers} must be >= 1")
    if args.baseline is not None and not (args.baseline / "zebra_sim_ros").is_dir():
        ap.error(f"--baseline {args.baseline}: not a checkout of this project (no zebra_sim_ros/ in it)")
    trees = {"this": HERE} | ({"baseline": args.baseline.resolve()} if args.baseline else {})
    runs: dict[str, dict[int, list[dict[str, Any]]]] = {t: {w: [] for w in args.workers} for t in trees}
    root = Path(tempfile.mkdtemp(prefix="bench_generate_"))
    try:
        for r in range(args.rounds):
            for workers in args.workers:
                for name, tree in trees.items():
                    s = _run(tree, root / f"{name}_w{workers}_r{r}", args, workers)
                    runs[name][workers].append(s)
                    print(f"round {r + 1}, {name}, {workers} worker(s): {s['frames_per_s']:.3f} frames/s "
                          f"({s['seconds']:.1f} s); split {s['time_split_s']}", flush=True)
    finally:
        shutil.rmtree(root, ignore_errors=True)
    results: dict[str, Any] = {}
    for name in trees:
        for workers, ss in runs[name].items():
            fps = statistics.median(s["frames_per_s"] for s in ss)
            results[f"{name}_workers_{workers}"] = {
                "frames": ss[0]["frames_written"], "frames_per_s": round(fps, 3), "frames_per_hour": round(fps * 3600),
                "hours_for_36k": round(36000 / fps / 3600, 2), "time_split_s": ss[-1]["time_split_s"],
                "zebras_labelled": ss[0]["zebras_labelled"], "digest": ss[0]["digest"]}
            print(f"{name}, {workers} worker(s), median of {len(ss)}: {fps:.3f} frames/s ({fps * 3600:.0f}/h, "
                  f"36K frames in {36000 / fps / 3600:.1f} h)")
    summary: dict[str, Any] = {}
    if 1 in args.workers and 2 in args.workers:
        summary["ratio_2_over_1"] = round(results["this_workers_2"]["frames_per_s"]
                                          / results["this_workers_1"]["frames_per_s"], 2)
        print(f"two workers / one worker: {summary['ratio_2_over_1']:.2f}x")
    if args.baseline:
        for workers in args.workers:
            ratios = [a["frames_per_s"] / b["frames_per_s"]
                      for a, b in zip(runs["this"][workers], runs["baseline"][workers], strict=True)]
            same = results[f"this_workers_{workers}"]["digest"] == results[f"baseline_workers_{workers}"]["digest"]
            summary[f"this_over_baseline_workers_{workers}"] = round(statistics.median(ratios), 2)
            summary[f"same_bytes_workers_{workers}"] = same
            print(f"{workers} worker(s): this tree / baseline {statistics.median(ratios):.2f}x "
                  f"(rounds: {', '.join(f'{x:.2f}' for x in ratios)}); same bytes written: {same}")
    if args.json:
        print(json.dumps({"benchmark": "generate", "worlds": args.worlds, "strategy": args.strategy,
                          "resolution": f"{args.size[0]}x{args.size[1]}", "frames": args.frames,
                          "machine": f"{platform.machine()} cpus={os.cpu_count()}", "results": results, **summary}))


if __name__ == "__main__":
    main()
