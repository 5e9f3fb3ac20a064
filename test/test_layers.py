"""The package's layers point one way: read every module's imports (module level and inside functions) with ``ast``
and check the import graph. No module is run, so this needs neither ROS nor a GPU.

Rules: (a) no import cycle among the package's modules; (b) no module imports a private name (``_x``) from another
module of the package; (c) geometry and world sit at the bottom; rendering takes scenes as messages (not placement's
types) and imports nothing from labels, detection, recording or the front-ends; only the ROS adapters (``nodes``;
``cli`` and ``graph``, which start the processes) import rclpy or ROS message packages.

Edges that break a rule today are listed in the ALLOWED_* sets below, each with the edge it names: delete an entry
when its module is fixed (the test then fails if the edge comes back, and also when an entry is no longer needed).
"""

from __future__ import annotations

import ast
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

PACKAGE = "zebra_sim_ros"
ROOT = Path(__file__).resolve().parents[1] / PACKAGE

# Lower layers and the packages they must not import from.
FORBIDDEN: dict[str, tuple[str, ...]] = {
    "geometry": ("placement", "rendering", "labels", "detection", "recording", "nodes", "cli", "dataset", "graph"),
    "world": ("placement", "rendering", "labels", "detection", "recording", "nodes", "cli", "dataset", "graph"),
    # Rendering takes scenes as messages (zebra_sim_ros.messages), not placement's types.
    "rendering": ("placement", "labels", "detection", "recording", "nodes", "cli", "dataset", "graph"),
}
# Subpackages that may talk to ROS itself.
ROS_ALLOWED = ("nodes", "cli", "graph")

# --- what breaks a rule today ------------------------------------------------------------------------------------
# (a) edges that close an import cycle: (importer, imported module), left out of the graph before looking for cycles.
ALLOWED_CYCLE: set[tuple[str, str]] = set()
# (b) private names imported from another module: (importer, imported module, name).
ALLOWED_PRIVATE: set[tuple[str, str, str]] = set()
# (c) layer edges (importer, imported module) against FORBIDDEN.
ALLOWED_LAYER: set[tuple[str, str]] = set()
# (c) ROS imports outside ROS_ALLOWED: (importer, ROS module).
ALLOWED_ROS: set[tuple[str, str]] = set()


@dataclass(frozen=True)
class Import:
    """One import statement's target: the package module it reaches, and the name taken from it (or None)."""

    importer: str
    module: str  # a package module, or an outside one (``rclpy.node``)
    name: str | None


def _module_name(path: Path) -> str:
    rel = path.relative_to(ROOT.parent).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(ROOT.rglob("*.py"))}


MODULES = _modules()


def _absolute(importer: str, is_package: bool, node: ast.ImportFrom) -> str:
    """The module ``from X import ...`` names, relative imports resolved against ``importer``."""
    if node.level == 0:
        return node.module or ""
    parts = importer.split(".")
    base = parts[: len(parts) - node.level + (1 if is_package else 0)]
    return ".".join(base + ([node.module] if node.module else []))


def read_imports(importer: str, source: str, is_package: bool = False) -> list[Import]:
    """Every import in a module's source, at any depth (functions, ``if TYPE_CHECKING:`` blocks, try blocks)."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out += [Import(importer, a.name, None) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = _absolute(importer, is_package, node)
            for a in node.names:
                sub = f"{base}.{a.name}"
                if sub in MODULES:  # ``from pkg import module``
                    out.append(Import(importer, sub, None))
                else:
                    out.append(Import(importer, base, a.name))
    return out


IMPORTS = {m: read_imports(m, p.read_text(), p.name == "__init__.py") for m, p in MODULES.items()}


def _graph(imports: dict[str, list[Import]] = IMPORTS) -> dict[str, set[str]]:
    """Package module -> the package modules it imports."""
    g: dict[str, set[str]] = defaultdict(set)
    for m, imps in imports.items():
        for i in imps:
            if i.module in MODULES and i.module != m:
                g[m].add(i.module)
    return g


def _layer(module: str) -> str:
    """The subpackage a module belongs to (``zebra_sim_ros.world.usd_io`` -> ``world``); "" for top-level ones."""
    parts = module.split(".")
    return parts[1] if len(parts) > 2 or (len(parts) == 2 and MODULES[module].name == "__init__.py") else ""


def _cycles(g: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(g.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(set(g) | {w for ws in g.values() for w in ws}):
        if v not in index:
            visit(v)
    return found


def test_the_graph_is_read() -> None:
    # A broken reader would pass every rule: the graph must hold edges we know are there.
    g = _graph()
    assert "zebra_sim_ros.world.model" in g["zebra_sim_ros.world.usd_io"]
    assert "zebra_sim_ros.graph.spec" in g["zebra_sim_ros.cli.up"]  # imported inside cmd_up only
    assert len(MODULES) > 50


def test_no_import_cycle() -> None:
    g = _graph()
    edges = {(m, d) for m, deps in g.items() for d in deps}
    assert ALLOWED_CYCLE - edges == set(), "fixed: delete these entries from ALLOWED_CYCLE"
    assert _cycles({m: deps - {d for a, d in ALLOWED_CYCLE if a == m} for m, deps in g.items()}) == []


def _private_imports() -> set[tuple[str, str, str]]:
    return {(i.importer, i.module, i.name) for imps in IMPORTS.values() for i in imps
            if i.module in MODULES and i.module != i.importer and i.name is not None
            and i.name.startswith("_") and not (i.name.startswith("__") and i.name.endswith("__"))}


def test_no_private_names_across_modules() -> None:
    found = _private_imports()
    assert found - ALLOWED_PRIVATE == set(), "private names imported from another module"
    assert ALLOWED_PRIVATE - found == set(), "fixed: delete these entries from ALLOWED_PRIVATE"


def _layer_edges() -> set[tuple[str, str]]:
    return {(m, d) for m, deps in _graph().items() for d in deps
            if _layer(d) in FORBIDDEN.get(_layer(m), ())}


def test_layers_point_one_way() -> None:
    found = _layer_edges()
    assert found - ALLOWED_LAYER == set(), "a lower layer imports from a higher one"
    assert ALLOWED_LAYER - found == set(), "fixed: delete these entries from ALLOWED_LAYER"


def _is_ros(module: str) -> bool:
    top = module.split(".")[0]
    return top in ("rclpy", "rosidl_runtime_py", "rosidl_parser") or top.endswith("_msgs")


def _ros_imports() -> set[tuple[str, str]]:
    return {(i.importer, i.module) for imps in IMPORTS.values() for i in imps
            if _is_ros(i.module) and _layer(i.importer) not in ROS_ALLOWED}


def test_only_the_adapters_import_ros() -> None:
    found = _ros_imports()
    assert found - ALLOWED_ROS == set(), "rclpy or ROS messages imported outside nodes/ (and cli/, graph/)"
    assert ALLOWED_ROS - found == set(), "fixed: delete these entries from ALLOWED_ROS"


def test_the_reader_sees_every_import() -> None:
    # Module level, in a function, relative, and ``from package import module``: all edges.
    src = ("from zebra_sim_ros.rendering.renderer import _unweld\n"
           "def f():\n    from zebra_sim_ros.world import usd_io\n"
           "    from .terrain import Heightfield\n")
    got = {(i.module, i.name) for i in read_imports("zebra_sim_ros.world.x", src)}
    assert got == {("zebra_sim_ros.rendering.renderer", "_unweld"), ("zebra_sim_ros.world.usd_io", None),
                   ("zebra_sim_ros.world.terrain", "Heightfield")}


def test_the_cycle_finder_finds_cycles() -> None:
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []
