"""Render the realism contact sheet: every built-in world, every camera strategy, at noon and in low sun, as the
generator writes them (the photograph's camera on), to set beside drone and ground photographs.

    python scripts/realism_sheet.py docs/realism_contact_sheet.jpg [--width 320] [--height 180] [--seed 1]

Each row is one world; each column one strategy at 12 h and at low sun (sun about 8 degrees up), drone_0 of
step 0. The strategies are those the placer accepts, in the order far, closeby, low, nadir. The title bar of each
cell names it, and the sheet's last line the commit's settings (seed, size).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.placement.config import PlacerConfig
from zebra_sim_ros.placement.placer import Placer
from zebra_sim_ros.placement.sun import lighting_for, solar_direction
from zebra_sim_ros.rendering.effects import SensorModel
from zebra_sim_ros.rendering.renderer import RenderOptions
from zebra_sim_ros.simulation import Simulator
from zebra_sim_ros.world.presets import PRESETS
from zebra_sim_ros.world.world import generate_world
from zebra_sim_ros.zebra.asset import load_library


def strategies() -> list[str]:
    """The strategies this placer accepts, of far, closeby, low and nadir."""
    out = []
    for s in ("far", "closeby", "low", "nadir"):
        try:
            PlacerConfig.from_params({"strategy": s})
            out.append(s)
        except ParameterError:
            continue
    return out


def low_sun_hour(day: int, latitude: float) -> float:
    """The morning hour at which the sun stands about 8 degrees up."""
    for h10 in range(50, 120):
        if solar_direction(h10 / 10, day, latitude)[1] >= 8.0:
            return h10 / 10
    return 7.0


def cell(rgb: np.ndarray, title: str) -> np.ndarray:
    out = rgb[..., ::-1].copy()
    cv2.rectangle(out, (0, 0), (out.shape[1], 14), (0, 0, 0), -1)
    cv2.putText(out, title, (3, 11), cv2.FONT_HERSHEY_SIMPLEX, 0.35, (255, 255, 255), 1, cv2.LINE_AA)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=180)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--worlds", default="", help="comma-separated presets (default: all)")
    args = ap.parse_args()
    lib = load_library()
    rows = []
    for name in (args.worlds.split(",") if args.worlds else PRESETS):
        world = generate_world(name, 0)
        sim = Simulator(world, lib, RenderOptions(width=args.width, height=args.height), sensor=SensorModel())
        row = []
        for strategy in strategies():
            cfg = PlacerConfig.from_params({"seed": args.seed, "strategy": strategy, "world": name,
                                            "camera_width": args.width, "camera_height": args.height})
            scene = Placer(cfg, world, lib).scene(0)
            light = scene.lighting
            for label, hour in (("noon", 12.0), ("low sun", low_sun_hour(light.day_of_year, light.latitude_deg))):
                lit = scene.with_lighting(lighting_for(hour, light.day_of_year, light.latitude_deg))
                view = sim.render(lit, ["drone_0"])[0]
                row.append(cell(view.rgb, f"{name} {strategy} {label}"))
        sim.release()
        rows.append(np.hstack(row))
        print(f"{name}: {len(row)} cells")
    sheet = np.vstack(rows)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(args.out), sheet, [cv2.IMWRITE_JPEG_QUALITY, 85])
    print(f"wrote {args.out} ({sheet.shape[1]}x{sheet.shape[0]})")


if __name__ == "__main__":
    main()
