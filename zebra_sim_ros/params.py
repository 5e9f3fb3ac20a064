"""Parameters: each declared once, as a field of its stage's frozen config dataclass.

A field made with :func:`param` carries the parameter's whole declaration (:class:`Param`: default, help, unit,
numeric range, choices, whether it may change while the node runs); its name is the field's name. Everything
else is derived from it: the :class:`ParamSpec` tuples the nodes declare as ROS parameters (with descriptors
holding the ranges), ``--help``, CLI options (:func:`add_option`), the README tables and ``config/*.yaml``
(``python -m zebra_sim_ros.graph.spec --write-config config/``). :func:`validate` checks types and ranges and raises
:class:`~zebra_sim_ros.errors.ParameterError` naming the parameter, the value and what is allowed.
"""

from __future__ import annotations

import argparse
import dataclasses
import re
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Self

from zebra_sim_ros.errors import ParameterError

ParamValue = bool | int | float | str | list[str] | list[float] | list[int]
_DECLARATION = "zebra_sim_ros.param"  # the key of a field's metadata that holds its Param


@dataclass(frozen=True)
class ParamSpec:
    """One named parameter as nodes declare it: default, a one-line description (ending with its unit), what
    values are allowed (text for people, ``check`` for code), the numeric range ``lo..hi`` that goes into the ROS
    descriptor (None: not numeric; ``check`` may allow less than the range), and whether it may change while the
    node runs."""

    name: str
    default: ParamValue
    description: str
    allowed: str
    check: Callable[[Any], bool]
    lo: float | None = None
    hi: float | None = None
    runtime: bool = False

    @property
    def meaning(self) -> str:
        """The description, and whether the value may change while the node runs (README tables, YAML comments)."""
        return self.description + (" (can change while running)" if self.runtime else "")


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


def names_list(v: Any) -> bool:
    """Check: a non-empty list of non-empty strings."""
    return len(v) > 0 and all(isinstance(x, str) and x for x in v)


def _number(x: float) -> str:
    """A range bound as people write it: ``0.001``, ``100000``, ``1e6``, ``2^31``, ``2^63-1``."""
    if isinstance(x, int) and x > 10**6:
        if (x + 1) & x == 0:
            return f"2^{x.bit_length()}-1"
        if x & (x - 1) == 0:
            return f"2^{x.bit_length() - 1}"
    return f"{x:g}".replace("e+0", "e").replace("e+", "e")


@dataclass(frozen=True)
class Param:
    """The declaration of one parameter, without its name (the field's name is the parameter's name).

    ``default`` is a tuple for list parameters (the config is frozen; ROS gets a list). ``help`` is one line
    without the unit; ``unit`` is appended to it and to the range. ``lo``/``hi`` bound a number (and go into the
    ROS descriptor); ``choices`` list the allowed strings; ``allowed`` replaces the text derived from them where it
    says more (``count_min..pool_size``); ``check`` adds a rule the range cannot say. ``runtime``: the value may
    change while the node runs (the node applies it), else a change is refused until a restart.
    """

    default: Any
    help: str
    unit: str = ""
    lo: float | None = None
    hi: float | None = None
    choices: tuple[str, ...] = ()
    allowed: str = ""
    check: Callable[[Any], bool] | None = None
    runtime: bool = False

    def field(self) -> Any:
        """A dataclass field with this declaration (typed Any so that ``x: float = Param(...).field()`` checks)."""
        return dataclasses.field(default=self.default, metadata={_DECLARATION: self})

    def allowed_text(self) -> str:
        """What is allowed, for people: ``allowed``, else the choices, the range with its unit, or true/false."""
        unit = f" {self.unit}" if self.unit else ""
        if self.allowed:
            return self.allowed
        if self.choices:
            return (", ".join(self.choices[:-1]) + " or " + self.choices[-1]) if len(self.choices) > 1 \
                else self.choices[0]
        if self.lo is not None and self.hi is not None:
            return f"{_number(self.lo)}..{_number(self.hi)}{unit}"
        if isinstance(self.default, bool):
            return "true or false"
        raise TypeError(f"parameter default {self.default!r} ({self.help}): say what is allowed")

    def spec(self, name: str) -> ParamSpec:
        """The named :class:`ParamSpec` of this declaration."""
        checks: list[Callable[[Any], bool]] = []
        if self.lo is not None and self.hi is not None:
            checks.append(in_range(self.lo, self.hi))
        if self.choices:
            checks.append(one_of(*self.choices))
        if self.check is not None:
            checks.append(self.check)
        default = list(self.default) if isinstance(self.default, tuple) else self.default
        description = f"{self.help}, {self.unit}" if self.unit else self.help
        return ParamSpec(name, default, description, self.allowed_text(), lambda v: all(c(v) for c in checks),
                         self.lo, self.hi, self.runtime)


