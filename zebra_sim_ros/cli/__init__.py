"""``zebra-sim``: the batch and tooling side of zebra_sim_ros, one subcommand per job.

Every subcommand has ``--help``; those that compute something accept ``--json`` and then print one
machine-readable summary line last on stdout. Errors print one line naming the bad value and exit 2;
a summary may carry its own ``exit_code`` (``up``: 1 when a node died, 130 when interrupted).
"""

from __future__ import annotations

import argparse
import faulthandler
import json
import os
import signal
import sys
from collections.abc import Sequence
from typing import Any

from zebra_sim_ros import __version__
from zebra_sim_ros.cli.common import Command, Summary, add_json_flag, parse_size, size_arg
from zebra_sim_ros.errors import ZebraSimError

__all__ = ["Command", "Summary", "add_json_flag", "build_parser", "main", "parse_size", "size_arg"]


class _Parser(argparse.ArgumentParser):
    """No abbreviations: ``generate --frame 3`` is an error naming ``--frame``, not ``--frames 3``."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs["allow_abbrev"] = False
        super().__init__(*args, **kwargs)


def build_parser() -> argparse.ArgumentParser:
    """The full ``zebra-sim`` argument parser."""
    from zebra_sim_ros.cli import asset, bag, detect, generate, place, predict, render, up, world

    parser = _Parser(
        prog="zebra-sim",
        description="Synthetic drone imagery of zebras with exact ground truth: batch tools.",
    )
    parser.add_argument("--version", action="version", version=f"zebra_sim_ros {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=_Parser)
    asset.register(sub)
    world.register(sub)
    place.register(sub)
    render.register(sub)
    generate.register(sub)
    detect.register(sub)
    predict.register(sub)
    bag.register(sub)
    up.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``zebra-sim`` console script; returns the exit status. A reader that closes the pipe
    early (``zebra-sim bag info x.mcap | head``) ends it quietly, as Unix tools do. ``kill -USR1 <pid>`` prints
    every thread's Python stack on stderr and lets the command go on (where is a long or stuck run)."""
    if sys.__stderr__ is not None:  # the process's own stderr, not a capture of it (the CLI called in-process)
        try:
            faulthandler.register(signal.SIGUSR1, file=sys.__stderr__, all_threads=True, chain=False)
        except (ValueError, OSError, RuntimeError):  # no file descriptor behind it
            pass
    try:
        return _main(argv)
    except BrokenPipeError:
        devnull = os.open(os.devnull, os.O_WRONLY)  # the interpreter's final flush must not fail again
        os.dup2(devnull, sys.stdout.fileno())
        return 141  # 128 + SIGPIPE, what a shell reports for a tool killed by the closed pipe


def _main(argv: Sequence[str] | None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, or a bad option (argparse printed why): its status, as the shell sees it
        return exc.code if isinstance(exc.code, int) else 2
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
