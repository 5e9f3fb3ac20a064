"""scripts/gpu/ab.sh: two training arms side by side, the same epochs, their snapshots paired by epoch (run here on
the CPU with a tiny pack; on a lent GPU it is the same script)."""

from __future__ import annotations

import os
import tarfile
from pathlib import Path

import torch
from cli_helpers import CliRun
from gpu_helpers import ROOT, assert_refused, run_script, tiny_pack

from zebra_sim_ros.detection.checkpoint import read_checkpoint

AB = ROOT / "scripts" / "gpu" / "ab.sh"


def test_ab_refuses_settings_that_name_the_bad_value(tmp_path: Path, pack: CliRun) -> None:
    data, out = tiny_pack(tmp_path, pack), tmp_path / "out"
    base = {"DATA": str(data), "OUT": str(out), "DEVICE": "cpu", "A_OPTS": "--p2"}
    assert_refused(AB, base, [({"B_OPTS": "--p2"}, "A_OPTS and B_OPTS are the same"), ({"EPOCHS": "0"}, "EPOCHS=0"),
                              ({"MAXIMG": "-1"}, "MAXIMG=-1"), ({"THREADS": "0"}, "THREADS=0"),
                              ({"BUDGET": "900"}, "BUDGET=900"),
                              ({"INIT_A": str(tmp_path / "none.pt")}, "INIT_A="),
                              ({"INIT_B": str(tmp_path / "b.pt")}, "INIT_B="),
                              ({"DATA": str(tmp_path / "empty")}, "DATA=")], out)


def test_ab_trains_both_arms_and_pairs_their_snapshots(tmp_path: Path, pack: CliRun) -> None:
    data, out = tiny_pack(tmp_path, pack), tmp_path / "out"
    tiny = {"DATA": str(data), "DEVICE": "cpu", "K": "1", "EPOCHS": "2", "BATCH": "2", "WORKERS": "1", "IMGSZ": "320",
            "CROP": "160", "BUDGET": "200"}
    r = run_script(AB, tiny | {"OUT": str(out), "A_OPTS": "--p2"})
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    assert "both arms finished 2 epochs" in r.stdout
    for arm, p2 in (("a", True), ("b", False)):
        for epoch in (1, 2):  # the last two epochs both finished, each an fp16 snapshot of its own arm
            ck = read_checkpoint(out / arm / f"ep_{epoch}.pt")
            assert ck["config"]["p2"] is p2
            assert ck["epoch"] == epoch - 1  # checkpoints count epochs from 0
            assert all(t.dtype == torch.float16 for t in ck["model"].values() if t.is_floating_point())
    with tarfile.open(out / "logs.tar.gz") as tar:
        assert sorted(tar.getnames()) == sorted(f"ab_{a}/{f}" for a in "ab" for f in ("train.log", "results.csv"))
        for arm in "ab":
            f = tar.extractfile(f"ab_{arm}/results.csv")
            assert f is not None
            assert len(f.read().decode().strip().splitlines()) == 3  # the header and two epochs
    machine = (out / "machine.txt").read_text()
    assert "A_OPTS='--p2' B_OPTS=''" in machine
    assert f"THREADS={max(1, len(os.sched_getaffinity(0)) // 2)} " in machine  # torch threads per arm: half the cores

    # the second call's way: each arm from its own snapshot in its own run folder, which the arm empties first
    out2 = tmp_path / "out2"
    snaps = {f"INIT_{arm.upper()}": str(data / f"ab_{arm}" / "snap" / "ep_2.pt") for arm in "ab"}
    r = run_script(AB, tiny | snaps | {"OUT": str(out2), "A_OPTS": "--p2", "EPOCHS": "1"})
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    assert read_checkpoint(out2 / "a" / "ep_1.pt")["config"]["p2"] is True

    # an arm that cannot train stops the other, and the run says so by its exit status
    out3 = tmp_path / "out3"
    r = run_script(AB, tiny | {"OUT": str(out3), "A_OPTS": "--no-such-option", "EPOCHS": "50"})
    assert r.returncode != 0
    assert "ab_a failed" in r.stdout and "stopping the other arm" in r.stdout
    assert "ab_b (exit 143)" in r.stdout  # stopped by the signal, not run to its 50 epochs or the budget
    assert "both arms finished 0 epochs" in r.stdout
    assert not list((out3 / "b").glob("*.pt"))