def param(default: Any, help: str, unit: str = "", *, lo: float | None = None, hi: float | None = None,
          choices: tuple[str, ...] = (), allowed: str = "", check: Callable[[Any], bool] | None = None,
          runtime: bool = False) -> Any:
    """A config dataclass field declaring one parameter (see :class:`Param` for the arguments)."""
    return Param(default, help, unit, lo, hi, choices, allowed, check, runtime).field()


RELIABILITY = ("reliable", "best_effort")  # the QoS reliability a node's qos_reliability parameter may name


def reliability_param(help: str) -> Any:
    """The ``qos_reliability`` field every node has (``reliable`` by default)."""
    return param("reliable", help, choices=RELIABILITY)


def image_reliability_param() -> Any:
    """The ``image_reliability`` of nodes that subscribe camera images (best effort by default: what camera
    drivers offer with the sensor-data QoS; a reliable subscription would receive nothing from them)."""
    return param("best_effort", "QoS reliability of the image subscriptions (best_effort matches camera drivers' "
                 "sensor-data QoS and reliable publishers alike; reliable only matches reliable publishers)",
                 choices=RELIABILITY)


def diagnostics_param() -> Any:
    """The ``diagnostics_period_s`` field every node has: how often it reports its health on /diagnostics
    (:mod:`zebra_sim_ros.health`)."""
    return param(1.0, "how often the node's health (its counts, rates, warnings and errors) is published on "
                 "/diagnostics (diagnostic_msgs/DiagnosticArray; 0: never)", "s", lo=0.0, hi=3600.0)


# Parameters every rclpy node has, which a node's own declarations never list.
ROS_BUILTIN_PARAMS = ("use_sim_time", "start_type_description_service")


def declaration(cls: type, name: str) -> Param:
    """The :class:`Param` of field ``name`` of the config dataclass ``cls``."""
    for f in dataclasses.fields(cls):
        if f.name == name and _DECLARATION in f.metadata:
            return f.metadata[_DECLARATION]  # type: ignore[no-any-return]
    raise KeyError(f"{cls.__name__} declares no parameter {name!r}")


def same_as(cls: type, name: str, **changes: Any) -> Any:
    """A field declaring the parameter of ``cls``'s field ``name`` again, e.g. with another ``help``: where two
    stages share a parameter (camera intrinsics, label filters), its default, unit and range are written once."""
    return dataclasses.replace(declaration(cls, name), **changes).field()


_SPECS: dict[type, tuple[ParamSpec, ...]] = {}


def specs_of(cls: type) -> tuple[ParamSpec, ...]:
    """The :class:`ParamSpec` of every field of ``cls`` declared with :func:`param`, in field order (made once)."""
    if cls not in _SPECS:
        _SPECS[cls] = tuple(f.metadata[_DECLARATION].spec(f.name) for f in dataclasses.fields(cls)
                            if _DECLARATION in f.metadata)
    return _SPECS[cls]


