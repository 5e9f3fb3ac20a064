"""scripts/gpu/ab.sh: two training arms side by side, the same epochs, their snapshots paired by epoch (run here on
the CPU with a tiny pack; on a lent GPU it is the same script)."""

from __future__ import annotations

import os
import subprocess
import sys
import tarfile
from pathlib import Path

import cv2
import numpy as np
import torch

from zebra_sim_ros.detection.checkpoint import read_checkpoint

ROOT = Path(__file__).resolve().parents[1]
AB = ROOT / "scripts" / "gpu" / "ab.sh"
PACK = ROOT / "scripts" / "gpu" / "pack.py"


def _pack(tmp: Path) -> Path:
    """A packed folder of 6 training and 2 validation frames: grey ground with one dark striped box each."""
    src = tmp / "set"
    rng = np.random.default_rng(7)
    for split, n in (("train", 6), ("val", 2)):
        for sub in ("images", "labels"):
            (src / sub / split).mkdir(parents=True, exist_ok=True)
        for k in range(n):
            img = rng.integers(90, 140, (180, 320, 3), dtype=np.uint8)
            x0, y0 = 40 + 30 * k, 50 + 10 * k
            img[y0:y0 + 40, x0:x0 + 60] = 30
            img[y0:y0 + 40:6, x0:x0 + 60] = 230  # stripes
            cv2.imwrite(str(src / "images" / split / f"f{k}.jpg"), img)
            (src / "labels" / split / f"f{k}.txt").write_text(
                f"0 {(x0 + 30) / 320:.4f} {(y0 + 20) / 180:.4f} {60 / 320:.4f} {40 / 180:.4f}\n")
    out = tmp / "pack"
    r = subprocess.run([sys.executable, str(PACK), "--train", str(src / "images" / "train"), "--val",
                        str(src / "images" / "val"), "--out", str(out)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    return out


def _ab(env: dict[str, str], timeout: float = 300) -> subprocess.CompletedProcess[str]:
    full = {**os.environ, **env}
    full["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{full.get('PATH', '')}"  # python3: this interpreter
    return subprocess.run(["bash", str(AB)], capture_output=True, text=True, timeout=timeout, env=full)


def test_ab_refuses_settings_that_name_the_bad_value(tmp_path: Path) -> None:
    data = _pack(tmp_path)
    base = {"DATA": str(data), "OUT": str(tmp_path / "out"), "DEVICE": "cpu"}
    r = _ab({**base, "A_OPTS": "--p2", "B_OPTS": "--p2"})
    assert r.returncode == 2 and "A_OPTS and B_OPTS are the same" in r.stderr
    r = _ab({**base, "A_OPTS": "--p2", "EPOCHS": "0"})
    assert r.returncode == 2 and "EPOCHS=0" in r.stderr
    r = _ab({**base, "A_OPTS": "--p2", "INIT_A": str(tmp_path / "none.pt")})
    assert r.returncode == 2 and "INIT_A=" in r.stderr and "none.pt" in r.stderr
    r = _ab({**base, "A_OPTS": "--p2", "DATA": str(tmp_path / "empty")})
    assert r.returncode == 2 and "DATA=" in r.stderr and "pack.py" in r.stderr
    r = _ab({**base, "A_OPTS": "--p2", "BUDGET": "900"})
    assert r.returncode == 2 and "BUDGET=900" in r.stderr
    assert not (tmp_path / "out" / "a").exists()  # nothing trained


def test_ab_trains_both_arms_and_pairs_their_snapshots(tmp_path: Path) -> None:
    data, out = _pack(tmp_path), tmp_path / "out"
    r = _ab({"DATA": str(data), "OUT": str(out), "DEVICE": "cpu", "A_OPTS": "--p2", "K": "1", "EPOCHS": "2",
             "BATCH": "2", "WORKERS": "1", "IMGSZ": "320", "CROP": "160", "BUDGET": "300"})
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    assert "both arms finished 2 epochs" in r.stdout
    for arm, p2 in (("a", True), ("b", False)):
        for epoch in (1, 2):  # the last two epochs both finished, each an fp16 snapshot of its own arm
            ck = read_checkpoint(out / arm / f"ep_{epoch}.pt")
            assert ck["config"]["p2"] is p2
            assert ck["epoch"] == epoch - 1  # checkpoints count epochs from 0
            assert all(t.dtype == torch.float16 for t in ck["model"].values() if t.is_floating_point())
    with tarfile.open(out / "logs.tar.gz") as tar:
        names = tar.getnames()
        assert sum(n.endswith("results.csv") for n in names) == 2 and sum(n.endswith("train.log") for n in names) == 2
        for n in names:
            if n.endswith("results.csv"):
                f = tar.extractfile(n)
                assert f is not None
                assert len(f.read().decode().strip().splitlines()) == 3  # the header and two epochs
    assert "A_OPTS='--p2' B_OPTS=''" in (out / "machine.txt").read_text()
