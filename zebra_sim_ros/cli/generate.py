"""``zebra-sim generate``: a labelled dataset (YOLO and COCO) from the in-process pipeline."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from zebra_sim_ros.cli.common import Summary, add_json_flag, parse_set, parse_size
from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.params import add_option, spec_of


def register(sub: Any) -> None:
    """Add the ``generate`` subcommand."""
    from zebra_sim_ros.dataset.generate import __doc__ as layout
    from zebra_sim_ros.labels.config import LabelFilters
    from zebra_sim_ros.placement.config import PlacerConfig
    from zebra_sim_ros.rendering.config import CameraConfig, add_lens_option

    p = sub.add_parser("generate", help="generate a labelled dataset (images, masks, depth, YOLO, COCO)",
                       description=(layout or "").strip(), formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--frames", type=int, default=None,
                   help="camera images in all (the paper: 36000); required but with --finalize-only")
    p.add_argument("--strategy", default="both",
                   help="far, closeby, low (ground level), nadir (survey drone looking down), both (far and "
                        "closeby, half each), all (the four, a quarter each), or the paper's sets SF (= both) and SC "
                        "(= closeby)")
    p.add_argument("--worlds", default="savanna", help="comma-separated world presets or USD paths, or 'all'")
    p.add_argument("--seed", type=int, default=0,
                   help="seed of the run; each world and strategy draws its own stream from it (in the frame names)")
    add_option(p, spec_of(PlacerConfig, "world_seed"))
    p.add_argument("--out", type=Path, required=True, help="output folder (reruns continue in it)")
    p.add_argument("--workers", type=int, default=1, help="worker processes (each renders on its own)")
    p.add_argument("--shard", default="0/1", help="i/n: make only steps with step %% n == i")
    p.add_argument("--imgsz", default="1280x720", help="WxH, or W for 16:9 (e.g. 1920)")
    add_option(p, spec_of(CameraConfig, "hfov_deg"), "--hfov")
    add_option(p, spec_of(CameraConfig, "sensor_strength"))
    add_option(p, spec_of(CameraConfig, "look"))
    add_lens_option(p)
    add_option(p, spec_of(PlacerConfig, "other_animals_max"), "--other-animals", default=20,
               note="distractors for training sets: on in generate, off in the placer node")
    add_option(p, spec_of(PlacerConfig, "look_randomise"), "--randomise", default=0.5,
               note="on in generate, off in the placer node; half of it is also the placer's ground_recolor "
                    "(terrain brightness and tint)")
    p.add_argument("--format", default="jpg", help="jpg or png for the RGB images")
    p.add_argument("--jpeg-quality", type=int, default=95, help="JPEG quality 1..100")
    p.add_argument("--yolo-box", default="visible", help="box in the YOLO labels: visible (tight) or full (amodal)")
    p.add_argument("--depth", default="float32", help="depth images: float32 (exact), float16 (half size) or none")
    p.add_argument("--val-fraction", type=float, default=0.2, help="share of placements in val")
    for name in ("min_visible_pixels", "min_visible_fraction", "min_box_px", "max_aspect_ratio"):
        add_option(p, spec_of(LabelFilters, name))  # the labeller node's filters, declared once
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help="override a placer parameter")
    p.add_argument("--finalize-only", action="store_true", help="only rebuild COCO, split lists and dataset.yaml")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_json_flag(p)
    p.set_defaults(func=cmd_generate)


def parse_imgsz(text: str) -> tuple[int, int]:
    """'1280x720' or '1920' (16:9) to (width, height)."""
    if "x" in text.lower():
        return parse_size(text, "--imgsz")
    try:
        w = int(text)
    except ValueError:
        raise ParameterError("--imgsz", text, "WxH or W, integers") from None
    try:
        return parse_size(f"{w}x{int(round(w * 9 / 16))}", "--imgsz")
    except ParameterError:
        raise ParameterError("--imgsz", text, "16..8192 pixels per side (W alone: W x 9/16)") from None


def cmd_generate(args: argparse.Namespace) -> Summary:
    """Generate (or continue generating) the dataset."""
    from zebra_sim_ros.dataset.generate import NAMED_SETS, GenerateConfig, finalize, format_histogram, generate
    from zebra_sim_ros.labels.config import LabelFilters
    from zebra_sim_ros.rendering.config import parse_lens
    from zebra_sim_ros.world.presets import PRESETS

    if args.frames is None and not args.finalize_only:
        raise ParameterError("--frames", None, "the number of camera images to generate (only --finalize-only "
                             "goes without)")
    width, height = parse_imgsz(args.imgsz)
    try:
        i, n = (int(v) for v in args.shard.split("/"))
    except ValueError:
        raise ParameterError("--shard", args.shard, "i/n, integers") from None
    worlds = tuple(PRESETS) if args.worlds == "all" else tuple(w.strip() for w in args.worlds.split(",") if w.strip())
    placer: dict[str, Any] = dict(parse_set(item) for item in args.set)
    frames = 1 if args.frames is None else args.frames  # finalizing counts none
    cfg = GenerateConfig(
        out=str(args.out), frames=frames, strategy=NAMED_SETS.get(args.strategy, args.strategy), worlds=worlds,
        seed=args.seed, world_seed=args.world_seed, width=width, height=height, hfov_deg=args.hfov_deg,
        image_format=args.format, jpeg_quality=args.jpeg_quality, workers=args.workers, shard=(i, n),
        sensor_strength=args.sensor_strength, look=args.look, other_animals=args.other_animals_max,
        randomise=args.look_randomise, lens=parse_lens(args.lens).coefficients,
        yolo_box=args.yolo_box, val_fraction=args.val_fraction,
        depth=args.depth, placer=placer,
        filters=LabelFilters(args.min_visible_pixels, args.min_visible_fraction, args.min_box_px,
                             args.max_aspect_ratio))
    if args.finalize_only:
        stats = finalize(args.out, cfg)
    else:
        stats = generate(cfg, (lambda d, t, s: None) if args.quiet else None)
    hist = stats.pop("box_sizes_px")
    others = stats.pop("other_species_labelled")
    by_strategy = stats.pop("box_sizes_px_by_strategy")
    print(f"dataset at {args.out}: {stats}")
    print("labelled boxes by size (sqrt of visible box area)" + "".join(
        f"; {k}: {sum(v.values())}" for k, v in by_strategy.items()))
    for line in format_histogram(hist):
        print(line)
    print("animals of other species (never zebra labels; COCO categories 2+): "
          + (", ".join(f"{k} {v}" for k, v in others.items()) or "none"))
    stats = {**stats, "box_sizes_px": hist, "box_sizes_px_by_strategy": by_strategy, "other_species_labelled": others}
    return {"out": str(args.out), **stats}
