"""What every ``zebra-sim`` subcommand shares: the summary type, the ``--json`` flag and the size parser.

A module of its own (not ``cli/__init__``), so the subcommands import it and ``cli/__init__`` imports the
subcommands without an import circle.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

from zebra_sim_ros.errors import ParameterError

Summary = dict[str, Any]
Command = Callable[[argparse.Namespace], Summary]


def parse_set(item: str, example: str = "count_max=50") -> tuple[str, Any]:
    """A ``--set NAME=VALUE`` item as (name, its YAML value); a malformed one is named (``example`` shows one)."""
    import yaml

    name, eq, raw = item.partition("=")
    if not (eq and name.strip()):
        raise ParameterError("--set", item, f"NAME=VALUE, e.g. {example}")
    try:
        return name.strip(), yaml.safe_load(raw)
    except yaml.YAMLError as exc:
        raise ParameterError("--set", item, f"a YAML value after '=' ({exc.__class__.__name__})") from None


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


def detector_options(p: argparse.ArgumentParser) -> None:
    """``--device``, ``--imgsz``, ``--scale``, ``--verifier`` and ``--amp``, mirroring the detector node's
    parameters (``val``, ``predict``, ``bag eval``): the same names, ranges and defaults, so a figure from the
    command line is the node's figure."""
    from zebra_sim_ros.detection.config import DetectorConfig
    from zebra_sim_ros.params import add_option, spec_of

    for name in ("device", "imgsz", "scale", "verifier", "amp"):
        add_option(p, spec_of(DetectorConfig, name))


def count_option(p: argparse.ArgumentParser) -> None:
    """``--count-conf``, mirroring the scorer node's ``count_conf`` (``val``, ``bag eval``): the zebras are
    counted with the detections at it or above."""
    from zebra_sim_ros.detection.config import ScorerConfig
    from zebra_sim_ros.params import add_option, spec_of

    add_option(p, spec_of(ScorerConfig, "count_conf"))


def census_options(p: argparse.ArgumentParser) -> None:
    """``--census-along``, ``--census-across``, ``--census-gate``, ``--census-separation``, ``--drones``, ``--output``,
    ``--census-output``, ``--pose`` and ``--pose-max-gap-s``, mirroring the locator node's census parameters, the
    topics it published and read its poses from and how it matched them to images (``bag census``): the same names
    and ranges; not given (None), the bag's locator's, as it reported them on /diagnostics, else the parameter's
    default."""
    from zebra_sim_ros.detection.config import CENSUS_READS, CENSUS_RULE, LocatorConfig
    from zebra_sim_ros.params import add_option, spec_of

    followed = "not given: the bag's locator's, from its /diagnostics, else this default"
    for name in CENSUS_RULE:
        add_option(p, spec_of(LocatorConfig, name), default=None, note=followed)
    for name in CENSUS_READS:
        note = {"pose": "here: the poses the bag's locator placed its detections from, read back for the cameras' "
                        "positions",
                "pose_max_gap_s": "here: how it matched those poses to its images (above 0: each image's camera "
                                  "position interpolated between two poses)"}.get(
            name, "here: the topic the bag's locator published it on")
        add_option(p, spec_of(LocatorConfig, name), default=None, note=f"{note}; {followed}")
    add_option(p, spec_of(LocatorConfig, "drones"), default=None,
               note="here: the bag's cameras, joined in this order (not given: the bag's locator's order, from its "
                    "/diagnostics, else the bag's cameras, drone_2 before drone_10, as up orders them)")