class StageConfig:
    """Base of a stage's frozen config dataclass whose fields are declared with :func:`param`.

    ``from_params`` is the one way from raw values (ROS parameters, a YAML file, CLI options) to a config:
    defaults for what is missing, every value type-coerced and range-checked, then :meth:`check`.
    """

    @classmethod
    def specs(cls) -> tuple[ParamSpec, ...]:
        """The parameters of this stage, in declaration order."""
        return specs_of(cls)

    @classmethod
    def from_params(cls, values: Mapping[str, Any]) -> Self:
        """Validate raw parameter values (missing ones take their defaults) into a config."""
        v = validate(cls.specs(), values)
        cfg = cls(**{k: tuple(x) if isinstance(x, list) else x for k, x in v.items()})
        cfg.check()
        return cfg

    def check(self) -> None:
        """Cross-parameter rules (each parameter alone was checked by its spec); raises :class:`ParameterError`."""

    def as_params(self) -> dict[str, Any]:
        """The config as ROS parameter values (lists for tuples)."""
        return {s.name: list(v) if isinstance(v := getattr(self, s.name), tuple) else v for s in self.specs()}

    def with_changes(self, values: Mapping[str, Any]) -> Self:
        """This config with ``values`` changed, validated as :meth:`from_params` does."""
        return self.from_params({**self.as_params(), **values})


def _coerce(spec: ParamSpec, value: Any) -> Any:
    d = spec.default
    if isinstance(d, bool):
        if not isinstance(value, bool):
            allowed = spec.allowed if spec.allowed == "true or false" else f"true or false ({spec.allowed})"
            raise ParameterError(spec.name, value, allowed)
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
    unknown = sorted(set(values) - known - set(ROS_BUILTIN_PARAMS))
    if unknown:
        raise ParameterError(unknown[0], values[unknown[0]], f"one of the known parameters {sorted(known)}")
    out: dict[str, Any] = {}
    for s in specs:
        v = _coerce(s, values.get(s.name, s.default))
        if not s.check(v):
            raise ParameterError(s.name, v, s.allowed)
        out[s.name] = v
    return out


_FROM_SPEC: Any = object()


def spec_of(cls: type, name: str) -> ParamSpec:
    """The :class:`ParamSpec` of field ``name`` of the config dataclass ``cls`` (for CLI options that mirror it)."""
    for spec in specs_of(cls):
        if spec.name == name:
            return spec
    raise KeyError(f"{cls.__name__} declares no parameter {name!r}")


def add_option(parser: argparse.ArgumentParser, spec: ParamSpec, flag: str = "", default: Any = _FROM_SPEC,
               note: str = "") -> None:
    """An argparse option that mirrors a parameter: ``--name-with-dashes`` (or ``flag``), its type, range and
    help from ``spec``; the default is the parameter's unless ``default`` is given (e.g. None, to tell "not
    given" from a value); ``note`` is appended to the help. A bad value is refused by argparse, naming the option
    and what is allowed. Values are YAML, as with ``-p``."""
    import yaml

    def parse(text: str) -> Any:
        value = text if isinstance(spec.default, str) else yaml.safe_load(text)
        try:
            return validate([spec], {spec.name: value})[spec.name]
        except ParameterError as exc:
            raise argparse.ArgumentTypeError(f"{text!r}: allowed {exc.allowed}") from None

    if default is _FROM_SPEC or default == spec.default:
        shown = f"default {spec.default!r}"
    else:  # None: "not given", which the note explains
        shown = f"the parameter's default {spec.default!r}" if default is None else (
            f"default {default!r}; the parameter's {spec.default!r}")
    text = f"{spec.description}; allowed {spec.allowed} ({shown}){'; ' + note if note else ''}"
    parser.add_argument(flag or "--" + spec.name.replace("_", "-"), type=parse, dest=spec.name,
                        default=spec.default if default is _FROM_SPEC else default, metavar=spec.name.upper(),
                        help=text.replace("%", "%%"))


NAME_TOKEN = r"[A-Za-z_][A-Za-z0-9_]*"  # one name of a ROS name: letters, digits and _, not a digit first
RELATIVE_NAME = re.compile(rf"{NAME_TOKEN}(?:/{NAME_TOKEN})*")  # a relative ROS name (topic, node): a/b/c
ROS_NAME = re.compile(rf"/?{RELATIVE_NAME.pattern}")  # a relative or absolute ROS name: /a/b/c
_NAME_TOKEN = re.compile(NAME_TOKEN)


