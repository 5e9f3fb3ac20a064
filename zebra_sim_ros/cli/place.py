"""``zebra-sim place``: the placer's scenes as JSON lines, without ROS."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from zebra_sim_ros.cli.common import Summary, add_json_flag, parse_set
from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.params import add_option, spec_of


def register(sub: Any) -> None:
    """Add the ``place`` subcommand."""
    from zebra_sim_ros.placement.config import PlacerConfig

    p = sub.add_parser("place", help="generate placer scenes (zebras, time of day, cameras) as JSON lines",
                       description="Prints one scene JSON per line, exactly what the placer node publishes on "
                                   "/zebra_sim/scene for the same parameters.")
    p.add_argument("--steps", type=int, default=1, help="number of steps (>= 1)")
    for name in ("seed", "start_step", "world", "strategy"):  # not given: the parameter file's, else the default
        add_option(p, spec_of(PlacerConfig, name), default=None)
    p.add_argument("--params-file", type=Path, default=None,
                   help="ROS 2 parameter YAML (e.g. config/placer.yaml); --set and flags override it")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="override one placer parameter (YAML value), e.g. --set count_max=50")
    p.add_argument("--out", type=Path, default=None, help="write the JSON lines to this file instead of stdout")
    add_json_flag(p)
    p.set_defaults(func=cmd_place)


def placer_values(args: argparse.Namespace) -> dict[str, Any]:
    """Parameter values from the file, ``--set`` and the dedicated flags, in that order of precedence."""
    from zebra_sim_ros.params import load_params_file

    values: dict[str, Any] = load_params_file(str(args.params_file), "placer") if args.params_file else {}
    values.update(parse_set(item) for item in args.set)
    for flag, key in (("seed", "seed"), ("world", "world"), ("strategy", "strategy"), ("start_step", "start_step")):
        if getattr(args, flag, None) is not None:
            values[key] = getattr(args, flag)
    return values


def cmd_place(args: argparse.Namespace) -> Summary:
    """Generate ``--steps`` scenes."""
    from zebra_sim_ros.placement.config import PlacerConfig
    from zebra_sim_ros.placement.placer import Placer
    from zebra_sim_ros.world.world import load_world
    from zebra_sim_ros.zebra.asset import load_library

    if args.steps < 1:
        raise ParameterError("--steps", args.steps, ">= 1")
    cfg = PlacerConfig.from_params(placer_values(args))
    t0 = time.perf_counter()
    world = load_world(cfg.world, cfg.terrain_prim, cfg.world_seed)
    placer = Placer(cfg, world, load_library())
    t_setup = time.perf_counter() - t0
    out = open(args.out, "w", encoding="utf-8") if args.out else sys.stdout  # noqa: SIM115
    placed, requested = [], []
    t1 = time.perf_counter()
    try:
        for step in range(cfg.start_step, cfg.start_step + args.steps):
            scene = placer.scene(step)
            placed.append(scene.placed)
            requested.append(scene.requested)
            out.write(scene.to_json() + "\n")
    finally:
        if args.out:
            out.close()
    seconds = time.perf_counter() - t1
    return {"steps": args.steps, "seed": cfg.seed, "world": world.name, "strategy": cfg.strategy,
            "zebras_requested": int(sum(requested)), "zebras_placed": int(sum(placed)),
            "setup_seconds": round(t_setup, 3), "seconds_per_step": round(seconds / args.steps, 4),
            "out": str(args.out) if args.out else None}
