"""Training runs end to end on generated images, writes its table, plot and checkpoints, and resumes."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import pytest

from zebra_sim_ros.dataset.generate import GenerateConfig, generate
from zebra_sim_ros.detection.train import TrainConfig, train


@pytest.fixture(scope="module")
def tiny(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("tiny")
    # Two steps of close-by views through a narrow lens: six small images with a few zebras each.
    generate(GenerateConfig(out=str(out), frames=6, strategy="closeby", seed=11, width=256, height=256, hfov_deg=30.0,
                            val_fraction=0.0, depth="none", placer={"count_min": 3, "count_max": 8}),
             progress=lambda *a: None)
    # Train and validate on the same images: this tests the run's mechanics, not what it learns.
    (out / "overfit.yaml").write_text(f"path: {out}\ntrain: images/train\nval: images/train\nnames:\n  0: zebra\n")
    return out


def test_resume_continues_from_last(tiny: Path, tmp_path: Path) -> None:
    base = dict(data=str(tiny / "overfit.yaml"), out=str(tmp_path / "run"), model="n", imgsz=128, batch=4,
                device="cpu", workers=0, max_train_images=4, val_every=1, close_mosaic=1)
    summary = train(TrainConfig(epochs=2, **base), log=io.StringIO())
    assert summary["train_images_per_s"] > 0
    for name in ("best.pt", "last.pt", "results.csv", "results.png"):
        assert (tmp_path / "run" / name).exists(), name
    rows_before = list(csv.DictReader(open(tmp_path / "run" / "results.csv")))
    train(TrainConfig(epochs=3, resume=True, **base), log=io.StringIO())
    rows = list(csv.DictReader(open(tmp_path / "run" / "results.csv")))
    assert [r["epoch"] for r in rows] == ["1", "2", "3"] and rows[:2] == rows_before
