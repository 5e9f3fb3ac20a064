"""``zebra-sim asset ...``: build the zebra asset, inspect it, prune other versions' caches, draw its preview sheet."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from zebra_sim_ros.cli.common import Summary, add_json_flag
from zebra_sim_ros.errors import ParameterError

if TYPE_CHECKING:
    from zebra_sim_ros.zebra.asset import CacheFolder


def register(sub: Any) -> None:
    """Add the ``asset`` subcommand group."""
    p = sub.add_parser("asset", help="the procedural zebra asset: build, info, prune, preview")
    asub = p.add_subparsers(dest="asset_command", required=True, metavar="ACTION")

    b = asub.add_parser("build", help="bake every morph, clip and frame into the cache and write USD files")
    b.add_argument("--out", type=Path, default=None,
                   help="folder for the USD files and coat textures (default: <cache>/zebra-<digest>/usd)")
    b.add_argument("--cache", type=Path, default=None,
                   help="cache root (default: $ZEBRA_SIM_CACHE or ~/.cache/zebra_sim_ros)")
    b.add_argument("--force", action="store_true", help="rebuild even if an intact cache exists")
    b.add_argument("--coat-seed", type=int, default=0, help="seed of the coat written beside the USD files")
    b.add_argument("--coat-size", type=int, default=1024, help="coat texture size in texels (32..4096)")
    add_json_flag(b)
    b.set_defaults(func=cmd_build)

    i = asub.add_parser("info", help="clips, frames, joints, keypoints and mesh sizes of the asset")
    i.add_argument("--cache", type=Path, default=None, help="cache root")
    add_json_flag(i)
    i.set_defaults(func=cmd_info)

    r = asub.add_parser("prune", help="remove the cache's zebra caches and coat stores of other code versions")
    r.add_argument("--cache", type=Path, default=None, help="cache root")
    r.add_argument("--all", action="store_true", dest="everything",
                   help="this version's cache and coat store too (rebuilt on next use; the USD files 'asset "
                   "build' wrote into the cache go with it)")
    r.add_argument("--dry-run", action="store_true", help="list what would be removed, remove nothing")
    add_json_flag(r)
    r.set_defaults(func=cmd_prune)

    v = asub.add_parser("preview", help="contact sheet of clips and frames, side and top views (PNG)")
    v.add_argument("out", type=Path, help="PNG file to write")
    v.add_argument("--morph", default="plains", help="plains, grevy, foal, or another species' morph "
                   "(wildebeest, impala, giraffe, buffalo, cattle, donkey, elephant, rhino)")
    v.add_argument("--clips", default="all", help="comma-separated clip names, or 'all'")
    v.add_argument("--frames-per-clip", type=int, default=4, help="frames shown per clip (1..12)")
    v.add_argument("--coat-seed", type=int, default=0, help="seed of the first individual's coat")
    v.add_argument("--cell", type=int, default=220, help="pixels per view (80..800)")
    v.add_argument("--cache", type=Path, default=None, help="cache root")
    add_json_flag(v)
    v.set_defaults(func=cmd_preview)


def cmd_build(args: argparse.Namespace) -> Summary:
    """Bake the cache and write one USD file and coat per morph."""
    import cv2

    from zebra_sim_ros.zebra.asset import build_library
    from zebra_sim_ros.zebra.coat import bake_coat, random_coat
    from zebra_sim_ros.zebra.skeleton import MORPHS
    from zebra_sim_ros.zebra.usd import write_usd

    t0 = time.perf_counter()
    lib = build_library(args.cache, force=args.force)
    t_bake = time.perf_counter() - t0
    out: Path = args.out or lib.root / "usd"
    out.mkdir(parents=True, exist_ok=True)
    files = []
    for name in lib.morphs:
        coat_name = f"zebra_{name}_coat.png"
        tex = bake_coat(MORPHS[name], random_coat(args.coat_seed, MORPHS[name]), args.coat_size)
        cv2.imwrite(str(out / coat_name), tex[..., ::-1])
        files.append(str(write_usd(lib, name, out / f"zebra_{name}.usd", f"./{coat_name}")))
        files.append(str(out / coat_name))
    seconds = time.perf_counter() - t0
    print(f"zebra asset {lib.manifest['digest']}: {len(lib.morphs)} morphs x {lib.n_frames} frames "
          f"({len(lib.clip_names)} clips) baked in {t_bake:.1f} s")
    print(f"cache: {lib.root}")
    for f in files:
        print(f"wrote {f}")
    _say_other_versions(lib.root.parent)
    return {"cache": str(lib.root), "digest": lib.manifest["digest"], "morphs": list(lib.morphs),
            "frames": lib.n_frames, "clips": len(lib.clip_names), "files": files,
            "seconds": round(seconds, 3)}


def cmd_info(args: argparse.Namespace) -> Summary:
    """Describe the asset."""
    from zebra_sim_ros.zebra.asset import load_library
    from zebra_sim_ros.zebra.coat_store import CoatStore

    lib = load_library(args.cache)
    store = CoatStore(lib.root.parent, enabled=False)  # looked at, not made
    coats, size = store.usage()
    tris = {f"lod{lod}": int(len(lib.faces(lod))) for lod in lib.manifest["lods"]}  # type: ignore[attr-defined]
    verts = {f"lod{lod}": int(lib.bind_vertices(0, lod).shape[0]) for lod in lib.manifest["lods"]}  # type: ignore[attr-defined]
    print(f"zebra asset {lib.manifest['digest']} at {lib.root}")
    print(f"morphs: {', '.join(lib.morphs)}; triangles {tris}; vertices {verts}")
    print(f"joints: {len(lib.manifest['joints'])}; keypoints: {len(lib.manifest['keypoints'])}")  # type: ignore[arg-type]
    print(f"{'clip':<14}{'frames':>7}{'loop':>6}")
    for name, n, loop in zip(lib.clip_names, lib.clip_frames, lib.clip_loop, strict=True):
        print(f"{name:<14}{int(n):>7}{'yes' if loop else 'no':>6}")
    print(f"{'total':<14}{lib.n_frames:>7}")
    print(f"coat store (the cameras' shared coats; safe to delete): {store.dir}: {coats} coats, {size / 1e6:.1f} MB")
    old = _say_other_versions(lib.root.parent)
    return {"digest": lib.manifest["digest"], "morphs": list(lib.morphs), "frames": lib.n_frames,
            "coat_store": {"dir": str(store.dir), "coats": coats, "bytes": size},
            "other_versions": {"folders": len(old), "bytes": sum(f.bytes for f in old)},
            "clips": dict(zip(lib.clip_names, [int(n) for n in lib.clip_frames], strict=True)),
            "joints": len(lib.manifest["joints"]), "keypoints": len(lib.manifest["keypoints"]),  # type: ignore[arg-type]
            "triangles": tris, "vertices": verts}


def _say_other_versions(root: Path) -> list[CacheFolder]:
    """The cache root's folders ``asset prune`` would remove (other code versions', interrupted builds), said in one
    line when there are any."""
    from zebra_sim_ros.zebra.asset import prune_cache

    old = prune_cache(root, dry_run=True).removed
    if old:
        print(f"other code versions' caches: {len(old)} folders, {sum(f.bytes for f in old) / 1e6:.1f} MB "
              "('zebra-sim asset prune' removes them)")
    return old


def cmd_prune(args: argparse.Namespace) -> Summary:
    """Remove other code versions' caches."""
    from zebra_sim_ros.zebra.asset import default_cache_root, prune_cache

    if args.cache is not None and not args.cache.is_dir():
        raise ParameterError("--cache", str(args.cache), "an existing cache folder")
    root = args.cache or default_cache_root()
    res = prune_cache(root, everything=args.everything, dry_run=args.dry_run)
    verb = "would remove" if args.dry_run else "removed"
    for f in res.removed:
        print(f"{verb} {f.path} ({f.bytes / 1e6:.1f} MB{', this version' if f.current else ''})")
    for f in res.failed:
        print(f"could not remove {f.path} (whole or in part): check its permissions", file=sys.stderr)
    freed = sum(f.bytes for f in res.removed)
    print(f"{verb} {len(res.removed)} folders, {freed / 1e6:.1f} MB; kept {len(res.kept)} under {root}")
    return {"cache": str(root), "dry_run": args.dry_run, ("would_remove" if args.dry_run else "removed"):
            [str(f.path) for f in res.removed], "bytes": freed, "failed": [str(f.path) for f in res.failed],
            "kept": [str(f.path) for f in res.kept], "exit_code": int(bool(res.failed))}


