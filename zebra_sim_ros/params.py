"""Parameter specifications shared by nodes and the command line.

A node declares every :class:`ParamSpec` as a ROS parameter (name, default, description), reads the
values once, and hands the dict to :func:`validate`, which checks types and ranges and raises
:class:`~zebra_sim_ros.errors.ParameterError` naming the parameter, the value and what is allowed.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from zebra_sim_ros.errors import ParameterError

ParamValue = bool | int | float | str | list[str] | list[float] | list[int]


@dataclass(frozen=True)
class ParamSpec:
    """One parameter: its default, a one-line description with unit, and what values are allowed."""

    name: str
    default: ParamValue
    description: str
    allowed: str
    check: Callable[[Any], bool]


def in_range(lo: float, hi: float) -> Callable[[Any], bool]:
    """Check: a number in [lo, hi]."""
    return lambda v: isinstance(v, int | float) and not isinstance(v, bool) and lo <= v <= hi


def is_regex(v: Any) -> bool:
    """Check: a string Python's ``re`` compiles."""
    if not isinstance(v, str):
        return False
    try:
        re.compile(v)
    except re.error:
        return False
    return True


def one_of(*choices: str) -> Callable[[Any], bool]:
    """Check: one of the given strings."""
    return lambda v: v in choices


def _coerce(spec: ParamSpec, value: Any) -> Any:
    d = spec.default
    if isinstance(d, bool):
        if not isinstance(value, bool):
            raise ParameterError(spec.name, value, f"true or false ({spec.allowed})")
        return value
    if isinstance(d, int):
        if isinstance(value, bool) or not isinstance(value, int):
            if isinstance(value, float) and value.is_integer():
                return int(value)
            raise ParameterError(spec.name, value, f"an integer, {spec.allowed}")
        return value
    if isinstance(d, float):
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ParameterError(spec.name, value, f"a number, {spec.allowed}")
        return float(value)
    if isinstance(d, str):
        if not isinstance(value, str):
            raise ParameterError(spec.name, value, f"a string, {spec.allowed}")
        return value
    if isinstance(d, list):
        if not isinstance(value, list | tuple):
            raise ParameterError(spec.name, value, f"a list, {spec.allowed}")
        return list(value)
    return value


def validate(specs: Iterable[ParamSpec], values: Mapping[str, Any]) -> dict[str, Any]:
    """Defaults overridden by ``values``, type-coerced and range-checked. Unknown names are errors."""
    specs = list(specs)
    known = {s.name for s in specs}
    unknown = sorted(set(values) - known)
    if unknown:
        raise ParameterError(unknown[0], values[unknown[0]], f"one of the known parameters {sorted(known)}")
    out: dict[str, Any] = {}
    for s in specs:
        v = _coerce(s, values.get(s.name, s.default))
        if not s.check(v):
            raise ParameterError(s.name, v, s.allowed)
        out[s.name] = v
    return out


def load_params_file(path: str, node_name: str) -> dict[str, Any]:
    """Parameters for ``node_name`` from a ROS 2 YAML file (``/**:`` or ``<node>:`` with ``ros__parameters``).

    Entries under ``/**`` apply to every node; a section named after the node (with or without a leading
    slash or namespace) overrides them, as ``ros2 run ... --params-file`` does.
    """
    import yaml

    try:
        with open(path, encoding="utf-8") as f:
            doc = yaml.safe_load(f) or {}
    except OSError as exc:
        raise ParameterError("params_file", path, f"a readable YAML file ({exc.strerror})") from exc
    except yaml.YAMLError as exc:
        raise ParameterError("params_file", path, f"valid YAML ({exc})") from exc
    if not isinstance(doc, dict):
        raise ParameterError("params_file", path, "a mapping of node names to ros__parameters")
    out: dict[str, Any] = {}
    for key in sorted(doc, key=lambda k: k != "/**"):  # wildcard first, specific sections override
        section = doc[key]
        name = str(key).rsplit("/", 1)[-1]
        if key == "/**" or name == node_name:
            params = section.get("ros__parameters", {}) if isinstance(section, dict) else {}
            out.update(params or {})
    return out


def markdown_table(specs: Iterable[ParamSpec]) -> str:
    """The README's parameter table of a node (a test keeps the README equal to the specs)."""
    def default(v: ParamValue) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if v == "":
            return "''"
        return str(v).replace("|", "\\|")

    rows = ["| parameter | default | meaning (unit) | allowed |", "| --- | --- | --- | --- |"]
    for s in specs:
        cells = [f"`{s.name}`", f"`{default(s.default)}`", s.description.replace("|", "\\|"),
                 s.allowed.replace("|", "\\|")]
        rows.append("| " + " | ".join(cells) + " |")
    return "\n".join(rows)
