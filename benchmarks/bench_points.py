"""Benchmark: what a camera node's point cloud (``points_stride``) costs beside the render it comes from.

Renders drone_0 of ``--steps`` steps of the default world (the placer's defaults, ``--size``, through ``--lens`` if
given) and, per step and stride in ``--strides``, times what the camera node does for ``drone_{i}/points``: the points
from the depth image (:func:`~zebra_sim_ros.geometry.camera.depth_points`), the PointCloud2 with packed colour
(``point_cloud_msg``) and its CDR serialisation (what rclpy hands DDS). It reports the medians, the message's size,
and the median over steps of the cloud's time / that step's render of the one view (the first step, which bakes
coats, left out), and how long a camera model's rays take to make once (the first cloud of a stride).

    python benchmarks/bench_points.py [--steps 6] [--size 1280x720] [--strides 1 2 4 8] [--lens K ...] [--json]
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
from std_msgs.msg import Header

from zebra_sim_ros.cli.common import parse_size
from zebra_sim_ros.geometry.camera import PinholeCamera, depth_points, pixel_rays
from zebra_sim_ros.nodes.ros_adapter import point_cloud_msg
from zebra_sim_ros.placement.config import PlacerConfig
from zebra_sim_ros.placement.placer import Placer
from zebra_sim_ros.rendering.config import add_lens_option, parse_lens
from zebra_sim_ros.rendering.renderer import RenderOptions
from zebra_sim_ros.simulation import Simulator
from zebra_sim_ros.world.world import load_world
from zebra_sim_ros.zebra.asset import load_library


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=6)
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--strides", type=int, nargs="+", default=[1, 2, 4, 8])
    add_lens_option(ap)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    width, height = parse_size(args.size)
    lens = parse_lens(args.lens)
    pc = PlacerConfig.from_params({"camera_width": width, "camera_height": height})
    world = load_world(pc.world, pc.terrain_prim, pc.world_seed)
    placer = Placer(pc, world, load_library())
    cam = PinholeCamera(width, height, pc.camera_hfov_deg, lens)
    rays_s = {}
    for s in args.strides:
        t0 = time.perf_counter()
        pixel_rays(cam, s)
        rays_s[s] = time.perf_counter() - t0
    sim = Simulator(world, placer.library, RenderOptions(width=width, height=height, hfov_deg=pc.camera_hfov_deg,
                                                         distortion=lens))
    render_ms: list[float] = []
    cloud_ms: dict[int, list[float]] = {s: [] for s in args.strides}
    ratio: dict[int, list[float]] = {s: [] for s in args.strides}
    size: dict[int, int] = {}
    try:
        for step in range(args.steps):
            scene = placer.scene(step)
            t0 = time.perf_counter()
            [view] = sim.render(scene, ["drone_0"])
            render = (time.perf_counter() - t0) * 1e3
            for s in args.strides:
                t1 = time.perf_counter()
                msg = point_cloud_msg(Header(frame_id="drone_0/camera_optical"), depth_points(view.depth, cam, s),
                                      view.rgb[::s, ::s])
                size[s] = len(serialize_message(msg))
                took = (time.perf_counter() - t1) * 1e3
                if step > 0:
                    cloud_ms[s].append(took)
                    ratio[s].append(took / render)
            if step > 0:
                render_ms.append(render)
    finally:
        sim.release()
    out: dict[str, Any] = {
        "date": time.strftime("%Y-%m-%d"), "machine": f"{platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} cores", "steps": args.steps, "size": args.size, "lens": list(lens.coefficients),
        "render_ms": round(statistics.median(render_ms), 1),
        "strides": {s: {"points": f"{-(-height // s)}x{-(-width // s)}", "rays_once_s": round(rays_s[s], 3),
                        "cloud_ms": round(statistics.median(cloud_ms[s]), 1), "message_mb": round(size[s] / 1e6, 2),
                        "over_render": round(statistics.median(ratio[s]), 3)} for s in args.strides}}
    print(json.dumps(out, indent=1) if args.json else "\n".join(f"{k}: {v}" for k, v in out.items()))


if __name__ == "__main__":
    main()
