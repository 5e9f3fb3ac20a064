"""The GPU scripts' tests (scripts/gpu/*.sh) run them on the CPU: a tiny pack, and a runner that passes settings
without inheriting any and kills the script's whole session on timeout."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
from cli_helpers import CliRun

ROOT = Path(__file__).resolve().parents[1]
# the scripts' settings: none is taken from the environment the tests run in
SETTINGS = ("BUDGET", "EPOCHS", "E0", "K", "IMGSZ", "CROP", "BATCH", "WORKERS", "DEVICE", "LR", "SEED", "MAXIMG",
            "INIT", "INIT_A", "INIT_B", "AUG", "A_OPTS", "B_OPTS", "OUT", "DATA", "P2", "MODEL", "THREADS")


def tiny_pack(tmp: Path, pack: CliRun) -> Path:
    """A packed folder of 6 training and 2 validation frames: grey ground with one dark striped box each (``pack``:
    the conftest fixture that runs scripts/gpu/pack.py)."""
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
    r = pack(["--train", src / "images" / "train", "--val", src / "images" / "val", "--out", out])
    assert r.returncode == 0, r.stdout + r.stderr
    return out


def run_script(script: Path, env: dict[str, str], timeout: float = 300) -> subprocess.CompletedProcess[str]:
    """Run a bash script with these settings only (none inherited), in a session of its own, killed whole on
    timeout (`timeout` puts the trainers in process groups of their own, inside the session)."""
    full = {k: v for k, v in os.environ.items() if k not in SETTINGS} | env
    full["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{full.get('PATH', '')}"  # python3: this interpreter
    with subprocess.Popen(["bash", str(script)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=full,
                          start_new_session=True) as proc:
        try:
            out, err = proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            subprocess.run(["pkill", "-KILL", "-s", str(proc.pid)], check=False, timeout=30)
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
            raise
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


def assert_refused(script: Path, base: dict[str, str], cases: list[tuple[dict[str, str], str]], out: Path) -> None:
    """Each case's settings over ``base`` stop the script with exit 2, its message holding the case's text, before
    it makes ``out``."""
    for bad, said in cases:
        r = run_script(script, base | bad)
        assert r.returncode == 2 and said in r.stderr, (bad, r.stderr)
        assert not out.exists()  # refused before anything was made