def _key_tokens(key: str) -> list[str] | None:
    """The names of a node key (``/g1/scorer``: ``g1``, ``scorer``), or None when ROS would refuse it: an empty
    name (``//``, a trailing ``/``), or a name neither a ROS name nor ``*`` or ``**``."""
    parts = (key[1:] if key.startswith("/") else key).split("/")
    ok = all(t in ("*", "**") or _NAME_TOKEN.fullmatch(t) for t in parts)
    return parts if ok else None


def node_pattern(key: str) -> re.Pattern[str]:
    """A parameter file's node key as ROS 2 matches it against a node's fully qualified name: a leading ``/`` added
    where it has none, ``*`` one name, ``**`` any number of names (``/**`` every node, ``/**/scorer`` a scorer in
    any namespace). ValueError for a key ROS refuses (:func:`_key_tokens`)."""
    parts = _key_tokens(str(key))
    if parts is None:
        raise ValueError(f"node key {key!r}: want /name/..., each name letters, digits and _ (or * or **)")
    regex = "".join("(?:/[^/]+)*" if t == "**" else "/[^/]+" if t == "*" else "/" + re.escape(t) for t in parts)
    return re.compile(regex)


def _sections(doc: dict[Any, Any], prefix: str, path: str) -> Iterator[tuple[str, dict[str, Any]]]:
    """A parameter file's ``(node key, ros__parameters)`` pairs in file order, nested keys joined (``/g1:`` holding
    ``scorer:`` is ``/g1/scorer``, as ROS reads it); ParameterError naming what ROS would refuse."""
    for raw, section in doc.items():
        key = f"{prefix}/{str(raw).lstrip('/')}" if prefix else str(raw)
        if not isinstance(section, dict) or not section:
            raise ParameterError("params_file", path, f"under {key!r} a mapping: ros__parameters, or node names")
        if "ros__parameters" in section:
            params = section["ros__parameters"]
            if len(section) > 1 or not isinstance(params, dict):
                raise ParameterError("params_file", path, f"under {key!r} ros__parameters alone, a mapping of "
                                     "parameter names to values")
            yield key, params
        else:
            yield from _sections(section, key, path)


def load_params_file(path: str, node_name: str) -> dict[str, Any]:
    """Parameters for the node ``node_name`` from a ROS 2 YAML file (sections of ``ros__parameters`` under node
    keys, nested keys joined: ``/g1:`` holding ``scorer:`` is ``/g1/scorer``), as ``ros2 run ... --params-file``
    gives them to it: ``node_name`` is its fully qualified name (``/g1/scorer``; without a leading slash, from the
    root); every section whose key matches it (:func:`node_pattern`) applies, in file order, a later one overriding
    an earlier one (rclpy's own overrides for the same file and name: a test compares the two). A file ROS would
    refuse (a malformed key or section) is refused, named, whatever node asks."""
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
    fqn = node_name if node_name.startswith("/") else f"/{node_name}"
    if _key_tokens(fqn) is None or "*" in fqn:
        raise ParameterError("node", node_name, "a node's fully qualified name, /name/...")
    out: dict[str, Any] = {}
    for key, params in _sections(doc, "", path):  # file order: a later section overrides an earlier one, as in ROS
        try:
            pattern = node_pattern(key)
        except ValueError as exc:
            raise ParameterError("params_file", path, str(exc)) from None
        if pattern.fullmatch(fqn):
            out.update(params)
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
        cells = [f"`{s.name}`", f"`{default(s.default)}`", s.meaning.replace("|", "\\|"),
                 s.allowed.replace("|", "\\|")]
        rows.append("| " + " | ".join(cells) + " |")
    return "\n".join(rows)


