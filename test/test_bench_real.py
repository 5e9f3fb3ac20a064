"""``benchmarks/bench_real.py``, the real-image benchmark, on a set laid out as ``scripts/real_sets/`` writes them,
built from generated frames (no real photograph in the suite): its zebra figures are ``val``'s on the same photos,
and its false detections on photos of other species are the ones ``zebra-sim predict`` finds there."""

from __future__ import annotations

import importlib.util
import json
import shutil
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
from cli_helpers import CliRun

from zebra_sim_ros.dataset.generate import GenerateConfig, generate
from zebra_sim_ros.detection.evaluate import evaluate
from zebra_sim_ros.detection.metrics import iou_matrix

ROOT = Path(__file__).resolve().parents[1]
IMGSZ = 544  # the shipped weights serve 320 px frames at 1.7x


def _bench_real() -> ModuleType:
    spec = importlib.util.spec_from_file_location("bench_real", ROOT / "benchmarks" / "bench_real.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["bench_real"] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def mini(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``mini/``: three frames with their zebra labels, and three more as photos "of other species only": no zebra
    labels, every zebra they show (labelled or too small to be) boxed under ``other_species/`` as class 1.
    ``zebras/``: the first three alone."""
    root = tmp_path_factory.mktemp("bench_real")
    generate(GenerateConfig(out=str(root / "gen"), frames=6, strategy="closeby", seed=31, width=320, height=180,
                            val_fraction=0.0, depth="none", other_animals=0, placer={"count_min": 20, "count_max": 60}),
             progress=lambda *a: None)
    images = sorted((root / "gen" / "images" / "train").glob("*.jpg"))
    assert len(images) == 6
    for sub in ("mini/images", "mini/labels", "mini/other_species", "zebras/images", "zebras/labels"):
        (root / sub).mkdir(parents=True)
    for k, img in enumerate(images):
        labels = (root / "gen" / "labels" / "train" / img.name).with_suffix(".txt").read_text()
        assert labels.strip(), f"{img.name}: a frame without zebras"
        shutil.copy(img, root / "mini" / "images" / img.name)
        if k < 3:
            (root / "mini" / "labels" / img.name).with_suffix(".txt").write_text(labels)
            shutil.copy(img, root / "zebras" / "images" / img.name)
            (root / "zebras" / "labels" / img.name).with_suffix(".txt").write_text(labels)
        else:
            (root / "mini" / "labels" / img.name).with_suffix(".txt").write_text("")
            ignored = (root / "gen" / "ignore" / "train" / img.name).with_suffix(".txt")  # zebras too far or hidden
            seen = labels.splitlines() + (ignored.read_text().splitlines() if ignored.exists() else [])
            other = "".join("1 " + line.split(" ", 1)[1] + "\n" for line in seen)
            (root / "mini" / "other_species" / img.name).with_suffix(".txt").write_text(other)
    return root


def test_bench_real_scores_as_val_and_counts_as_predict(mini: Path, tmp_path: Path, cli: CliRun) -> None:
    bench = _bench_real()
    row = bench.score_set("shipped", mini / "mini", IMGSZ)
    assert row["zebra_images"] == 3 and row["other_images"] == 3 and row["served"] == [IMGSZ]
    # the zebra figures: val's on the same three photos at the same size
    m, _ = evaluate(None, mini / "zebras" / "images", imgsz=IMGSZ, device="cpu")
    assert row["zebras"] == m.instances > 10
    assert row["mAP50"] == pytest.approx(m.map50, abs=1e-3) and row["mAP50-95"] == pytest.approx(m.map50_95, abs=1e-3)
    assert row["mAP50"] > 0.2  # the shipped weights find zebras in our frames
    # the false detections: predict's at the detector's threshold on the other three, and which of them sit on an
    # "other animal" (IoU >= 0.5 with one of its boxes; or the centre inside one), counted here from predict's boxes
    run = cli(["predict", str(mini / "mini" / "images"), "--out", str(tmp_path / "p"), "--imgsz", str(IMGSZ),
               "--conf", str(bench.CONF), "--no-draw", "--quiet"])
    assert run.returncode == 0, run.stderr
    found = on = centred = 0
    for other in sorted((mini / "mini" / "other_species").glob("*.txt")):
        dets = np.array([d["box_xyxy"] for d in json.loads((tmp_path / "p" / "json" / other.name).with_suffix(
            ".json").read_text())["detections"]]).reshape(-1, 4)
        cx, cy, w, h = np.loadtxt(other, ndmin=2)[:, 1:].T * np.array([[320], [180], [320], [180]])
        boxes = np.stack([cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2], 1)
        found += len(dets)
        if len(dets):
            on += int((iou_matrix(dets, boxes).max(1) >= 0.5).sum())
            mx, my = (dets[:, 0] + dets[:, 2]) / 2, (dets[:, 1] + dets[:, 3]) / 2
            centred += int(((mx[:, None] >= boxes[:, 0]) & (mx[:, None] <= boxes[:, 2]) & (my[:, None] >= boxes[:, 1])
                            & (my[:, None] <= boxes[:, 3])).any(1).sum())
    assert found > 0 and row["other_det_per_image"] == pytest.approx(found / 3, abs=1e-3)
    assert row["other_on_animal_share"] == pytest.approx(on / found, abs=1e-3)
    assert row["other_centre_on_animal_share"] == pytest.approx(centred / found, abs=1e-3) and centred >= on > 0
    assert row["other_by_class"] == {1: {"photos": 3, "det_per_image": pytest.approx(found / 3, abs=1e-3),
                                         "centred_per_image": pytest.approx(centred / 3, abs=1e-3)}}
    lines = bench.table([row])
    assert len(lines) == 3 and f"| shipped | mini | {IMGSZ} ({IMGSZ}) | 3 / {m.instances} |" in lines[2]


def test_bench_real_gives_no_figure_for_photos_a_set_lacks(mini: Path) -> None:
    """A set of zebra photos only has no false-detection figures (None, "-" in the table), not 0."""
    bench = _bench_real()
    row = bench.score_set("shipped", mini / "zebras", IMGSZ)
    assert row["other_images"] == 0 and row["other_det_per_image"] is None and row["mAP50"] is not None
    assert "| - |" in bench.table([row])[2]
