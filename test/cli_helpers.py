"""Running ``zebra-sim`` (or any console-script ``main``) in the test's own process, as the ``cli`` fixture of
conftest.py does: the exit status as the interpreter makes it, fd-level output, and a timeout that no ``except``
in the code under test swallows."""

from __future__ import annotations

import math
import os
import runpy
import signal
import subprocess
import sys
from collections.abc import Callable, Mapping, Sequence

import pytest

CliRun = Callable[..., "subprocess.CompletedProcess[str]"]


def exit_status(exc: SystemExit) -> int:
    """The status the interpreter exits with on ``exc``, printing a message code to stderr as it does."""
    if exc.code is None or isinstance(exc.code, int):
        return exc.code or 0
    print(exc.code, file=sys.stderr)
    return 1


def script_main(script: str | os.PathLike[str]) -> Callable[[list[str]], int | None]:
    """A ``main`` for :func:`run_cli` that runs the Python file ``script`` as ``python SCRIPT ARGV`` would (as
    ``__main__``, with ``sys.argv`` set for the run and put back after it)."""
    path = os.fspath(script)

    def main(argv: list[str]) -> int | None:
        saved, sys.argv = sys.argv, [path, *argv]
        try:
            runpy.run_path(path, run_name="__main__")
        finally:
            sys.argv = saved
        return 0

    return main


class CliTimeout(BaseException):
    """A ``cli`` run past its timeout: a BaseException, so no ``except OSError`` (or Exception) in the code under
    test swallows it."""


def run_cli(main: Callable[[list[str]], int | None], args: Sequence[object], capfd: pytest.CaptureFixture[str],
            monkeypatch: pytest.MonkeyPatch, env: Mapping[str, str] | None = None,
            timeout: float = 120.0, name: str = "zebra-sim") -> subprocess.CompletedProcess[str]:
    """``main(ARGS)`` in this process with ``env`` set for the run: its exit status (a SystemExit as the interpreter
    makes it), stdout and stderr (file descriptors, children's included) as a finished process's. A run past
    ``timeout`` seconds raises :class:`CliTimeout` naming the program ``name`` (SIGALRM; main thread only)."""
    if not 0 < timeout < math.inf:
        raise ValueError(f"timeout must be a positive, finite number of seconds, got {timeout!r}")

    def on_alarm(signum: int, frame: object) -> None:
        raise CliTimeout(f"{name} ran past its timeout of {timeout} s (signal {signum})")

    argv = [str(a) for a in args]
    out = err = ""
    with monkeypatch.context() as m:
        for key, value in (env or {}).items():
            m.setenv(key, value)
        before = capfd.readouterr()
        old = signal.signal(signal.SIGALRM, on_alarm)
        try:
            try:
                signal.setitimer(signal.ITIMER_REAL, timeout)
                code = main(argv) or 0
            except SystemExit as exc:
                code = exit_status(exc)
            finally:
                signal.setitimer(signal.ITIMER_REAL, 0)
                signal.signal(signal.SIGALRM, old)
                sys.stdout.flush()
                sys.stderr.flush()
                out, err = capfd.readouterr()
        finally:
            # written back on every path, so a failing test's report shows everything, this run's output too
            sys.stdout.write(before.out + out)
            sys.stderr.write(before.err + err)
    return subprocess.CompletedProcess(argv, code, out, err)
