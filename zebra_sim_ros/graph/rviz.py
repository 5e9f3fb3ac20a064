"""An RViz configuration for one graph: the package's ``zebra_sim.rviz`` (drawn for the default three drones, no
namespace) rewritten for the graph's cameras and namespace, so that ``rviz2 -d`` shows every drone of a ``zebra-sim up
--drones N --namespace /g1`` run.

The file's displays are of three kinds, told apart by their topics: the world's (no drone in the topic: the grid,
TF, the placed zebras), those drawn for every drone (the same class and topic, less the drone, for each drone the
file shows: the detection images), and those of one drone only (drone_0's labelled 3D boxes and raw image, off until
ticked). The world's are kept; an every-drone display is drawn once per camera of the graph where its first copy
stood (its name's ``drone_N`` made the camera's); a one-drone display is kept where the graph has that drone; every
topic is moved into the namespace, a relative one too (``drone_0/...`` counts as drone 0's). Displays inside a group
(``rviz_common/Group``) are moved into the namespace but not drawn per drone. RViz's TF display and its clock read
``/tf``, ``/tf_static`` and ``/clock``, which a namespaced graph remaps: :func:`rviz_command` says how to start RViz
on them.
"""

from __future__ import annotations

import copy
import re
import shlex
from collections.abc import Collection, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

from zebra_sim_ros.graph.spec import global_remaps

RVIZ_FILE = "zebra_sim.rviz"  # in the config folder, installed as share/zebra_sim_ros/config/zebra_sim.rviz
_DRONE = re.compile(r"^(/?)drone_(\d+)/")


def _topic(display: dict[str, Any]) -> str:
    """The topic a display shows ("" when it has none)."""
    topic = display.get("Topic")
    value = topic.get("Value", "") if isinstance(topic, dict) else ""
    return value if isinstance(value, str) else ""


def _drone_of(display: dict[str, Any]) -> int | None:
    """The drone whose topic a display shows (``/drone_2/...``: 2), or None for the world's displays."""
    m = _DRONE.match(_topic(display))
    return int(m.group(2)) if m else None


def _kind(display: dict[str, Any]) -> tuple[str, str]:
    """What a display of a drone shows whichever drone it is: its class and its topic less the drone."""
    return str(display.get("Class", "")), _DRONE.sub(r"\1drone_*/", _topic(display))


def _every_display(displays: list[dict[str, Any]]) -> Iterator[dict[str, Any]]:
    """``displays`` and, depth first, those inside their groups (``rviz_common/Group``'s ``Displays``)."""
    for d in displays:
        yield d
        inner = d.get("Displays")
        if isinstance(inner, list):
            yield from _every_display([x for x in inner if isinstance(x, dict)])


def _namespaced(displays: list[dict[str, Any]], namespace: str) -> None:
    """Every topic of ``displays`` (those inside groups too) moved into ``namespace``, in place."""
    for d in _every_display(displays):
        if topic := _topic(d):
            d["Topic"]["Value"] = f"{namespace}{topic}" if topic.startswith("/") else f"{namespace}/{topic}"


def _switch_off(displays: list[dict[str, Any]], off: set[str]) -> None:
    """The displays (those inside groups too) of the topics ``off`` (absolute) switched off, in place."""
    for d in _every_display(displays):
        if (topic := _topic(d)) and "/" + topic.lstrip("/") in off:
            d["Enabled"] = False


def _move(displays: list[dict[str, Any]], moved: Mapping[str, str]) -> None:
    """The displays (those inside groups too) of the topics ``moved``'s keys (absolute) shown on its values instead,
    in place."""
    for d in _every_display(displays):
        if (topic := _topic(d)) and (to := moved.get("/" + topic.lstrip("/"))) is not None:
            d["Topic"]["Value"] = to