def cmd_preview(args: argparse.Namespace) -> Summary:
    """Draw the contact sheet."""
    import cv2

    from zebra_sim_ros.zebra.asset import load_library
    from zebra_sim_ros.zebra.coat import bake_coat, random_coat
    from zebra_sim_ros.zebra.preview import contact_sheet, individuals_strip
    from zebra_sim_ros.zebra.skeleton import get_morph

    if not 1 <= args.frames_per_clip <= 12:
        raise ParameterError("--frames-per-clip", args.frames_per_clip, "1..12")
    if not 80 <= args.cell <= 800:
        raise ParameterError("--cell", args.cell, "80..800 pixels")
    if args.out.suffix.lower() != ".png":
        raise ParameterError("out", str(args.out), "a path ending in .png")
    morph = get_morph(args.morph)
    lib = load_library(args.cache)
    clips = list(lib.clip_names) if args.clips == "all" else [c.strip() for c in args.clips.split(",")]
    unknown = [c for c in clips if c not in lib.clip_names]
    if unknown:
        raise ParameterError("--clips", ",".join(unknown), f"names among {list(lib.clip_names)}")
    t0 = time.perf_counter()
    tex = bake_coat(morph, random_coat(args.coat_seed, morph), 512)
    sheet = contact_sheet(lib, tex, lib.morphs.index(morph.name), clips, args.frames_per_clip, args.cell)
    strip = individuals_strip(lib, args.coat_seed, sheet.shape[1], args.cell)
    import numpy as np

    img = np.concatenate([strip, sheet], axis=0)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(args.out), img[..., ::-1]):
        raise ParameterError("out", str(args.out), "a writable PNG path")
    print(f"wrote {args.out} ({img.shape[1]}x{img.shape[0]}): {len(clips)} clips x {args.frames_per_clip} frames, "
          f"side and top views, plus individuals of every morph")
    return {"out": str(args.out), "width": int(img.shape[1]), "height": int(img.shape[0]),
            "clips": clips, "seconds": round(time.perf_counter() - t0, 3)}
