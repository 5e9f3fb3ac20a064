"""Shared fixtures: the zebra library in a private cache folder for the session (linked from the default cache);
``zebra-sim`` run in the test's own process; the default world, generated once per test module."""

from __future__ import annotations

import os
import shutil
import subprocess
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import pytest
from cli_helpers import CliRun, run_cli, script_main

from zebra_sim_ros.errors import AssetError
from zebra_sim_ros.world.world import World, generate_world
from zebra_sim_ros.zebra.asset import ZebraLibrary, build_library, library_dir, load_library


@pytest.fixture(scope="module")
def savanna() -> World:
    """The default world (savanna, seed 0), once per module: a module that changes it changes only its own."""
    return generate_world("savanna", 0)


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


def _runner(main: Callable[[list[str]], int | None], name: str, capfd: pytest.CaptureFixture[str],
            monkeypatch: pytest.MonkeyPatch) -> CliRun:
    """``run(args, env, timeout)`` of ``main`` through ``cli_helpers.run_cli``, its timeout naming ``name``."""

    def run(args: Sequence[object], env: Mapping[str, str] | None = None,
            timeout: float = 120.0) -> subprocess.CompletedProcess[str]:
        return run_cli(main, args, capfd, monkeypatch, env, timeout, name)

    return run


@pytest.fixture
def cli(capfd: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> CliRun:
    """``cli(args, env, timeout)``: ``zebra-sim ARGS`` through the console script's own ``main`` in this process
    (``cli_helpers.run_cli``): its exit status and everything written to stdout and stderr (file descriptors,
    children's included) returned as a finished process's; a run past ``timeout`` seconds fails the test. A fresh
    interpreter costs about 3 s on our 2 cores (torch's import most of it); the tests whose subject is the process
    itself (a closed pipe, a signal, the installed script) still start one."""
    from zebra_sim_ros.cli import main

    return _runner(main, "zebra-sim", capfd, monkeypatch)


@pytest.fixture
def pack(capfd: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> CliRun:
    """``pack(args, env, timeout)``: ``python scripts/gpu/pack.py ARGS`` run in this process as the ``cli`` fixture
    runs ``zebra-sim`` (its one child, git, writes to the same captured descriptors)."""
    script = Path(__file__).resolve().parents[1] / "scripts" / "gpu" / "pack.py"
    return _runner(script_main(script), "pack.py", capfd, monkeypatch)
