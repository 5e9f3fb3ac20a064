"""Shared fixtures: the zebra library in a private cache folder for the session (linked from the default cache);
``zebra-sim`` run in the test's own process."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import pytest

from zebra_sim_ros.errors import AssetError
from zebra_sim_ros.zebra.asset import ZebraLibrary, build_library, library_dir, load_library


@pytest.fixture(scope="session")
def zebra_cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("zebra_cache")


@pytest.fixture(scope="session")
def library(zebra_cache: Path) -> ZebraLibrary:
    # The private cache holds hard links to the default cache's baked arrays and manifest (which generate, the nodes
    # and ``up`` use, and build when it is missing): the arrays are opened read-only and a rebuild writes new files
    # and renames them in, so no test writes through a link. The ``usd`` folder that ``asset build`` without
    # ``--out`` writes in place is not linked. test_rebuild_is_bit_identical still compares a fresh build with these.
    # Where links cannot be made (another file system) the library is baked here, as before.
    try:
        shared = load_library().root
        shutil.copytree(shared, library_dir(zebra_cache), copy_function=os.link, ignore=shutil.ignore_patterns("usd"))
    except (OSError, AssetError):
        shutil.rmtree(library_dir(zebra_cache), ignore_errors=True)
        return build_library(zebra_cache)
    return load_library(zebra_cache, build_if_missing=False)


CliRun = Callable[..., "subprocess.CompletedProcess[str]"]


def exit_status(exc: SystemExit) -> int:
    """The status the interpreter exits with on ``exc``, printing a message code to stderr as it does."""
    if exc.code is None or isinstance(exc.code, int):
        return exc.code or 0
    print(exc.code, file=sys.stderr)
    return 1


class CliTimeout(BaseException):
    """A ``cli`` run past its timeout: a BaseException, so no ``except OSError`` (or Exception) in the code under
    test swallows it."""


@pytest.fixture
def cli(capfd: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> CliRun:
    """``cli(args, env, timeout)``: ``zebra-sim ARGS`` through the console script's own ``main`` in this process, its
    exit status and everything written to stdout and stderr (file descriptors, children's included) returned as a
    finished process's; a SystemExit is a status as the interpreter makes it, and a run past ``timeout`` seconds
    fails the test. A fresh interpreter costs about 3 s on our 2 cores (torch's import most of it); the tests whose
    subject is the process itself (a closed pipe, a signal, the installed script) still start one."""
    from zebra_sim_ros.cli import main

    def on_alarm(signum: int, frame: object) -> None:
        raise CliTimeout(f"zebra-sim ran past its timeout: {signum}")

    def run(args: Sequence[object], env: Mapping[str, str] | None = None,
            timeout: float = 120.0) -> subprocess.CompletedProcess[str]:
        argv = [str(a) for a in args]
        out = err = ""
        with monkeypatch.context() as m:
            for key, value in (env or {}).items():
                m.setenv(key, value)
            before = capfd.readouterr()
            old = signal.signal(signal.SIGALRM, on_alarm)
            signal.setitimer(signal.ITIMER_REAL, timeout)
            try:
                try:
                    code = main(argv)
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

    return run
