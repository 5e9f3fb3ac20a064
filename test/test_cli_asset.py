"""``zebra-sim asset ...``: JSON summary last, clear errors. The build runs as a user runs it, a real process; the
rest through the console script's ``main`` in the test's process (the ``cli`` fixture)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import cv2
import pytest
from cli_helpers import CliRun

from zebra_sim_ros.zebra.asset import ZebraLibrary, coat_store_dir, library_dir
from zebra_sim_ros.zebra.coat_store import CoatStore


def _run(args: list[str], cache: Path, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, ZEBRA_SIM_CACHE=str(cache))
    return subprocess.run([sys.executable, "-m", "zebra_sim_ros.cli", *args], env=env, capture_output=True,
                          text=True, timeout=timeout)


def test_every_subcommand_has_help(zebra_cache: Path, cli: CliRun) -> None:
    for args in (["--help"], ["asset", "--help"], ["asset", "build", "--help"], ["asset", "info", "--help"],
                 ["asset", "prune", "--help"], ["asset", "preview", "--help"]):
        proc = cli(args, {"ZEBRA_SIM_CACHE": str(zebra_cache)})
        assert proc.returncode == 0, (args, proc.stderr)
        assert "usage:" in proc.stdout


def test_build_writes_usd_and_a_json_summary(library: ZebraLibrary, zebra_cache: Path, tmp_path: Path) -> None:
    proc = _run(["asset", "build", "--out", str(tmp_path / "usd"), "--coat-size", "128", "--json"], zebra_cache)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    assert summary["frames"] == library.n_frames
    assert summary["cache"] == str(library.root)
    for name in ("plains", "grevy", "foal"):
        assert (tmp_path / "usd" / f"zebra_{name}.usd").stat().st_size > 100_000
        assert cv2.imread(str(tmp_path / "usd" / f"zebra_{name}_coat.png")).shape == (128, 128, 3)


def test_info_json(library: ZebraLibrary, zebra_cache: Path, cli: CliRun) -> None:
    store = CoatStore(zebra_cache)
    store.coats([("plains", 1), ("rhino", 2)], 64)  # two coats in the cache's store, as a camera leaves them
    proc = cli(["asset", "info", "--json"], {"ZEBRA_SIM_CACHE": str(zebra_cache)})
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    assert summary["keypoints"] >= 20 and summary["joints"] >= 25
    assert summary["triangles"]["lod0"] >= 4000
    assert sum(summary["clips"].values()) == library.n_frames
    files = list(store.dir.glob("*.z"))
    assert len(files) >= 2 and summary["coat_store"] == {"dir": str(store.dir), "coats": len(files),
                                                         "bytes": sum(f.stat().st_size for f in files)}
    assert f"{store.dir}: {len(files)} coats" in proc.stdout


def test_preview_sheet(library: ZebraLibrary, zebra_cache: Path, tmp_path: Path, cli: CliRun) -> None:
    out = tmp_path / "sheet.png"
    proc = cli(["asset", "preview", str(out), "--clips", "walk,graze", "--frames-per-clip", "3",
                "--cell", "100", "--json"], {"ZEBRA_SIM_CACHE": str(zebra_cache)})
    assert proc.returncode == 0, proc.stderr
    img = cv2.imread(str(out))
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    assert img.shape[:2] == (summary["height"], summary["width"])
    # One row of two individuals per morph (zebras and other species), then two clip rows of a side view (100 px)
    # over a top view (50 px).
    strip = min(100, summary["width"] // (2 * len(library.morphs)))
    assert img.shape[0] == strip + 2 * 150
    # The zebras are drawn: plenty of dark stripe pixels on the light background.
    assert (img.mean(axis=2) < 80).mean() > 0.01


@pytest.mark.parametrize(("args", "needle"), [
    (["asset", "preview", "x.png", "--clips", "moonwalk"], "--clips"),
    (["asset", "preview", "x.png", "--frames-per-clip", "0"], "--frames-per-clip"),
    (["asset", "preview", "x.jpg"], "out"),
    (["asset", "preview", "x.png", "--morph", "quagga"], "morph"),
])
def test_bad_arguments_stop_with_a_message_naming_them(library: ZebraLibrary, zebra_cache: Path, tmp_path: Path,
                                                       args: list[str], needle: str, cli: CliRun) -> None:
    args = [str(tmp_path / a) if a.endswith((".png", ".jpg")) else a for a in args]
    proc = cli(args, {"ZEBRA_SIM_CACHE": str(zebra_cache)})
    assert proc.returncode == 2
    assert needle in proc.stderr and "invalid" in proc.stderr


def test_prune_removes_other_versions_caches_and_nothing_else(tmp_path: Path, cli: CliRun) -> None:
    """Only the folders named as ours and not read by this code version go; a build whose process runs here or that
    was touched within the hour stays, and so does anything else under the root, links included (never followed).
    ``--dry-run`` lists without removing, ``--all`` takes this version's too."""
    root, outside = tmp_path / "cache", tmp_path / "outside"
    here, coats = library_dir(root), coat_store_dir(root)
    no_pid = int(Path("/proc/sys/kernel/pid_max").read_text())  # pids are below it: never a running process
    old = {"zebra-0123456789abcdef": 3000, "coats-0123456789abcdef-np2.0.0": 500, "coats-fedcba9876543210": 700,
           f"{here.name}.tmp{no_pid}": 200}  # an interrupted build of this version: no process, untouched for 2 h
    others = {here.name: 1000, coats.name: 400,
              f"zebra-0123456789abcdef.tmp{os.getpid()}": 100,  # being built by a running process
              f"zebra-0123456789abcdee.tmp{no_pid}": 100,  # no process here, but touched just now: another machine's?
              "zebra-notours": 10, "notes": 10}
    for name, size in {**old, **others}.items():
        (root / name / "sub").mkdir(parents=True)
        (root / name / "sub" / "a.bin").write_bytes(b"x" * size)
    two_hours_ago = time.time() - 7200
    for path in (root / f"{here.name}.tmp{no_pid}", root / f"{here.name}.tmp{no_pid}" / "sub"):
        os.utime(path, (two_hours_ago, two_hours_ago))
    (outside / "keep").mkdir(parents=True)
    (outside / "keep" / "b.bin").write_bytes(b"y" * 50)
    (root / "zebra-0123456789abcdef" / "link").symlink_to(outside / "keep")  # inside an old cache: not followed
    (root / "coats-00112233445566ff").symlink_to(outside)  # named as ours but a link: not ours
    (root / "coats-0123456789abcdee").write_text("a file, not a folder")
    untouched = sorted([*others, "coats-00112233445566ff", "coats-0123456789abcdee"])

    dry = cli(["asset", "prune", "--cache", str(root), "--dry-run", "--json"], {"ZEBRA_SIM_CACHE": str(root)})
    assert dry.returncode == 0, dry.stderr
    summary = json.loads(dry.stdout.strip().splitlines()[-1])
    assert sorted(Path(p).name for p in summary["would_remove"]) == sorted(old) and "removed" not in summary
    assert summary["bytes"] == sum(old.values())  # the link inside counts nothing
    assert sorted(p.name for p in root.iterdir()) == sorted([*old, *untouched])

    proc = cli(["asset", "prune", "--cache", str(root), "--json"], {"ZEBRA_SIM_CACHE": str(root)})
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    assert sorted(Path(p).name for p in summary["removed"]) == sorted(old) and summary["failed"] == []
    assert sorted(p.name for p in root.iterdir()) == untouched
    assert (outside / "keep" / "b.bin").read_bytes() == b"y" * 50
    assert sorted(Path(p).name for p in summary["kept"]) == sorted(
        [here.name, coats.name, f"zebra-0123456789abcdef.tmp{os.getpid()}", f"zebra-0123456789abcdee.tmp{no_pid}"])

    proc = cli(["asset", "prune", "--cache", str(root), "--all", "--json"], {"ZEBRA_SIM_CACHE": str(root)})
    assert proc.returncode == 0, proc.stderr
    assert not here.exists() and not coats.exists()
    assert sorted(p.name for p in root.iterdir()) == sorted(set(untouched) - {here.name, coats.name})

    proc = cli(["asset", "prune", "--cache", str(tmp_path / "no_such_cache")], {"ZEBRA_SIM_CACHE": str(root)})
    assert proc.returncode == 2 and "--cache" in proc.stderr and "no_such_cache" in proc.stderr


def test_info_counts_other_versions_caches(library: ZebraLibrary, zebra_cache: Path, tmp_path: Path,
                                           cli: CliRun) -> None:
    root = tmp_path / "cache"
    root.mkdir()
    (root / library.root.name).symlink_to(library.root)  # this version's cache, not copied
    (root / "zebra-0123456789abcdef").mkdir()
    (root / "zebra-0123456789abcdef" / "joints.npy").write_bytes(b"x" * 2_500_000)
    proc = cli(["asset", "info", "--cache", str(root), "--json"], {"ZEBRA_SIM_CACHE": str(root)})
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    assert summary["other_versions"] == {"folders": 1, "bytes": 2_500_000}
    assert "1 folders, 2.5 MB ('zebra-sim asset prune' removes them)" in proc.stdout
