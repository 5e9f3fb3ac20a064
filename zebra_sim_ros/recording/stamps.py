"""The header stamp of a serialized message, read without deserialising it: bags are written with log times equal
to the stamps (one time base: the simulated time of the step; see the placer's ``/clock``).

A CDR message starts with a 4-byte encapsulation header. When a type's first field is a ``std_msgs/Header`` or a
``builtin_interfaces/Time`` (``rosgraph_msgs/Clock``), its stamp (int32 sec, uint32 nanosec) follows at offset 4;
when the first field is an array of a type that starts with one (``visualization_msgs/MarkerArray``,
``tf2_msgs/TFMessage``), the first element's stamp follows the uint32 length, at offset 8. A ``std_msgs/String``
holding one of our JSON messages (scene, labels, detections) gives the ``stamp`` it carries. Other types: None.

A report's stamp is not a data time: a ``diagnostic_msgs/DiagnosticArray`` is stamped by its node's clock, which
is wall time in a node run without ``use_sim_time`` (a scorer or a driver beside the graph) and simulated time in
the graph's nodes. :class:`LogTimes` logs them at the latest stamp it has given, so one bag keeps one time base (a
wall-clock stamp among simulated ones put the bag's first message 56 years after its last step, and a replay from
that start skipped every step).
"""

from __future__ import annotations

import re
import struct
from collections.abc import Callable
from datetime import UTC, datetime
from functools import lru_cache

from zebra_sim_ros.recording.schemas import SchemaError, msg_text

NS_PER_S = 1_000_000_000
_STAMPED = ("std_msgs/Header", "Header", "builtin_interfaces/Time")
_JSON_STAMP = re.compile(rb'"stamp":\s*\{"sec":\s*(-?\d+),\s*"nanosec":\s*(\d+)\}')


def _first_field(type_name: str) -> str | None:
    """The type of the first field of ``pkg/msg/Type`` as written in its .msg (constants and comments skipped)."""
    for line in msg_text(type_name).splitlines():
        fields = line.split("#", 1)[0].split()
        if len(fields) >= 2 and "=" not in fields[1] and "=" not in fields[0]:
            return fields[0]
    return None


def _qualified(base: str, pkg: str) -> str:
    if base == "Header":
        return "std_msgs/msg/Header"
    p = (base if "/" in base else f"{pkg}/{base}").split("/")
    return f"{p[0]}/msg/{p[-1]}"


@lru_cache(maxsize=256)
def stamp_offset(type_name: str) -> tuple[int, bool] | None:
    """(byte offset of the stamp, whether it is behind an array length) for ``type_name``, or None."""
    try:
        first = _first_field(type_name)
        if first is None:
            return None
        base = re.sub(r"\[.*\]$", "", first)
        if type_name in ("std_msgs/msg/Header", "builtin_interfaces/msg/Time") or base in _STAMPED:
            return 4, False
        if first.endswith("[]"):
            inner = _first_field(_qualified(base, type_name.split("/")[0]))
            if inner is not None and re.sub(r"\[.*\]$", "", inner) in _STAMPED:
                return 8, True
    except SchemaError:
        return None
    return None


def header_stamp_ns(type_name: str, data: bytes) -> int | None:
    """The stamp, ns, of a serialized (CDR, little- or big-endian) message of ``type_name``; None if the type has
    none, an array is empty or the bytes are too short."""
    if type_name == "std_msgs/msg/String":
        return _json_stamp_ns(data)
    where = stamp_offset(type_name)
    if where is None or len(data) < 4:
        return None
    offset, behind_length = where
    endian = "<" if data[1] in (1, 3) else ">"  # CDR_LE / PL_CDR_LE
    if behind_length:
        if len(data) < 8 or struct.unpack_from(endian + "I", data, 4)[0] == 0:
            return None
    if len(data) < offset + 8:
        return None
    sec, nanosec = struct.unpack_from(endian + "iI", data, offset)
    return sec * NS_PER_S + nanosec


REPORT_TYPES = frozenset({"diagnostic_msgs/msg/DiagnosticArray"})  # stamped on the reporter's clock


class LogTimes:
    """The log time a recorder gives each message, so one bag keeps one time base: its header stamp
    (:func:`header_stamp_ns`), so log times equal the stamps; a report (:data:`REPORT_TYPES`), whose stamp is its
    node's clock and not a data time, the latest stamp given so far (the data's time base, with or without
    use_sim_time); anything else, and a report before any stamp, ``now()``: the recorder's clock."""

    def __init__(self) -> None:
        self.latest: int | None = None  # the latest header stamp given

    def __call__(self, type_name: str, data: bytes, now: Callable[[], int]) -> int:
        if type_name in REPORT_TYPES:
            t = self.latest
        elif (t := header_stamp_ns(type_name, data)) is not None:
            self.latest = t if self.latest is None else max(self.latest, t)
        return now() if t is None else t


def _json_stamp_ns(data: bytes) -> int | None:
    """The ``stamp`` of our JSON messages in a serialized std_msgs/String (searched in its first 512 bytes: the
    messages write it near the start), or None."""
    m = _JSON_STAMP.search(data[8:520])
    if m is None or b'"schema"' not in data[8:200]:
        return None
    return int(m.group(1)) * NS_PER_S + int(m.group(2))


def iso_time(stamp_ns: int) -> str:
    """A stamp as ISO 8601 UTC to the millisecond (``1970-01-01T00:00:01.250Z``), the form a GIS reads as a
    date-time field (GDAL's GeoJSON driver types it so; QGIS's temporal controller plays it); truncated, not rounded,
    so it never passes the next stamp's second. A JSON number holds ``stamp_ns`` exactly only below 2^53 ns (104
    days): a reader in JavaScript or with doubles loses the nanoseconds of a real flight's stamp, which this and the
    feature's id keep."""
    seconds, ns = divmod(stamp_ns, 10**9)
    return datetime.fromtimestamp(seconds, UTC).strftime("%Y-%m-%dT%H:%M:%S") + f".{ns // 10**6:03d}Z"


def stamp_text(stamp_ns: int) -> str:
    """A stamp as a date and the exact seconds since the epoch, the pair ``ros2 bag info`` gives a bag's start and end:
    ``2025-12-01T08:25:32.123Z (1764577532.123999999)`` (:func:`iso_time`, then seconds.nanoseconds; before the
    epoch both signed as the stamp: ``-1`` ns is ``(-0.000000001)``)."""
    seconds, ns = divmod(abs(stamp_ns), 10**9)
    return f"{iso_time(stamp_ns)} ({'-' if stamp_ns < 0 else ''}{seconds}.{ns:09d})"
