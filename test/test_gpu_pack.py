"""scripts/gpu/pack.py: the frames that travel to a GPU machine, with their labels, re-encoded and thinned."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
from cli_helpers import CliRun

from zebra_sim_ros.detection.data import generate_settings


def _set(root: Path, split: str, n: int, prefix: str, seed: int = 6001) -> Path:
    """A generated-set layout: ``n`` noisy 160x90 frames in images/<split>, labels for all, don't-care for odd."""
    rng = np.random.default_rng(n)
    for k in range(n):
        name = f"{prefix}_{k:03d}"
        for sub in ("images", "labels", "ignore"):
            (root / sub / split).mkdir(parents=True, exist_ok=True)
        img = rng.integers(0, 256, (90, 160, 3), dtype=np.uint8)
        cv2.imwrite(str(root / "images" / split / f"{name}.jpg"), img, [cv2.IMWRITE_JPEG_QUALITY, 98])
        (root / "labels" / split / f"{name}.txt").write_text(f"0 0.5 0.5 0.{k % 9 + 1} 0.1\n")
        if k % 2:
            (root / "ignore" / split / f"{name}.txt").write_text("0 0.2 0.2 0.01 0.01\n")
    (root / "generate.json").write_text(json.dumps({"config": {"seed": seed}}))
    return root / "images" / split


def test_pack_selects_reencodes_and_keeps_labels(tmp_path: Path, pack: CliRun) -> None:
    a = _set(tmp_path / "a", "train", 12, "a")
    b = _set(tmp_path / "b", "train", 8, "b", seed=6000)
    val = _set(tmp_path / "b", "val", 5, "v", seed=6000)
    out = tmp_path / "gpu_data"
    r = pack(["--train", a, b, "--drop-every", f"{b}=4", "--val", val, "--val-frames", "3", "--quality", "60",
              "--out", out])
    assert r.returncode == 0, r.stderr
    got = sorted(p.stem for p in (out / "train" / "images" / "train").glob("*.jpg"))
    # all 12 of a; b less its 1st and 5th frame (every 4th from the first)
    assert got == [f"a_{k:03d}" for k in range(12)] + [f"b_{k:03d}" for k in (1, 2, 3, 5, 6, 7)]
    assert "18 training and 3 validation frames" in r.stdout
    # the tree that travels counts the repository's files (the shipped weights alone are over 5 MiB) and the pack
    tree = float(r.stdout.split("travels with it, on disk: ")[1].split(" MiB")[0])
    pack_mib = float(r.stdout.split("(the pack ")[1].split(",")[0])
    repo = float(r.stdout.split("the repository ")[1].split(")")[0])
    assert repo > 5.0 and pack_mib > 0.0 and abs(tree - (pack_mib + repo)) < 0.15  # nothing else in --out; rounding
    for stem in got:  # labels travel unchanged; don't-care files where the source had them
        src_root = tmp_path / stem[0]
        assert (out / "train" / "labels" / "train" / f"{stem}.txt").read_text() == \
            (src_root / "labels" / "train" / f"{stem}.txt").read_text()
        assert (out / "train" / "ignore" / "train" / f"{stem}.txt").exists() == (int(stem[2:]) % 2 == 1)
    packed = out / "train" / "images" / "train" / "a_000.jpg"
    original = a / "a_000.jpg"
    assert packed.stat().st_size < 0.8 * original.stat().st_size  # quality 60 of a quality-98 noise frame
    diff = np.abs(cv2.imread(str(packed)).astype(int) - cv2.imread(str(original)).astype(int)).mean()
    assert 1.0 < diff < 60.0  # the same picture, re-encoded
    assert sorted(p.stem for p in (out / "val" / "images" / "val").glob("*.jpg")) == ["v_000", "v_001", "v_002"]
    # checkpoints record both sets' generator settings, as for a dataset.yaml listing both
    (out / "mix.yaml").write_text("path: .\ntrain: [train/images/train]\nval: val/images/val\n")
    assert generate_settings(out / "mix.yaml") == {"sets": {str(tmp_path / "a"): {"seed": 6001},
                                                            str(tmp_path / "b"): {"seed": 6000}}}
    one = tmp_path / "one"
    assert pack(["--train", a, "--val", val, "--val-frames", "1", "--out", one]).returncode == 0
    assert json.loads((one / "train" / "generate.json").read_text()) == {"config": {"seed": 6001}}  # one: a copy
    assert generate_settings(one / "train" / "images" / "train") == {"sets": {str(one / "train"): {"seed": 6001}}}

    r = pack(["--train", a, b, "--drop-every", f"{b}=4", "--val", val, "--thin", "3", "--out", out])
    assert r.returncode == 0, r.stderr
    thinned = sorted(p.stem for p in (out / "train" / "images" / "train").glob("*.jpg"))
    assert thinned == [s for k, s in enumerate(got) if k % 3]  # every 3rd of the sorted list left out, old files gone

    r = pack(["--train", a, b, "--keep-every", f"{a}=5", "--val", val, "--out", out])
    assert r.returncode == 0, r.stderr
    kept = sorted(p.stem for p in (out / "train" / "images" / "train").glob("*.jpg"))
    assert kept == ["a_000", "a_005", "a_010"] + [f"b_{k:03d}" for k in range(8)]  # a's 1st, 6th, 11th; all of b


def test_pack_refuses_bad_options_and_oversized_trees(tmp_path: Path, pack: CliRun) -> None:
    a = _set(tmp_path / "a", "train", 4, "a")
    r = pack(["--train", a, "--drop-every", f"{a}=1", "--val", a])
    assert r.returncode != 0 and "--drop-every" in r.stderr and "N >= 2" in r.stderr
    r = pack(["--train", a, "--keep-every", f"{a}=x", "--val", a])
    assert r.returncode != 0 and "--keep-every" in r.stderr and "N >= 2" in r.stderr
    r = pack(["--train", a, "--keep-every", f"{a}=2", "--drop-every", f"{a}=3", "--val", a])
    assert r.returncode != 0 and "both --drop-every and --keep-every" in r.stderr
    r = pack(["--train", tmp_path / "nothing", "--val", a, "--out", tmp_path / "o"])
    assert r.returncode != 0 and "holds no .jpg or .png frames" in r.stderr
    r = pack(["--train", a, "--val", a, "--out", tmp_path / "o", "--thin", "1"])
    assert r.returncode != 0 and "--thin 1" in r.stderr
    r = pack(["--train", a, "--val", a, "--out", tmp_path / "o", "--quality", "101"])
    assert r.returncode != 0 and "--quality 101" in r.stderr
    r = pack(["--train", a, "--val", a, "--out", tmp_path / "o", "--max-mib", "0.00001"])
    assert r.returncode != 0 and "over --max-mib" in r.stderr
