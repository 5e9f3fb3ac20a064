"""An RViz configuration for one graph: the package's ``zebra_sim.rviz`` (drawn for the default three drones, no
namespace) rewritten for the graph's cameras and namespace, so that ``rviz2 -d`` shows every drone of a ``zebra-sim up
--drones N --namespace /g1`` run.

The package file's displays are of three kinds, told apart by their topics: the world's (no drone in the topic: the
grid, TF, the placed zebras), those drawn for every drone (a topic of each of drone_0, drone_1 and drone_2: the
detection images), and those drawn for the first drone only (drone_0's labelled 3D boxes and raw image, off until
ticked). The world's and the first drone's are kept, the every-drone ones are drawn again from drone_0's for each
camera, and every topic is moved into the namespace. RViz's TF display and its clock read ``/tf``, ``/tf_static`` and
``/clock``, which a namespaced graph remaps: :func:`rviz_command` says how to start RViz on them.
"""

from __future__ import annotations

import copy
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from zebra_sim_ros.graph.spec import GLOBAL_TOPICS

RVIZ_FILE = "zebra_sim.rviz"  # in the config folder, installed as share/zebra_sim_ros/config/zebra_sim.rviz
_DRONE = re.compile(r"^/drone_(\d+)/")


def _drone_of(display: dict[str, Any]) -> int | None:
    """The drone whose topic a display shows (``/drone_2/...``: 2), or None for the world's displays."""
    topic = display.get("Topic", {}).get("Value", "")
    m = _DRONE.match(topic) if isinstance(topic, str) else None
    return int(m.group(1)) if m else None


def rviz_config(base: dict[str, Any], drones: Sequence[str], namespace: str = "") -> dict[str, Any]:
    """``base`` (the package file, parsed) for a graph of ``drones`` (``drone_0``, ``drone_1`` ...) in ``namespace``
    ("" or ``/g1``): each every-drone display drawn once per camera, in drone order, where the file's first copy
    stood (the others dropped); a display of one drone kept where the graph has that drone; the rest in the file's
    order; every topic moved into the namespace. ``base`` is left as it is."""
    out = copy.deepcopy(base)
    displays: list[dict[str, Any]] = out["Visualization Manager"]["Displays"]
    shown = {_drone_of(d) for d in displays} - {None}
    if not shown:
        raise ValueError("the RViz file shows no drone's topic (/drone_N/...): nothing to draw for each camera")
    # the displays whose topic (less the drone) every drone the file shows has: drawn for each camera
    suffix = {id(d): _DRONE.sub("/", d["Topic"]["Value"]) for d in displays if _drone_of(d) is not None}
    per_drone_suffixes = {s for s in suffix.values()
                          if all(any(_drone_of(d) == k and suffix[id(d)] == s for d in displays) for k in shown)}
    new: list[dict[str, Any]] = []
    drawn: set[str] = set()
    for d in displays:  # in the file's order; an every-drone display becomes one per camera where its first stood
        k = _drone_of(d)
        if k is None:
            new.append(copy.deepcopy(d))
        elif suffix[id(d)] not in per_drone_suffixes:
            if k < len(drones):  # one drone's own display, kept where this graph has that drone
                new.append(copy.deepcopy(d))
        elif suffix[id(d)] not in drawn:
            drawn.add(suffix[id(d)])
            for name in drones:
                c = copy.deepcopy(d)
                c["Name"] = str(c.get("Name", "")).replace(f"drone_{k}", name)
                c["Topic"]["Value"] = f"/{name}{suffix[id(d)]}"
                new.append(c)
    if namespace:
        for d in new:
            if "Topic" in d:
                d["Topic"]["Value"] = f"{namespace}{d['Topic']['Value']}"
    out["Visualization Manager"]["Displays"] = new
    return out


def write_rviz(config: Path, dest: Path, drones: Sequence[str], namespace: str = "") -> Path | None:
    """Write :func:`rviz_config` of ``config``/zebra_sim.rviz to ``dest``; None (nothing written) when the config
    folder has no RViz file."""
    import yaml

    src = Path(config) / RVIZ_FILE
    if not src.is_file():
        return None
    base = yaml.safe_load(src.read_text())
    dest.write_text(yaml.safe_dump(rviz_config(base, drones, namespace), sort_keys=False))
    return dest


def rviz_command(path: Path, namespace: str = "") -> str:
    """The command line that starts RViz on ``path`` for a graph in ``namespace``: on the graph's simulated time,
    with its ``/tf``, ``/tf_static`` and ``/clock`` remapped into the namespace when it has one."""
    remaps = "".join(f" -r {t}:={namespace}{t}" for t in GLOBAL_TOPICS) if namespace else ""
    return f"rviz2 -d {path} --ros-args -p use_sim_time:=true{remaps}"
