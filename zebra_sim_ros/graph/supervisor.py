"""Start, watch and stop the graph's processes (no rclpy here: plain processes and signals).

Each node runs in its own session (a Ctrl-C in the terminal reaches only the supervisor, which then stops the
nodes in order) with ``PR_SET_PDEATHSIG`` so that no node outlives a supervisor that is killed outright. Output
goes to ``<logs>/<label>.log``. Stopping sends SIGINT (nodes finalise, the recorder writes its summary), then
SIGTERM, then SIGKILL, each after a grace period.
"""

from __future__ import annotations

import ctypes
import math
import os
import signal
import subprocess
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO

from zebra_sim_ros.graph.spec import NodeSpec

_PR_SET_PDEATHSIG = 1


def child_setup() -> None:
    """``preexec_fn`` of a node process (runs in the child between fork and exec): SIGINT and SIGTERM at their
    defaults, and SIGTERM when its parent dies, so that no node outlives the process that started it."""
    # SIGINT is how the supervisor asks a node to finish; a supervisor started as a background job of a
    # non-interactive shell inherits SIGINT ignored, and an ignored disposition would survive exec.
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
    except OSError:
        pass


@dataclass
class Child:
    """One running node process."""

    spec: NodeSpec
    proc: subprocess.Popen[bytes]
    log_path: Path
    log_file: IO[bytes]
    expected_exit: bool = False  # the placer ends by itself after its last step

    @property
    def label(self) -> str:
        return self.spec.label

    def log_tail(self, lines: int = 8) -> str:
        """The last lines of the node's output (to say why it died)."""
        try:
            text = self.log_path.read_text(errors="replace")
        except OSError:
            return ""
        return "\n".join(text.rstrip().splitlines()[-lines:])


class NodeDied(RuntimeError):
    """A node exited while the graph was running."""

    def __init__(self, child: Child, code: int) -> None:
        self.child, self.code = child, code
        how = f"signal {signal.Signals(-code).name}" if code < 0 else f"exit status {code}"
        super().__init__(f"node {child.label} died ({how}); last output:\n{child.log_tail()}")


class Supervisor:
    """The graph's processes; use as a context manager so they are always stopped."""

    def __init__(self, logs: Path, env: dict[str, str]) -> None:
        self.logs = logs
        self.env = env
        self.children: list[Child] = []
        logs.mkdir(parents=True, exist_ok=True)

    def start(self, spec: NodeSpec, args: Sequence[str], expected_exit: bool = False) -> Child:
        """Start one node process."""
        path = self.logs / (spec.label.replace("/", "_") + ".log")
        log = open(path, "wb")  # noqa: SIM115 (closed in stop())
        proc = subprocess.Popen(list(args), env=self.env, stdout=log, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, start_new_session=True, preexec_fn=child_setup)
        child = Child(spec, proc, path, log, expected_exit)
        self.children.append(child)
        return child

    def check(self) -> None:
        """Raise :class:`NodeDied` for the first node that exited unexpectedly (or with an error)."""
        for c in self.children:
            code = c.proc.poll()
            if code is not None and (not c.expected_exit or code != 0):
                raise NodeDied(c, code)

    def stop(self, order: Sequence[Child] | None = None, grace_s: float = 10.0,
             kill_after_s: float = 5.0) -> dict[str, int | None]:
        """Stop every process still running, in ``order`` (default: reverse start order), and return each one's
        exit status. SIGINT first; SIGTERM for those that do not exit within ``grace_s``, and SIGKILL for those
        still running ``kill_after_s`` after it. Both are seconds, finite and 0 or more."""
        for name, value in (("grace_s", grace_s), ("kill_after_s", kill_after_s)):
            if not 0.0 <= value < math.inf:
                raise ValueError(f"Supervisor.stop: {name} must be a finite number of seconds >= 0, got {value!r}")
        todo = list(order) if order is not None else list(reversed(self.children))
        todo += [c for c in self.children if c not in todo]
        for c in todo:
            if c.proc.poll() is None:
                self._signal(c, signal.SIGINT)
                self._wait(c, grace_s, signal.SIGTERM) or self._wait(c, kill_after_s, signal.SIGKILL)
                self._wait(c, 5.0, None)
        for c in self.children:
            c.log_file.close()
        return {c.label: c.proc.poll() for c in self.children}

    @staticmethod
    def _signal(c: Child, sig: signal.Signals) -> None:
        try:
            os.killpg(c.proc.pid, sig)
        except ProcessLookupError:
            pass

    def _wait(self, c: Child, timeout: float, then: signal.Signals | None) -> bool:
        try:
            c.proc.wait(timeout=timeout)
            return True
        except subprocess.TimeoutExpired:
            if then is not None:
                self._signal(c, then)
            return False

    def __enter__(self) -> Supervisor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
