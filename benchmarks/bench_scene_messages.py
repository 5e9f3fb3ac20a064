"""Benchmark: what the placer's typed 3D ground truth (``zebra_sim/zebras``, a Detection3DArray of every placed
animal) costs per step, against the scene JSON (``zebra_sim/scene``) it publishes beside it.

Scenes come from the placer's own core (``Placer.scene``, the default world, seeded), with up to ``--others``
animals of other species besides the zebras. Per scene, the median of ``--repeats`` of: the Detection3DArray built
(``scene_animals_msg``) and serialized (CDR, as DDS sends it), and the scene's JSON made and serialized as its
std_msgs/String; the ratio of the two in the same run, and each message's size.

    python benchmarks/bench_scene_messages.py [--others 0 60 150] [--steps 3] [--repeats 15] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from typing import Any

from rclpy.serialization import serialize_message
from std_msgs.msg import Header, String

from zebra_sim_ros.nodes.ros_adapter import detection3d_array_type, scene_animals_msg
from zebra_sim_ros.placement.config import PlacerConfig
from zebra_sim_ros.placement.placer import Placer
from zebra_sim_ros.world.world import load_world
from zebra_sim_ros.zebra.asset import load_library


def _median_s(fn: Any, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--others", type=int, nargs="+", default=[0, 60, 150], help="other_animals_max per run")
    ap.add_argument("--steps", type=int, default=3, help="scenes per setting")
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    type_name = detection3d_array_type()
    out: dict[str, Any] = {"date": time.strftime("%Y-%m-%d"), "machine": f"{platform.processor() or platform.machine()}"
                           f", {os.cpu_count()} cores", "type": type_name, "rows": []}
    library = load_library()
    world = load_world("savanna", "/World/Terrain", 0)
    for others in args.others:
        placer = Placer(PlacerConfig(seed=5, other_animals_max=others), world, library)
        for step in range(args.steps):
            scene = placer.scene(step * placer.cfg.camera_rerolls)  # a new placement each (a step is a reroll)
            header = Header(frame_id="map")
            typed = _median_s(lambda s=scene, h=header: serialize_message(scene_animals_msg(type_name, h, s.zebras)),
                              args.repeats)
            plain = _median_s(lambda s=scene: serialize_message(String(data=s.to_json())), args.repeats)
            typed_bytes = len(serialize_message(scene_animals_msg(type_name, header, scene.zebras)))
            json_bytes = len(serialize_message(String(data=scene.to_json())))
            out["rows"].append({"other_animals_max": others, "step": step, "animals": len(scene.zebras),
                                "typed_ms": round(typed * 1e3, 2), "json_ms": round(plain * 1e3, 2),
                                "typed_over_json": round(typed / plain, 2), "typed_kb": round(typed_bytes / 1e3, 1),
                                "json_kb": round(json_bytes / 1e3, 1)})
    if args.json:
        print(json.dumps(out, indent=1))
        return
    print(f"{out['machine']}; {type_name}")
    print("| other_animals_max | step | animals | Detection3DArray built + serialized (ms) | scene JSON (ms) | ratio "
          "| Detection3DArray (kB) | scene JSON (kB) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in out["rows"]:
        print(f"| {r['other_animals_max']} | {r['step']} | {r['animals']} | {r['typed_ms']} | {r['json_ms']} | "
              f"{r['typed_over_json']} | {r['typed_kb']} | {r['json_kb']} |")


if __name__ == "__main__":
    main()
