"""``zebra-sim render``: one step's three views to files, without ROS."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from zebra_sim_ros.cli.common import Summary, add_json_flag
from zebra_sim_ros.cli.place import placer_values
from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.geometry.frames import optical_frame
from zebra_sim_ros.params import add_option, spec_of


def register(sub: Any) -> None:
    """Add the ``render`` subcommand."""
    from zebra_sim_ros.placement.config import PlacerConfig
    from zebra_sim_ros.rendering.config import CameraConfig, add_lens_option

    p = sub.add_parser(
        "render", help="render one step's camera views to files (PNG RGB, depth, instance mask)",
        description="Writes per camera: <name>_rgb.png (sRGB), <name>_depth.npy (float32 metres along the optical "
                    "axis, inf = sky), <name>_depth_mm.png (uint16 millimetres, 0 = sky or beyond 65.5 m), "
                    "<name>_instances.png (uint16: zebra id + 1, 0 = not a zebra), plus scene.json, "
                    "camera_info.json (K and the lens's D per camera) and a contact sheet preview.png.")
    for name in ("seed", "world", "strategy"):  # the placer's parameters; not given: the parameter file's
        add_option(p, spec_of(PlacerConfig, name), default=None)
    p.add_argument("--step", type=int, default=0, help="which step of the seed's sequence (>= 0)")
    p.add_argument("--params-file", type=Path, default=None, help="placer parameter YAML (config/placer.yaml)")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help="override a placer parameter")
    p.add_argument("--time-of-day", type=float, default=None, help="override the drawn time of day, hours")
    add_option(p, spec_of(CameraConfig, "width"))
    add_option(p, spec_of(CameraConfig, "height"))
    add_option(p, spec_of(CameraConfig, "hfov_deg"), "--hfov", default=None, note="not given: the placer's")
    add_option(p, spec_of(CameraConfig, "sensor_strength"))
    add_option(p, spec_of(CameraConfig, "look"))
    add_lens_option(p)
    p.add_argument("--no-shadows", action="store_true", help="render without sun shadows")
    p.add_argument("--out", type=Path, required=True, help="output folder")
    add_json_flag(p)
    p.set_defaults(func=cmd_render)


def cmd_render(args: argparse.Namespace) -> Summary:
    """Render the step."""
    import cv2

    from zebra_sim_ros.geometry.lens import PLUMB_BOB, lens_named, lens_names, lens_params
    from zebra_sim_ros.placement.config import PlacerConfig
    from zebra_sim_ros.placement.placer import Placer
    from zebra_sim_ros.placement.sun import lighting_for
    from zebra_sim_ros.rendering.config import check_render_options, look_options, parse_lens
    from zebra_sim_ros.rendering.effects import SensorModel
    from zebra_sim_ros.rendering.renderer import RenderOptions
    from zebra_sim_ros.simulation import Simulator
    from zebra_sim_ros.world.world import load_world
    from zebra_sim_ros.zebra.asset import load_library

    if args.step < 0:
        raise ParameterError("--step", args.step, ">= 0")
    values = placer_values(argparse.Namespace(**{**vars(args), "start_step": None}))
    values.setdefault("camera_width", args.width)
    values.setdefault("camera_height", args.height)
    if args.hfov_deg is not None:
        values["camera_hfov_deg"] = args.hfov_deg
    lens = parse_lens(args.lens)
    values.update(lens_params(lens, "camera_lens_"))  # the placer aims through the lens the step is rendered with
    with lens_named("--lens", lens_names("camera_lens_")):  # a lens its camera cannot use: named by the option
        cfg = PlacerConfig.from_params(values)
    options = check_render_options(RenderOptions(width=args.width, height=args.height, hfov_deg=cfg.camera_hfov_deg,
                                                 shadows=not args.no_shadows, distortion=lens,
                                                 **look_options(args.look)), "--lens")
    t0 = time.perf_counter()
    world = load_world(cfg.world, cfg.terrain_prim, cfg.world_seed)
    lib = load_library()
    scene = Placer(cfg, world, lib).scene(args.step)
    if args.time_of_day is not None:
        light = scene.lighting
        scene = scene.with_lighting(lighting_for(args.time_of_day % 24.0, light.day_of_year, light.latitude_deg))
    sim = Simulator(world, lib, options,
                    sensor=SensorModel(args.sensor_strength) if args.sensor_strength > 0 else None)
    renderer = sim.renderer
    t1 = time.perf_counter()
    views = sim.render(scene)
    t_render = time.perf_counter() - t1
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    (out / "scene.json").write_text(json.dumps(scene.to_dict(), indent=1))
    info = {}
    tiles = []
    for v in views:
        cv2.imwrite(str(out / f"{v.name}_rgb.png"), v.rgb[..., ::-1])
        np.save(out / f"{v.name}_depth.npy", v.depth)
        mm = np.where(np.isfinite(v.depth), np.clip(np.rint(v.depth * 1000), 0, 65535), 0).astype(np.uint16)
        cv2.imwrite(str(out / f"{v.name}_depth_mm.png"), mm)
        cv2.imwrite(str(out / f"{v.name}_instances.png"), v.instances)
        info[v.name] = {"width": args.width, "height": args.height, "K": v.K.tolist(), "distortion_model": PLUMB_BOB,
                        "D": list(v.D),
                        "frame_id": optical_frame(v.name), "depth_unit": "m", "instances": "zebra id + 1"}
        tiles.append(preview_row(v.rgb, v.depth, v.instances))
    (out / "camera_info.json").write_text(json.dumps(info, indent=1))
    cv2.imwrite(str(out / "preview.png"), np.concatenate(tiles, axis=0)[..., ::-1])
    sim.release()
    n_px = {v.name: int((v.instances > 0).sum()) for v in views}
    print(f"rendered step {args.step} ({scene.placed} zebras, {scene.lighting.time_of_day_h:.1f} h) in "
          f"{t_render:.2f} s "
          f"on {renderer.info['GL_RENDERER']}; wrote {out}")
    return {"out": str(out), "step": args.step, "zebras": scene.placed, "render_seconds": round(t_render, 3),
            "setup_seconds": round(t1 - t0, 3), "device": renderer.info["device"], "zebra_pixels": n_px}


def preview_row(rgb: np.ndarray, depth: np.ndarray, ids: np.ndarray, depth_max: float = 200.0) -> np.ndarray:
    """RGB | depth (near bright, sky black) | coloured instance mask, side by side, RGB uint8."""
    import cv2

    d = np.where(np.isfinite(depth), 1.0 - np.clip(depth / depth_max, 0, 1), 0.0)
    d8 = cv2.cvtColor((d * 255).astype(np.uint8), cv2.COLOR_GRAY2RGB)
    hue = ((ids.astype(np.int64) * 47) % 180).astype(np.uint8)
    hsv = np.stack([hue, np.full_like(hue, 200), np.where(ids > 0, 255, 0).astype(np.uint8)], axis=-1)
    m8 = cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)
    return np.concatenate([rgb, d8, m8], axis=1)
