"""Benchmark: how long ``zebra-sim`` takes to start, for commands that run no model.

Runs ``python -m zebra_sim_ros.cli ARGS`` (by default ``--help`` and ``generate --help``: the parser built, nothing
run) ``--repeats`` times each in fresh processes, and reports the median wall and CPU seconds (user + system, the
child's own) and whether torch was imported. ``--baseline DIR`` also runs every call with the code of another
checkout (``git worktree add DIR REV``), call after call alternating with this tree, and reports this tree's time
over the baseline's: the same machine, the same minutes. Each tree's bytecode is compiled first, as setup.sh does.

    python benchmarks/bench_cli_start.py [--repeats 7] [--baseline DIR] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parents[1]
COMMANDS = (["--help"], ["generate", "--help"])
# the parser as the console script builds it, then whether torch came with it (printed last, on stderr)
_CHILD = ("import sys, runpy; sys.argv = ['zebra-sim'] + sys.argv[1:]\n"
          "try:\n    runpy.run_module('zebra_sim_ros.cli', run_name='__main__')\n"
          "except SystemExit as e:\n    if e.code not in (0, None):\n        raise\n"
          "print('torch' in sys.modules, file=sys.stderr)")


def one(root: Path, args: list[str]) -> tuple[float, float, bool]:
    """Wall seconds, CPU seconds and whether torch was imported, for one start of ``zebra-sim ARGS`` from ``root``."""
    env = {**os.environ, "PYTHONPATH": str(root)}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    run = subprocess.run([sys.executable, "-c", _CHILD, *args], cwd=root, env=env, capture_output=True, text=True,
                         timeout=120)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if run.returncode != 0:
        raise SystemExit(f"zebra-sim {' '.join(args)} from {root} failed: {run.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, run.stderr.strip().splitlines()[-1] == "True"


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--baseline", type=Path, help="another checkout to run the same calls with, alternating")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    if args.repeats < 1:
        ap.error(f"--repeats {args.repeats}: want 1 or more")
    trees = {"this": HERE} | ({"baseline": args.baseline.resolve()} if args.baseline else {})
    for name, root in trees.items():
        if not (root / "zebra_sim_ros" / "cli" / "__init__.py").is_file():
            ap.error(f"{name} tree {root}: no zebra_sim_ros/cli there")
    runs: dict[str, dict[str, list[tuple[float, float, bool]]]] = {n: {} for n in trees}
    for root in trees.values():  # bytecode compiled as setup.sh does, then one start each: the page cache warmed
        subprocess.run([sys.executable, "-m", "compileall", "-q", str(root / "zebra_sim_ros")], check=True,
                       stdout=subprocess.DEVNULL)
        for c in COMMANDS:
            one(root, c)
    for _ in range(args.repeats):
        for c in COMMANDS:
            for name, root in trees.items():
                runs[name].setdefault(" ".join(c), []).append(one(root, c))
    result: dict[str, Any] = {"machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs",
                              "repeats": args.repeats, "trees": {}}
    for name, per in runs.items():
        result["trees"][name] = {c: {"wall_s": round(statistics.median(r[0] for r in rs), 3),
                                     "cpu_s": round(statistics.median(r[1] for r in rs), 3),
                                     "torch_imported": any(r[2] for r in rs)} for c, rs in per.items()}
    if args.baseline:
        result["this_over_baseline_cpu"] = {
            c: round(result["trees"]["this"][c]["cpu_s"] / result["trees"]["baseline"][c]["cpu_s"], 3)
            for c in result["trees"]["this"]}
    if args.json:
        print(json.dumps(result, indent=1))
        return
    for name, per in result["trees"].items():
        for c, r in per.items():
            print(f"{name:8s} zebra-sim {c:18s} wall {r['wall_s']:.2f} s  CPU {r['cpu_s']:.2f} s  "
                  f"torch imported: {r['torch_imported']}  (median of {args.repeats})")
    for c, ratio in result.get("this_over_baseline_cpu", {}).items():
        print(f"zebra-sim {c}: this tree's CPU / the baseline's {ratio:.2f}")


if __name__ == "__main__":
    main()
