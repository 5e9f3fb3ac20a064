"""Benchmark: what ``zebra-sim bag census`` costs on a recorded ``up --locate`` run, and what writing the census on
the Earth (``--geojson``: each scene read for its datum, every animal converted to WGS84, the file written) adds.

Alternates the two, ``--repeats`` times each in one process (the bag in the page cache after a first, unmeasured
read), and prints the medians and their ratio: the cost of ``--geojson`` as a share of the recount's. Beside them,
the GeoJSON alone (``census_geojson`` and ``write_geojson`` on the recounted animals, read back from the file): the
part of it that reading the bag does not hide in its noise.

    python benchmarks/bench_bag_census.py out/up/zebra_sim.mcap [--repeats 5] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from zebra_sim_ros.messages import Datum
from zebra_sim_ros.recording.cdr import Placed3D
from zebra_sim_ros.recording.census import bag_census, census_geojson, write_geojson


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("bag", type=Path, help="a bag recorded by zebra-sim up --locate")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    if args.repeats < 1:
        ap.error(f"--repeats {args.repeats}: want 1 or more")
    times: dict[str, list[float]] = {"recount": [], "recount + geojson": []}
    with tempfile.TemporaryDirectory() as tmp:
        first = bag_census(args.bag, geojson=Path(tmp) / "census.geojson")  # warms the page cache
        doc = json.loads((Path(tmp) / "census.geojson").read_text())  # the same file each repeat writes again
        features = len(doc["features"])
        for _ in range(args.repeats):
            for name, geojson in (("recount", None), ("recount + geojson", Path(tmp) / "census.geojson")):
                t0 = time.perf_counter()
                bag_census(args.bag, geojson=geojson)
                times[name].append(time.perf_counter() - t0)
        census: dict[int, list[Placed3D]] = {}
        for f in doc["features"]:
            props = f["properties"]
            census.setdefault(props["stamp_ns"], []).append(Placed3D(
                props["class"], props["score"], (props["map_x"], props["map_y"], props["map_z"]), props["detections"]))
        datum = Datum(**doc["zebra_sim"]["datum"])
        alone = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            write_geojson(Path(tmp) / "alone.geojson", census_geojson(census, datum, {}))
            alone.append(time.perf_counter() - t0)
        times["the GeoJSON alone"] = alone
    med = {k: statistics.median(v) for k, v in times.items()}
    files = sorted(args.bag.rglob("*.mcap")) if args.bag.is_dir() else [args.bag]  # a split recording's folder
    out: dict[str, Any] = {
        "date": time.strftime("%Y-%m-%d"), "machine": platform.processor() or platform.machine(),
        "cores": os.cpu_count(), "bag": str(args.bag), "bag_mb": round(sum(p.stat().st_size for p in files) / 2**20, 1),
        "stamps": first["stamps_counted"], "animals": first["recounted"]["animals"], "features": features,
        "median_s": {k: round(v, 3) for k, v in med.items()},
        "geojson_share": round(med["recount + geojson"] / med["recount"] - 1.0, 3)}
    if args.json:
        print(json.dumps(out, indent=1))
        return
    print(f"{out['bag']} ({out['bag_mb']} MB, {out['stamps']} steps, {out['animals']} animals, {features} features)")
    print("| run | median s |\n| --- | --- |")
    for k, v in out["median_s"].items():
        print(f"| {k} | {v} |")
    print(f"--geojson adds {out['geojson_share']:+.1%} to the recount ({args.repeats} of each, alternated)")


if __name__ == "__main__":
    main()
