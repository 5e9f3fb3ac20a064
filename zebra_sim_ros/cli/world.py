"""``zebra-sim world ...``: list the built-in worlds, export one to USD, draw a top-down preview map."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.cli.common import Summary, add_json_flag
from zebra_sim_ros.errors import ParameterError


def register(sub: Any) -> None:
    """Add the ``world`` subcommand group."""
    p = sub.add_parser("world", help="built-in worlds: list, export to USD, preview map")
    wsub = p.add_subparsers(dest="world_command", required=True, metavar="ACTION")

    ls = wsub.add_parser("list", help="the built-in world presets, one line each")
    add_json_flag(ls)
    ls.set_defaults(func=cmd_list)

    e = _preset_parser(wsub, "export", "generate a preset world and write it as a USD stage (z up, metres)",
                       "USD file to write (.usd, .usda or .usdc)", "world seed (>= 0): same seed, same world")
    add_json_flag(e)
    e.set_defaults(func=cmd_export)

    v = _preset_parser(wsub, "preview", "top-down map of a preset world: ground colours, hillshade, vegetation",
                       "PNG file to write", "world seed (>= 0)")
    v.add_argument("--px-per-m", type=float, default=2.0, help="image pixels per metre (0.5..8)")
    add_json_flag(v)
    v.set_defaults(func=cmd_preview)


def _preset_parser(wsub: Any, name: str, help_text: str, out_help: str, seed_help: str) -> argparse.ArgumentParser:
    """A subcommand that writes ``out`` from the world of ``--preset`` and ``--seed`` (checked by :func:`_check`)."""
    p: argparse.ArgumentParser = wsub.add_parser(name, help=help_text)
    p.add_argument("out", type=Path, help=out_help)
    p.add_argument("--preset", default="savanna", help="world preset (see 'zebra-sim world list')")
    p.add_argument("--seed", type=int, default=0, help=seed_help)
    return p


def _check(args: argparse.Namespace) -> None:
    from zebra_sim_ros.world.presets import PRESETS

    if args.preset not in PRESETS:
        raise ParameterError("--preset", args.preset, f"one of {sorted(PRESETS)}")
    if args.seed < 0:
        raise ParameterError("--seed", args.seed, "an integer >= 0")


def cmd_list(args: argparse.Namespace) -> Summary:
    """Print the presets."""
    from zebra_sim_ros.world.presets import DEFAULT_PRESET, PRESETS

    width = max(len(n) for n in PRESETS)
    for name, p in PRESETS.items():
        mark = " (default)" if name == DEFAULT_PRESET else ""
        print(f"{name:<{width}}  {p.description}{mark}")
    return {"worlds": [{"name": n, "description": p.description, "size_m": p.terrain.size_m}
                       for n, p in PRESETS.items()], "default": DEFAULT_PRESET}


def cmd_export(args: argparse.Namespace) -> Summary:
    """Generate and write the world."""
    from zebra_sim_ros.world.usd_io import export_world_usd
    from zebra_sim_ros.world.world import USD_SUFFIXES, generate_world

    _check(args)
    if args.out.suffix.lower() not in USD_SUFFIXES[:3]:
        raise ParameterError("out", str(args.out), "a path ending in .usd, .usda or .usdc")
    t0 = time.perf_counter()
    world = generate_world(args.preset, args.seed)
    t_gen = time.perf_counter() - t0
    export_world_usd(world, args.out)
    seconds = time.perf_counter() - t0
    x0, y0, x1, y1 = world.terrain.bounds
    ny, nx = world.terrain.shape
    tris = 2 * (ny - 1) * (nx - 1)
    counts = world.instance_count()
    print(f"wrote {args.out}: {world.name} seed {world.seed}, {x1 - x0:.0f} x {y1 - y0:.0f} m terrain "
          f"({tris} triangles), {sum(counts.values())} instances of {len(counts)} prototypes, "
          f"{len(world.obstacles)} obstacles; generated in {t_gen:.2f} s, total {seconds:.2f} s")
    return {"path": str(args.out), "preset": world.name, "seed": world.seed, "bytes": args.out.stat().st_size,
            "size_m": [x1 - x0, y1 - y0], "triangles": tris, "instances": counts,
            "obstacles": len(world.obstacles), "seconds": round(seconds, 3)}


def preview_image(world: Any, px_per_m: float = 2.0) -> NDArray[np.uint8]:
    """Top-down RGB map (H, W, 3) uint8 of a world, north up: hillshaded ground colours, tree crowns with
    shadows, bushes, rocks, grass dots, and the placeable rectangle in white."""
    import cv2

    hf = world.terrain
    rgb = world.ground_colors().astype(np.float64)
    gy, gx = np.gradient(hf.heights.astype(np.float64), hf.resolution)
    n = np.stack([-gx, -gy, np.ones_like(gx)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    sun = np.array([-0.5, 0.5, 0.7])  # from the north-west, as maps are lit
    shade = np.clip(n @ (sun / np.linalg.norm(sun)), 0, 1)
    img = rgb * (0.35 + 0.8 * shade)[..., None]
    x0, y0, x1, y1 = hf.bounds
    w, h = int(round((x1 - x0) * px_per_m)), int(round((y1 - y0) * px_per_m))
    img = cv2.resize(img[::-1].astype(np.float32), (w, h), interpolation=cv2.INTER_LINEAR)

    def px(xy: NDArray[np.float64]) -> NDArray[np.int32]:
        return np.stack([(xy[:, 0] - x0) * px_per_m, (y1 - xy[:, 1]) * px_per_m], 1).round().astype(np.int32)

    order = {"grass": 0, "rock": 1, "bush": 2, "tree": 3}
    for name, inst in sorted(world.vegetation.items(), key=lambda kv: order.get(kv[1].kind, 0)):
        v, _, c = world.prototypes[name]
        top = v[:, 2] >= np.percentile(v[:, 2], 50)
        col = tuple(float(a) for a in c[top].mean(axis=0))
        crown = float(np.max(np.hypot(v[:, 0], v[:, 1])))
        p = px(inst.positions[:, :2])
        if inst.kind == "grass":
            ok = (p[:, 0] >= 0) & (p[:, 0] < w) & (p[:, 1] >= 0) & (p[:, 1] < h)
            img[p[ok, 1], p[ok, 0]] = 0.5 * img[p[ok, 1], p[ok, 0]] + 0.5 * np.asarray(col, dtype=np.float32)
            continue
        radii = np.maximum(crown * inst.scale * px_per_m, 1.0)
        if inst.kind == "tree":
            off = np.array([0.35, 0.35]) * radii[:, None]
            for q, r in zip((p + off).astype(np.int32), radii, strict=True):
                cv2.circle(img, (int(q[0]), int(q[1])), int(round(r)), (0.1, 0.1, 0.08), -1, cv2.LINE_AA)
        dark = tuple(0.6 * a for a in col)
        for q, r in zip(p, radii, strict=True):
            cv2.circle(img, (int(q[0]), int(q[1])), int(round(r)), col, -1, cv2.LINE_AA)
            if r >= 3:
                cv2.circle(img, (int(q[0]), int(q[1])), int(round(r)), dark, 1, cv2.LINE_AA)
    px0, py0, px1, py1 = world.placeable
    corners = px(np.array([[px0, py1], [px1, py0]], dtype=np.float64))
    cv2.rectangle(img, tuple(int(a) for a in corners[0]), tuple(int(a) for a in corners[1]), (1.0, 1.0, 1.0), 1)
    # linear RGB -> sRGB for viewing
    out = np.where(img <= 0.0031308, 12.92 * img, 1.055 * np.power(np.clip(img, 0, 1), 1 / 2.4) - 0.055)
    u8 = np.ascontiguousarray(np.clip(out * 255 + 0.5, 0, 255).astype(np.uint8))
    label = f"{world.name}, seed {world.seed}, {x1 - x0:.0f} m x {y1 - y0:.0f} m, north up"
    (tw, th), _ = cv2.getTextSize(label, cv2.FONT_HERSHEY_SIMPLEX, 0.6, 1)
    u8[:th + 14, :tw + 14] //= 3
    cv2.putText(u8, label, (7, th + 6), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255), 1, cv2.LINE_AA)
    return np.asarray(u8)


def cmd_preview(args: argparse.Namespace) -> Summary:
    """Draw the preview map."""
    import cv2

    from zebra_sim_ros.world.world import generate_world

    _check(args)
    if not 0.5 <= args.px_per_m <= 8:
        raise ParameterError("--px-per-m", args.px_per_m, "0.5..8")
    if args.out.suffix.lower() != ".png":
        raise ParameterError("out", str(args.out), "a path ending in .png")
    t0 = time.perf_counter()
    world = generate_world(args.preset, args.seed)
    img = preview_image(world, args.px_per_m)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(args.out), img[..., ::-1]):
        raise ParameterError("out", str(args.out), "a writable PNG path")
    print(f"wrote {args.out} ({img.shape[1]}x{img.shape[0]}): {world.name} seed {world.seed}")
    return {"out": str(args.out), "preset": world.name, "seed": world.seed, "width": int(img.shape[1]),
            "height": int(img.shape[0]), "seconds": round(time.perf_counter() - t0, 3)}
