"""ROS 2 message definitions for MCAP schemas (encoding ``ros2msg``), read from the installed ``.msg`` files.

rosbag2's convention: the schema of ``pkg/msg/Type`` is the text of ``Type.msg`` followed, for every message
type it uses (recursively, each once), by a line of 80 ``=``, a line ``MSG: pkg/Type`` and that type's text.
"""

from __future__ import annotations

import os
import re
import sys
from functools import lru_cache
from pathlib import Path

from zebra_sim_ros.errors import ZebraSimError

PRIMITIVES = {"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16", "int32", "uint32",
              "int64", "uint64", "string", "wstring", "time", "duration"}
SEPARATOR = "=" * 80


class SchemaError(ZebraSimError):
    """A message definition cannot be found or parsed."""


def _share_dirs() -> list[Path]:
    dirs = [Path(p) / "share" for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    dirs += [Path(sys.prefix) / "share", Path("/opt/ros/jazzy/share")]
    return [d for d in dirs if d.is_dir()]


@lru_cache(maxsize=512)
def msg_text(type_name: str) -> str:
    """The ``.msg`` text of ``pkg/msg/Type`` (or ``pkg/Type``)."""
    parts = type_name.split("/")
    if len(parts) == 3:
        pkg, kind, name = parts
    elif len(parts) == 2:
        (pkg, name), kind = parts, "msg"
    else:
        raise SchemaError(f"message type {type_name!r} is not pkg/msg/Type")
    for share in _share_dirs():
        path = share / pkg / kind / f"{name}.msg"
        if path.is_file():
            return path.read_text()
    raise SchemaError(f"no {pkg}/{kind}/{name}.msg under {[str(d) for d in _share_dirs()]}")


def _dependencies(type_name: str, text: str) -> list[str]:
    pkg = type_name.split("/")[0]
    deps = []
    for line in text.splitlines():
        fields = line.split("#", 1)[0].split()
        if len(fields) < 2 or "=" in fields[1]:  # blank, or a constant
            continue
        base = re.sub(r"\[.*\]$", "", fields[0])
        base = re.sub(r"<=\d+$", "", base)
        if base in PRIMITIVES or base.startswith("string<="):
            continue
        if base == "Header":
            base = "std_msgs/Header"
        full = base if "/" in base else f"{pkg}/{base}"
        p = full.split("/")
        deps.append(f"{p[0]}/msg/{p[-1]}")
    return deps


@lru_cache(maxsize=512)
def schema_text(type_name: str) -> str:
    """The full ``ros2msg`` schema text of ``pkg/msg/Type``, with every dependency appended once."""
    root = msg_text(type_name)
    out = [root.rstrip("\n")]
    seen = {type_name}
    queue = _dependencies(type_name, root)
    while queue:
        dep = queue.pop(0)
        if dep in seen:
            continue
        seen.add(dep)
        text = msg_text(dep)
        pkg, _, name = dep.split("/")
        out.append(f"{SEPARATOR}\nMSG: {pkg}/{name}\n{text.rstrip()}")
        queue += _dependencies(dep, text)
    return "\n".join(out) + "\n"