def rviz_config(base: dict[str, Any], drones: Sequence[str], namespace: str = "",
                off: Collection[str] = (), moved: Mapping[str, str] | None = None) -> dict[str, Any]:
    """``base`` (the package file, parsed) for a graph of ``drones`` (``drone_0``, ``drone_1`` ...) in ``namespace``
    ("" or ``/g1``): each every-drone display drawn once per camera, in drone order, where the file's first copy
    stood (the others dropped); a display of one drone kept where the graph has that drone; the rest in the file's
    order; the displays of the topics ``off`` (as the file names them: those of a node this graph leaves out)
    switched off; those of the topics ``moved``'s keys shown on its values (absolute; a node of this graph that
    publishes under other names); every topic moved into the namespace. ``base`` is left as it is; ValueError when
    it is not an RViz configuration (no ``Visualization Manager`` with a list of ``Displays``)."""
    manager = base.get("Visualization Manager") if isinstance(base, dict) else None
    displays = manager.get("Displays") if isinstance(manager, dict) else None
    if not isinstance(displays, list) or not all(isinstance(d, dict) for d in displays):
        raise ValueError("not an RViz configuration: no 'Visualization Manager' with a list of 'Displays'")
    shown = {_drone_of(d) for d in displays} - {None}
    # the kinds every drone the file shows has: drawn for each camera
    every = {_kind(d) for d in displays if _drone_of(d) is not None}
    every = {k for k in every if all(any(_drone_of(d) == n and _kind(d) == k for d in displays) for n in shown)}
    new: list[dict[str, Any]] = []
    drawn: set[tuple[str, str]] = set()
    for d in displays:
        n = _drone_of(d)
        if n is None:
            new.append(copy.deepcopy(d))
        elif _kind(d) not in every:
            if n < len(drones):  # one drone's own display, kept where this graph has that drone
                new.append(copy.deepcopy(d))
        elif _kind(d) not in drawn:
            drawn.add(_kind(d))
            for name in drones:
                c = copy.deepcopy(d)
                c["Name"] = re.sub(rf"\bdrone_{n}\b", name, str(c.get("Name", "")))
                c["Topic"]["Value"] = _DRONE.sub(rf"\g<1>{name}/", _topic(d))
                new.append(c)
    _switch_off(new, {"/" + t.lstrip("/") for t in off})
    _move(new, {"/" + a.lstrip("/"): "/" + b.lstrip("/") for a, b in (moved or {}).items()})
    if namespace:
        _namespaced(new, namespace)
    out = copy.deepcopy(base)
    out["Visualization Manager"]["Displays"] = new
    return out


def cloud_display(topic: str, reliability: str = "reliable") -> dict[str, Any]:
    """An RViz PointCloud2 display of a camera's point cloud (absolute ``topic``, published with ``reliability``,
    reliable or best_effort, which it subscribes alike), each point in its colour."""
    return {"Class": "rviz_default_plugins/PointCloud2", "Name": topic.strip("/").replace("/", " "), "Enabled": True,
            "Color Transformer": "RGB8", "Position Transformer": "XYZ", "Style": "Points", "Size (Pixels)": 2,
            "Decay Time": 0, "Use Fixed Frame": True, "Selectable": True, "Value": True,
            "Topic": {"Value": topic, "Depth": 5, "Durability Policy": "Volatile", "History Policy": "Keep Last",
                      "Reliability Policy": "Reliable" if reliability == "reliable" else "Best Effort"}}


def rviz_view(config: Path, drones: Sequence[str], namespace: str = "",
              off: Collection[str] = (), moved: Mapping[str, str] | None = None,
              clouds: Sequence[tuple[str, str]] = ()) -> dict[str, Any] | None:
    """:func:`rviz_config` of ``config``/zebra_sim.rviz, and a :func:`cloud_display` for each of the cameras' point
    clouds ``clouds`` (absolute topic and reliability: :func:`~zebra_sim_ros.graph.spec.cloud_topics`); None when the
    config folder has no file. ValueError naming the file when it cannot be read or is not an RViz configuration."""
    import yaml

    src = Path(config) / RVIZ_FILE
    if not src.is_file():
        return None
    try:
        view = rviz_config(yaml.safe_load(src.read_text()), drones, namespace, off, moved)
    except (OSError, UnicodeDecodeError, yaml.YAMLError, ValueError) as exc:
        raise ValueError(f"{src}: {exc}") from exc
    view["Visualization Manager"]["Displays"] += [cloud_display(t, reliability) for t, reliability in clouds]
    return view


def write_rviz(view: dict[str, Any], dest: Path) -> Path:
    """Write a view (:func:`rviz_view`) to ``dest`` (its folder made if needed)."""
    import yaml

    dest.parent.mkdir(parents=True, exist_ok=True)
    dest.write_text(yaml.safe_dump(view, sort_keys=False))
    return dest


def rviz_command(path: Path, namespace: str = "") -> str:
    """The command line that starts RViz on ``path`` for a graph in ``namespace``: on the graph's simulated time,
    with its ``/tf``, ``/tf_static`` and ``/clock`` remapped into the namespace when it has one (a shell's quoting,
    an absolute path)."""
    remaps = "".join(f" -r {src}:={dst}" for src, dst in global_remaps(namespace))
    return f"rviz2 -d {shlex.quote(str(Path(path).resolve()))} --ros-args -p use_sim_time:=true{remaps}"
