"""``zebra-sim``: the batch and tooling side of zebra_sim_ros, one subcommand per job.

Every subcommand has ``--help``; those that compute something accept ``--json`` and then print one
machine-readable summary line last on stdout. Errors print one line naming the bad value and exit 2;
a summary may carry its own ``exit_code`` (``up``: 1 when a node died, 130 when interrupted).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from typing import Any

from zebra_sim_ros import __version__
from zebra_sim_ros.errors import ParameterError, ZebraSimError

Summary = dict[str, Any]
Command = Callable[[argparse.Namespace], Summary]


def add_json_flag(p: argparse.ArgumentParser) -> None:
    """Give a computing subcommand the shared ``--json`` flag."""
    p.add_argument("--json", action="store_true", help="print one JSON summary line last on stdout")


def parse_size(text: str, name: str = "--size") -> tuple[int, int]:
    """'1280x720' to (width, height), each 16..8192 px; raises :class:`ParameterError` naming ``name``."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise ParameterError(name, text, "WxH in pixels, e.g. 1280x720") from None
    if not (16 <= w <= 8192 and 16 <= h <= 8192):
        raise ParameterError(name, text, "16..8192 pixels per side")
    return w, h


def size_arg(text: str) -> tuple[int, int]:
    """:func:`parse_size` as an argparse ``type`` (argparse names the option in its error)."""
    try:
        return parse_size(text)
    except ParameterError as exc:
        raise argparse.ArgumentTypeError(f"{text!r}: allowed {exc.allowed}") from None


def build_parser() -> argparse.ArgumentParser:
    """The full ``zebra-sim`` argument parser."""
    from zebra_sim_ros.cli import asset, bag, detect, generate, place, render, up, world

    parser = argparse.ArgumentParser(
        prog="zebra-sim",
        description="Synthetic drone imagery of zebras with exact ground truth: batch tools.",
    )
    parser.add_argument("--version", action="version", version=f"zebra_sim_ros {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    asset.register(sub)
    world.register(sub)
    place.register(sub)
    render.register(sub)
    generate.register(sub)
    detect.register(sub)
    bag.register(sub)
    up.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``zebra-sim`` console script; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    func: Command = args.func
    try:
        summary = func(args)
    except ZebraSimError as exc:
        print(f"zebra-sim: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("zebra-sim: interrupted", file=sys.stderr)
        return 130
    if getattr(args, "json", False):
        print(json.dumps(summary, sort_keys=True))
    return int(summary.get("exit_code", 0))


if __name__ == "__main__":
    raise SystemExit(main())