def replace_tables(readme: str, tables: Mapping[str, Iterable[ParamSpec]]) -> str:
    """``readme`` with each node's parameter table replaced by :func:`markdown_table` of its specs. A table is
    found by its header and first parameter, after the node's section heading (``### The `<node>` node``) where
    there is one; ``ParameterError`` names a node whose table is not there, or the nodes that found one table (the
    one without a heading of its own should get one). Every table is found in the text as given, then replaced."""
    header = "| parameter | default | meaning (unit) | allowed |\n| --- | --- | --- | --- |\n"
    found: dict[int, tuple[str, list[ParamSpec]]] = {}
    for node, specs in tables.items():
        specs = list(specs)
        section = readme.find(f"### The `{node}` node")
        end_of_section = min((i for i in (readme.find("\n### ", section + 1), readme.find("\n## ", section + 1))
                              if i >= 0), default=len(readme)) if section >= 0 else len(readme)
        start = readme.find(header + f"| `{specs[0].name}` |", max(section, 0), end_of_section)
        if start < 0:
            where = "in its section" if section >= 0 else "(it has no section '### The `<node>` node')"
            raise ParameterError("README table", node, f"a table starting with `{specs[0].name}` {where}")
        if start in found:
            other = found[start][0]
            lacking = [n for n in (other, node) if f"### The `{n}` node" not in readme]
            raise ParameterError("README table", node, f"a table of its own ({other} found the same one; give "
                                 f"{' and '.join(lacking) or 'them'} a section '### The `<node>` node')")
        found[start] = (node, specs)
    for start in sorted(found, reverse=True):  # from the end: the earlier tables' places do not move
        end = readme.find("\n\n", start)
        end = len(readme) if end < 0 else end
        readme = readme[:start] + markdown_table(found[start][1]) + readme[end:]
    return readme


# -- config/*.yaml ----------------------------------------------------------------------------------------------
_PLAIN = re.compile(r"[A-Za-z0-9_/][A-Za-z0-9_/.\-]*")


def yaml_value(v: Any) -> str:
    """A parameter value as one line of YAML that reads back as the same value (strings quoted only if needed)."""
    import yaml

    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, list | tuple):
        return "[" + ", ".join(yaml_value(x) for x in v) + "]"
    if isinstance(v, str):
        if _PLAIN.fullmatch(v) and yaml.safe_load(v) == v:
            return v
        return "'" + v.replace("'", "''") + "'"
    return repr(v)


def config_yaml(specs: Iterable[ParamSpec], header: str) -> str:
    """A ``config/<node>.yaml``: ``header`` (comment lines), then every parameter at its default under
    ``/**: ros__parameters:``, each with its description as a comment."""
    lines = [header.rstrip("\n"), "/**:", "  ros__parameters:"]
    lines += [f"    {s.name}: {yaml_value(s.default)}  # {s.meaning}" for s in specs]
    return "\n".join(lines) + "\n"


def yaml_header(executable: str, text: str | None = None) -> str:
    """The comment lines before ``/**:`` of an existing config file's ``text`` (kept when it is rewritten), else
    a standard header for ``executable``."""
    if text is not None:
        head = text.split("\n/**:", 1)[0] if not text.startswith("/**:") else ""
        if head and all(line.startswith("#") for line in head.splitlines()):
            return head + "\n"
    return (f"# Parameters of the {executable} node (ros2 run zebra_sim_ros {executable} --ros-args --params-file "
            f"config/{executable}.yaml).\n# `{executable} --help` lists meaning, unit and allowed range of each.\n")


def write_config(folder: Path, nodes: Mapping[str, Iterable[ParamSpec]]) -> list[Path]:
    """Write ``folder/<node>.yaml`` for every node from its specs (keeping each file's header); the paths written."""
    written = []
    for executable, specs in nodes.items():
        path = folder / f"{executable}.yaml"
        old = path.read_text(encoding="utf-8") if path.is_file() else None
        text = config_yaml(specs, yaml_header(executable, old))
        if text != old:
            path.write_text(text, encoding="utf-8")
            written.append(path)
    return written
