"""Benchmark: how long the message packages under ``interfaces/`` take to build, Python-only against whole.

Builds each package (``zebra_sim_msgs``, ``tf2_msgs``, ``rosbag2_interfaces``; ``--packages`` names some) from
scratch with CMake as ``scripts/build_interfaces.sh`` does, into a throwaway build folder and install prefix, once
with ``-DZEBRA_SIM_PYTHON_ONLY=ON`` (what the set-up builds: the C and Python code) and once with it off (the whole
ROS package: C++ headers and the three C++ typesupports too), the two alternating ``--rounds`` times, and reports
each one's median wall and CPU seconds (the children's user + system), their ratio, and the libraries each
installed. Run it after ``scripts/setup.sh`` (it uses
the venv's rosidl generators and the typesupport markers the set-up registers under ``build/interfaces``).

    python benchmarks/bench_interfaces_build.py [--rounds 3] [--jobs 2] [--packages P ...] [--json]
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
import tempfile
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parents[1]
VENV = HERE / ".venv"
PACKAGES = ("zebra_sim_msgs", "tf2_msgs", "rosbag2_interfaces")


def build(pkg: str, python_only: bool, jobs: int) -> tuple[float, float, list[str]]:
    """Wall and CPU seconds of configuring, building and installing ``pkg`` from scratch, and the libraries it
    installed."""
    markers = HERE / "build" / "interfaces" / "markers"
    if not markers.is_dir():
        raise SystemExit(f"no typesupport markers at {markers}: run scripts/setup.sh first")
    env = {**os.environ, "AMENT_PREFIX_PATH": f"{markers}:{VENV}", "CMAKE_PREFIX_PATH": str(VENV),
           "PATH": f"{VENV / 'bin'}:{os.environ['PATH']}"}
    with tempfile.TemporaryDirectory(prefix="zebra_ifbuild_") as tmp:
        b, prefix = Path(tmp) / "build", Path(tmp) / "prefix"
        steps = [["cmake", "-S", str(HERE / "interfaces" / pkg), "-B", str(b), f"-DCMAKE_INSTALL_PREFIX={prefix}",
                  f"-DPython3_EXECUTABLE={VENV / 'bin' / 'python'}", "-DBUILD_TESTING=OFF",
                  "-DCMAKE_BUILD_TYPE=Release", f"-DZEBRA_SIM_PYTHON_ONLY={'ON' if python_only else 'OFF'}"],
                 ["cmake", "--build", str(b), "-j", str(jobs)], ["cmake", "--install", str(b)]]
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t = time.perf_counter()
        for cmd in steps:
            run = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
            if run.returncode != 0:
                raise SystemExit(f"{' '.join(cmd[:2])} of {pkg} (python_only={python_only}) failed:\n"
                                 f"{run.stdout[-2000:]}{run.stderr[-2000:]}")
        wall = time.perf_counter() - t
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        libs = sorted(p.name for p in (prefix / "lib").glob("lib*.so"))
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), libs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="cmake --build -j (the set-up: nproc)")
    ap.add_argument("--packages", nargs="+", default=list(PACKAGES), help="the packages built (each round, in turn)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    if unknown := [p for p in args.packages if p not in PACKAGES]:
        raise SystemExit(f"--packages: {unknown[0]!r} is not under interfaces/ (want some of {', '.join(PACKAGES)})")
    if args.rounds < 1:
        raise SystemExit(f"--rounds must be 1 or more, got {args.rounds}")
    if args.jobs < 1:
        raise SystemExit(f"--jobs must be 1 or more, got {args.jobs}")
    times: dict[bool, list[tuple[float, float]]] = {True: [], False: []}
    libs: dict[bool, list[str]] = {}
    for r in range(args.rounds):
        for python_only in ((True, False) if r % 2 == 0 else (False, True)):
            wall = cpu = 0.0
            names: list[str] = []
            for pkg in args.packages:
                w, c, n = build(pkg, python_only, args.jobs)
                wall, cpu, names = wall + w, cpu + c, names + n
            times[python_only].append((wall, cpu))
            libs[python_only] = names
            print(f"round {r + 1}: python_only={python_only}: {wall:.1f} s wall, {cpu:.1f} s CPU", file=sys.stderr)
    med = {k: (statistics.median(w for w, _ in v), statistics.median(c for _, c in v)) for k, v in times.items()}
    out: dict[str, Any] = {
        "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores", "jobs": args.jobs,
        "rounds": args.rounds, "packages": args.packages,
        "python_only": {"wall_s": round(med[True][0], 1), "cpu_s": round(med[True][1], 1), "libraries": libs[True]},
        "whole": {"wall_s": round(med[False][0], 1), "cpu_s": round(med[False][1], 1), "libraries": libs[False]},
        "wall_ratio": round(med[True][0] / med[False][0], 3), "cpu_ratio": round(med[True][1] / med[False][1], 3)}
    if args.json:
        print(json.dumps(out, indent=1))
        return
    print(f"| build ({' + '.join(args.packages)}, -j {args.jobs}) | median wall (s) | median CPU (s) | libraries |")
    print("| --- | --- | --- | --- |")
    for key, name in (("python_only", "C and Python (-DZEBRA_SIM_PYTHON_ONLY=ON, the set-up's)"),
                      ("whole", "whole package (off)")):
        v = out[key]
        print(f"| {name} | {v['wall_s']:.1f} | {v['cpu_s']:.1f} | {len(v['libraries'])} |")
    print(f"python-only / whole: wall {out['wall_ratio']:.3f}, CPU {out['cpu_ratio']:.3f} ({args.rounds} rounds "
          f"alternating, {out['machine']})")


if __name__ == "__main__":
    main()
