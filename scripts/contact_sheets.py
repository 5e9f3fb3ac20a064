"""Render the docs contact sheet: every built-in world at noon and at dusk (RGB, depth, instance mask).

    python scripts/contact_sheets.py docs/worlds_contact_sheet.jpg [--width 320] [--height 180]

Each row is one world: noon RGB, depth, mask, then dusk RGB, depth, mask of the same view (drone_0 of step 0,
closeby strategy, seed 1). Depth is shown near-bright, sky black; each zebra has its own mask colour.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from zebra_sim_ros.cli.render import preview_row
from zebra_sim_ros.placement.config import PlacerConfig
from zebra_sim_ros.placement.placer import Placer
from zebra_sim_ros.placement.sun import lighting_for
from zebra_sim_ros.rendering.renderer import Renderer, RenderOptions
from zebra_sim_ros.rendering.views import views_from_scene, zebras_from_scene
from zebra_sim_ros.world.presets import PRESETS
from zebra_sim_ros.world.world import generate_world
from zebra_sim_ros.zebra.asset import load_library


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=180)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    lib = load_library()
    rows = []
    for name in PRESETS:
        world = generate_world(name, 0)
        cfg = PlacerConfig.from_params({"seed": args.seed, "strategy": "closeby", "count_min": 40, "count_max": 120,
                                        "camera_width": args.width, "camera_height": args.height})
        scene = Placer(cfg, world, lib).scene(0)
        r = Renderer(world, lib, RenderOptions(width=args.width, height=args.height, shadow_size=1024))
        zs, views = zebras_from_scene(scene, lib), views_from_scene(scene, ["drone_0"])
        day = scene.lighting.day_of_year
        tiles = []
        for hour, label in ((12.0, "noon"), (18.1, "dusk")):
            v = r.render(zs, lighting_for(hour, day, cfg.latitude_deg), views)[0]
            tile = preview_row(v.rgb, v.depth, v.instances, depth_max=120.0)
            cv2.putText(tile, f"{name} {label}", (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1,
                        cv2.LINE_AA)
            tiles.append(tile)
        r.release()
        rows.append(np.concatenate(tiles, axis=1))
    sheet = np.concatenate(rows, axis=0)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(args.out), sheet[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, 85])
    print(f"wrote {args.out} ({sheet.shape[1]}x{sheet.shape[0]})")


if __name__ == "__main__":
    main()
