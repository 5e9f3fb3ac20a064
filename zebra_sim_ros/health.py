"""A node's health for ``/diagnostics`` (no rclpy here): its counters, compared report by report.

Each node says what it has done so far as an :class:`Activity` (totals since it started: frames rendered, scenes
skipped, seconds spent working). A :class:`HealthMonitor` turns the activity into a :class:`Health` for the period
since its last report, with the levels of ``diagnostic_msgs/DiagnosticStatus``:

- ERROR while the node has failed (``error``: a recorder whose disk is full, a replay that could not read on);
- WARN when a problem counter (``skipped``, ``dropped``, ``unmatched``) rose in the period;
- OK otherwise: working, waiting for its inputs, or idle, with how long.

The values (``diagnostic_msgs/KeyValue``, strings) hold every counter's total, the rate of work in the period, the
mean seconds per unit of work in the period where the node times its work, and the node's fixed facts.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import IntEnum


class Level(IntEnum):
    """The levels of ``diagnostic_msgs/DiagnosticStatus``."""

    OK = 0
    WARN = 1
    ERROR = 2
    STALE = 3


@dataclass(frozen=True)
class Activity:
    """What a node has done since it started: ``counters`` (totals), of which ``work`` counts the work done and
    ``problems`` count what went wrong (a rise of one in a period is a warning); ``busy_s``, the seconds spent
    working, where the node times its work; ``error``, why the node failed (empty: it has not); ``waiting``, what it
    waits for before it starts (empty: it is not waiting); ``info``, fixed facts (weights, device, world);
    ``hardware``, what it runs on or stands for (a drone, a device), the status's ``hardware_id``; ``note``, what
    the node has to say beyond its counts (the scorer's figures), appended to an OK or WARN message."""

    counters: Mapping[str, int]
    work: str
    problems: tuple[str, ...] = ()
    busy_s: float | None = None
    error: str = ""
    waiting: str = ""
    info: Mapping[str, str] = field(default_factory=dict)
    hardware: str = ""
    note: str = ""

    def __post_init__(self) -> None:
        missing = [n for n in (self.work, *self.problems) if n not in self.counters]
        if missing:
            raise KeyError(f"activity counters {sorted(self.counters)} lack {missing}")


@dataclass(frozen=True)
class Health:
    """One report: level, a one-line message, and the key-value pairs (strings)."""

    level: Level
    message: str
    values: tuple[tuple[str, str], ...]

    def value(self, key: str) -> str:
        """The value of ``key``; KeyError names the keys there are."""
        for k, v in self.values:
            if k == key:
                return v
        raise KeyError(f"no value {key!r} among {[k for k, _ in self.values]}")


def status_name(fqn: str, executable: str) -> str:
    """The name of a node's status on /diagnostics: ``<full node name without the leading />: <executable>``
    (``g1/drone_0_camera: camera``); ``zebra-sim up`` finds its nodes' statuses by it."""
    return f"{fqn.lstrip('/')}: {executable}"


def _seconds(s: float) -> str:
    return f"{s:.1f} s" if s < 120 else f"{s / 60:.1f} min"


class HealthMonitor:
    """Reports on a node's :class:`Activity`, each for the period since the one before (the first: since
    ``start_s``, when the node started). Times are seconds of a monotonic clock."""

    def __init__(self, start_s: float) -> None:
        self.last_s = start_s
        self.last: dict[str, int] = {}
        self.last_busy = 0.0
        self.last_work_s: float | None = None  # when work was last seen to rise

    def report(self, now_s: float, act: Activity) -> Health:
        """The health over ``[last report, now_s]``; remembers this report's counters for the next."""
        period = max(now_s - self.last_s, 1e-9)
        rises = {k: int(v) - self.last.get(k, 0) for k, v in act.counters.items()}
        done = rises[act.work]
        busy = None if act.busy_s is None else act.busy_s - self.last_busy
        if done > 0:
            self.last_work_s = now_s
        values = [(k, str(int(v))) for k, v in act.counters.items()]
        values.append((f"{act.work} per second", f"{done / period:.3g}"))
        if busy is not None and done > 0:
            values.append((f"seconds per {act.work.rstrip('s') or act.work}", f"{busy / done:.3g}"))
        values += [(k, str(v)) for k, v in act.info.items()]
        total = int(act.counters[act.work])
        rate = f"{done} {act.work} in the last {_seconds(period)} ({done / period:.3g}/s)"
        problems = [f"{rises[p]} {p}" for p in act.problems if rises[p] > 0]
        if act.error:
            level, message = Level.ERROR, act.error
        elif problems:
            level, message = Level.WARN, f"{', '.join(problems)} in the last {_seconds(period)}; {rate}"
        elif act.waiting:
            level, message = Level.OK, act.waiting
        elif done > 0:
            level, message = Level.OK, rate
        elif total == 0:
            level, message = Level.OK, f"no {act.work} yet"
        else:
            since = now_s - (self.last_work_s if self.last_work_s is not None else self.last_s)
            level, message = Level.OK, f"no {act.work} for {_seconds(since)}; {total} in all"
        if act.note and level is not Level.ERROR:
            message = f"{message}; {act.note}"
        self.last_s = now_s
        self.last = {k: int(v) for k, v in act.counters.items()}
        if act.busy_s is not None and math.isfinite(act.busy_s):
            self.last_busy = act.busy_s
        return Health(level, message, tuple(values))
