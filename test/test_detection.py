"""Our YOLO: box codec, NMS, metrics against pycocotools, checkpoints, ONNX."""

from __future__ import annotations

import contextlib
import io
import json
import os
import platform
import re
import subprocess
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch
from model_helpers import randomise_batch_norms
from pycocotools.coco import COCO
from pycocotools.cocoeval import COCOeval

from zebra_sim_ros.detection.boxes import box_iou, decode_ltrb, encode_ltrb, nms, postprocess
from zebra_sim_ros.detection.checkpoint import load_model, read_checkpoint, save_checkpoint
from zebra_sim_ros.detection.metrics import ap_by_size, evaluate_detections, precision_recall_at
from zebra_sim_ros.detection.model import (
    ModelConfig,
    Widening,
    build_model,
    count_parameters,
    p2_tensors,
    widen_state,
)
from zebra_sim_ros.errors import AssetError, ParameterError


def test_box_codec_round_trip() -> None:
    g = torch.Generator().manual_seed(0)
    anchors = torch.rand(200, 2, generator=g) * 50 + 10
    dist = torch.rand(200, 4, generator=g) * 9
    boxes = decode_ltrb(anchors, dist)
    torch.testing.assert_close(encode_ltrb(anchors, boxes, reg_max=16), dist)
    assert (boxes[:, 2:] >= boxes[:, :2]).all()


def _nms_reference(boxes: torch.Tensor, scores: torch.Tensor, thr: float) -> list[int]:
    # greedy by score, one pair at a time, on the pairwise IoUs computed once (a call per pair took 18 s a seed)
    iou = box_iou(boxes, boxes).tolist()
    order = sorted(range(len(scores)), key=lambda i: -float(scores[i]))
    keep: list[int] = []
    for i in order:
        if all(iou[i][j] <= thr for j in keep):
            keep.append(i)
    return keep


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_nms_equals_brute_force(seed: int) -> None:
    g = torch.Generator().manual_seed(seed)
    xy = torch.rand(300, 2, generator=g) * 200
    boxes = torch.cat([xy, xy + torch.rand(300, 2, generator=g) * 40 + 2], 1)
    scores = torch.rand(300, generator=g)
    for thr in (0.3, 0.5, 0.7):
        assert nms(boxes, scores, thr).tolist() == _nms_reference(boxes, scores, thr)


def test_postprocess_keeps_images_apart() -> None:
    box = torch.tensor([10.0, 10, 50, 50])
    pred = torch.zeros(2, 3, 5)
    pred[:, :, :4] = box
    pred[0, :, 4] = torch.tensor([0.9, 0.8, 0.1])
    pred[1, :, 4] = torch.tensor([0.3, 0.95, 0.2])
    out = postprocess(pred, conf=0.25, iou=0.5)
    assert [len(o) for o in out] == [1, 1]
    assert out[0][0, 4] == pytest.approx(0.9) and out[1][0, 4] == pytest.approx(0.95)


def test_postprocess_keeps_every_animal_of_a_crowded_frame() -> None:
    # 250 zebras on a grid, each found by 8 overlapping anchor points whose scores fall zebra by zebra (the first
    # zebra's 8 candidates score highest): NMS must see all 2,000 candidates to keep all 250; a fixed cap of 1,000
    # would keep the first 125 zebras only.
    k = torch.arange(250)
    corner = torch.stack([(k % 25) * 40.0, (k // 25) * 40.0], 1)
    jitter = torch.linspace(0.0, 1.4, 8)
    pred = torch.zeros(1, 250 * 8, 5)
    for j in range(8):
        pred[0, j::8, :2] = corner + jitter[j]
        pred[0, j::8, 2:4] = corner + 20 + jitter[j]
        pred[0, j::8, 4] = 0.99 - k * 0.003 - j * 0.0001
    kept = postprocess(pred, conf=0.001, iou=0.7, max_det=300)[0]
    assert len(kept) == 250
    assert len(postprocess(pred, conf=0.001, iou=0.7, max_det=300, max_nms=1000)[0]) == 125


def _random_eval_set(seed: int) -> tuple[list[np.ndarray], list[np.ndarray]]:
    rng = np.random.default_rng(seed)
    gts, preds = [], []
    for _ in range(40):
        n = int(rng.integers(0, 15))
        xy = rng.uniform(0, 600, (n, 2))
        g = np.concatenate([xy, xy + rng.uniform(4, 90, (n, 2))], 1)
        p = g + rng.normal(0, 3, g.shape)
        p[:, 2:] = np.maximum(p[:, 2:], p[:, :2] + 1)
        p = p[rng.uniform(size=n) < 0.8]
        fxy = rng.uniform(0, 600, (int(rng.integers(0, 8)), 2))
        p = np.concatenate([p, np.concatenate([fxy, fxy + rng.uniform(4, 60, fxy.shape)], 1)])
        gts.append(g)
        preds.append(np.concatenate([p, rng.uniform(0.01, 1, (len(p), 1))], 1))
    return preds, gts


def _pycocotools_map(preds: list[np.ndarray], gts: list[np.ndarray],
                     crowds: list[np.ndarray]) -> tuple[float, float]:
    """(mAP50-95, mAP50) by pycocotools, ``crowds`` as iscrowd=1 annotations."""
    stats = _pycocotools_stats(preds, gts, crowds)
    return float(stats[0]), float(stats[1])


def _pycocotools_stats(preds: list[np.ndarray], gts: list[np.ndarray], crowds: list[np.ndarray]) -> np.ndarray:
    """COCOeval's 12 summary numbers (0 AP, 1 AP50, 3-5 AP small/medium/large)."""
    images, anns, dets = [], [], []
    for i, (p, g, c) in enumerate(zip(preds, gts, crowds, strict=True)):
        images.append({"id": i + 1, "width": 700, "height": 700})
        for boxes, crowd in ((g, 0), (c, 1)):
            for b in boxes:
                anns.append({"id": len(anns) + 1, "image_id": i + 1, "category_id": 1, "iscrowd": crowd,
                             "bbox": [b[0], b[1], b[2] - b[0], b[3] - b[1]],
                             "area": float((b[2] - b[0]) * (b[3] - b[1]))})
        for b in p:
            dets.append({"image_id": i + 1, "category_id": 1, "bbox": [b[0], b[1], b[2] - b[0], b[3] - b[1]],
                         "score": float(b[4])})
    coco = COCO()
    coco.dataset = {"images": images, "annotations": anns, "categories": [{"id": 1, "name": "zebra"}]}
    with contextlib.redirect_stdout(io.StringIO()):
        coco.createIndex()
        ev = COCOeval(coco, coco.loadRes(dets), "bbox")
        ev.evaluate()
        ev.accumulate()
        ev.summarize()
    return np.asarray(ev.stats)


def test_a_count_is_the_detections_at_the_threshold_off_dont_care_zebras() -> None:
    """count_errors: per image, the detections at conf or above that are not on a don't-care zebra against the
    zebras that count; mean absolute and signed error per image, and the whole count's relative error."""
    from zebra_sim_ros.detection.metrics import count_errors, match_images

    gt = [np.array([[0.0, 0, 20, 20], [40, 40, 60, 60], [80, 80, 100, 100]]), np.zeros((0, 4))]
    ignore = [np.array([[200.0, 200, 220, 220]]), np.zeros((0, 4))]
    preds = [np.array([[0.0, 0, 20, 20, 0.9], [41, 41, 61, 61, 0.8],  # two of three zebras found
                       [300, 300, 320, 320, 0.3],  # a box on nothing, over the threshold
                       [80, 80, 100, 100, 0.1],  # the third zebra, under it
                       [200, 200, 220, 220, 0.95]]),  # on the don't-care zebra: neither counted nor missed
             np.array([[5.0, 5, 25, 25, 0.5]])]  # a box in an image of no zebra
    matched = match_images(preds, gt, ignores=ignore)
    c = count_errors(matched, 0.25)
    assert c == pytest.approx({"conf": 0.25, "images": 2, "true": 3, "counted": 4, "mae": 0.5, "bias": 0.5,
                               "relative": 1 / 3}, abs=1e-4)
    assert count_errors(matched, 0.05)["counted"] == 5 and count_errors(matched, 0.99)["counted"] == 0
    assert count_errors(matched[1:], 0.25)["relative"] is None  # no zebra to count against
    with pytest.raises(ParameterError, match="count_conf"):
        count_errors(matched, 1.5)


@pytest.mark.parametrize("seed", [3, 4])
def test_metrics_agree_with_pycocotools(seed: int) -> None:
    preds, gts = _random_eval_set(seed)
    coco_50_95, coco_50 = _pycocotools_map(preds, gts, [np.zeros((0, 4))] * len(gts))
    ours = evaluate_detections(preds, gts)
    assert ours.map50_95 == pytest.approx(coco_50_95, abs=0.005)
    assert ours.map50 == pytest.approx(coco_50, abs=0.005)
    assert 0.1 < ours.map50 < 0.95  # a set where the comparison means something
    assert 0 < ours.precision <= 1 and 0 < ours.recall <= 1


@pytest.mark.parametrize("seed", [5, 6])
def test_ignore_regions_agree_with_pycocotools_crowds(seed: int) -> None:
    """Don't-care boxes score as COCO's crowd annotations: detections on them are neither right nor wrong."""
    preds, gts = _random_eval_set(seed)
    rng = np.random.default_rng(seed)
    kept, ignores, with_inner = [], [], []
    for p, g in zip(preds, gts, strict=True):
        drop = rng.uniform(size=len(g)) < 0.3
        kept.append(g[~drop])
        ignores.append(g[drop])
        # detections well inside a don't-care box (high coverage, low IoU) and two on the same box
        c = (g[drop, :2] + g[drop, 2:]) / 2
        inner = np.concatenate([c - 1.5, c + 1.5, rng.uniform(0.3, 1, (len(c), 1))], 1)
        with_inner.append(np.concatenate([p, inner, inner + [0.5, 0, 0.5, 0, -0.01]]))
    coco_50_95, coco_50 = _pycocotools_map(with_inner, kept, ignores)
    ours = evaluate_detections(with_inner, kept, ignores=ignores)
    assert ours.map50_95 == pytest.approx(coco_50_95, abs=0.005)
    assert ours.map50 == pytest.approx(coco_50, abs=0.005)
    assert ours.instances == sum(len(g) for g in kept)  # don't-care boxes are not instances
    plain = evaluate_detections(with_inner, kept)  # the same detections, scored as false positives
    assert plain.map50 < ours.map50 - 0.05


def test_ap_by_size_agrees_with_pycocotools_area_ranges() -> None:
    preds, gts = _random_eval_set(7)
    preds = [p * [2.2, 2.2, 2.2, 2.2, 1.0] for p in preds]  # sizes 9..200 px: all three COCO ranges are filled
    gts = [g * 2.2 for g in gts]
    stats = _pycocotools_stats(preds, gts, [np.zeros((0, 4))] * len(gts))
    ours = ap_by_size(preds, gts)
    for k, name in ((3, "small"), (4, "medium"), (5, "large")):
        assert ours[name]["instances"] > 10
        assert ours[name]["mAP50-95"] == pytest.approx(stats[k], abs=0.01), name
    total = sum(ours[n]["instances"] for n in ("<8", "8-16", "16-32", "32-96", ">=96"))
    assert total == sum(len(g) for g in gts)


def test_a_box_with_a_non_finite_coordinate_never_matches() -> None:
    # a diverged model's NaN box is a false positive: ranked first, it halves the precision at full recall (the loop
    # before the candidate walk let a NaN IoU take the zebra and scored 1.0)
    gts = [np.array([[10.0, 10, 50, 40]])]
    for bad in (np.nan, np.inf):
        preds = [np.array([[bad, 10, 50, 40, 0.9], [11, 10, 50, 41, 0.8]])]
        m = evaluate_detections(preds, gts)
        assert m.recall == pytest.approx(1.0) and m.map50 == pytest.approx(0.5), (bad, m.to_dict())


def test_precision_recall_at_a_threshold() -> None:
    gts = [np.array([[0.0, 0, 10, 10], [20, 20, 40, 50]]), np.zeros((0, 4))]
    preds = [np.array([[0.0, 0, 10, 10, 0.9], [100, 100, 120, 120, 0.5], [20, 20, 40, 50, 0.1]]),
             np.array([[5.0, 5, 30, 30, 0.6]])]
    assert precision_recall_at(preds, gts, 0.25) == pytest.approx((1 / 3, 1 / 2))
    assert precision_recall_at(preds, gts, 0.05) == pytest.approx((2 / 4, 1.0))
    assert precision_recall_at(preds, gts, 0.95) == (0.0, 0.0)


def test_perfect_and_empty_predictions() -> None:
    gts = [np.array([[0.0, 0, 10, 10], [20, 20, 40, 50]])]
    perfect = [np.array([[0.0, 0, 10, 10, 0.9], [20, 20, 40, 50, 0.8]])]
    m = evaluate_detections(perfect, gts)
    assert m.map50 == pytest.approx(1.0) and m.map50_95 == pytest.approx(1.0)
    assert evaluate_detections([np.zeros((0, 5))], gts).map50 == pytest.approx(0.0, abs=1e-6)


def test_a_herd_of_over_100_zebras_is_scored_whole() -> None:
    """A frame may show 180 labelled zebras: every detection the detector publishes (its max_det, 300) counts,
    not COCO's 100 per image, which capped recall at 100 / n on crowded frames."""
    from zebra_sim_ros.detection.config import DetectorConfig
    from zebra_sim_ros.detection.metrics import MAX_DETECTIONS

    xs = np.arange(180, dtype=np.float64) * 12.0
    gts = [np.stack([xs, np.zeros(180), xs + 10, np.full(180, 10.0)], 1)]
    found = [np.concatenate([gts[0], np.linspace(0.9, 0.3, 180)[:, None]], 1)]
    assert MAX_DETECTIONS == DetectorConfig().max_det >= 250  # a placement holds up to 250 zebras
    m = evaluate_detections(found, gts)
    assert m.recall == pytest.approx(1.0) and m.map50 == pytest.approx(1.0)
    capped = evaluate_detections(found, gts, max_det=100)
    assert capped.recall == pytest.approx(100 / 180, abs=0.01) and capped.map50 < 0.6


def test_paired_bootstrap_draws_whole_groups_and_pairs_the_runs() -> None:
    """Resamples of a set's placements: one group holds every image, so each draw is the set itself; a group drawn
    takes all its images; two runs are scored on the same draws, so a run with a false positive less never scores
    under the other; the same seed gives the same draws."""
    from zebra_sim_ros.detection.metrics import match_images, paired_bootstrap
    from zebra_sim_ros.errors import ParameterError

    preds, gts = _random_eval_set(3)
    whole = evaluate_detections(preds, gts)
    matched = match_images(preds, gts)
    once = paired_bootstrap([matched], ["one"] * len(gts), samples=5, seed=1)
    assert once.shape == (5, 1, 10) and np.allclose(once[:, 0], whole.ap, atol=1e-12)
    # two placements of two views each: one found perfectly, one not at all (its detections all elsewhere)
    box = np.array([[0.0, 0, 10, 10], [20, 20, 40, 50]])
    hit = np.concatenate([box, [[0.9], [0.8]]], 1)
    miss = np.concatenate([box + 100, [[0.7], [0.6]]], 1)
    g2 = [box] * 4
    p2 = [hit, hit, miss, miss]
    mixed = evaluate_detections(p2, g2).map50
    draws = paired_bootstrap([match_images(p2, g2)], ["a", "a", "b", "b"], samples=200, seed=2, map50_only=True)
    values = draws[:, 0, 0]
    assert np.all(draws[:, 0, 1:] == 0.0)  # only AP50 was computed
    for v in (1.0, 0.0, mixed):  # both a, both b, or one of each: nothing else
        assert np.isclose(values, v, atol=1e-9).any()
    assert np.isclose(values[:, None], [1.0, 0.0, mixed], atol=1e-9).any(1).all()
    # pairing: run B is run A without its lowest-scored false positive (at IoU 0.5) in each image
    fewer = []
    for p, m in zip(preds, matched, strict=True):
        p = p[np.argsort(-p[:, 4], kind="mergesort")]  # the order match_images keeps
        fp = np.flatnonzero(~m.tp[0] & ~m.ignored[0])
        fewer.append(np.delete(p, fp[-1], axis=0) if len(fp) else p)
    groups = [i // 3 for i in range(len(gts))]
    ab = paired_bootstrap([matched, match_images(fewer, gts)], groups, samples=100, seed=3, map50_only=True)
    assert np.all(ab[:, 1, 0] >= ab[:, 0, 0] - 1e-12) and np.ptp(ab[:, 0, 0]) > 0.01  # the draws do differ
    assert np.array_equal(ab, paired_bootstrap([matched, match_images(fewer, gts)], groups, 100, 3, True))
    with pytest.raises(ParameterError, match="samples"):
        paired_bootstrap([matched], groups, samples=0)
    with pytest.raises(ParameterError, match="seed.*-1"):
        paired_bootstrap([matched], groups, seed=-1)
    with pytest.raises(ParameterError, match="runs"):
        paired_bootstrap([matched, matched[:-1]], groups)


def test_val_intervals_draw_a_placements_views_together() -> None:
    """``val --bootstrap``: a generated set's three views of a placement share its key; resampled, a set of one
    placement found and one missed spans both extremes, and its figures lie inside the intervals."""
    from zebra_sim_ros.detection.evaluate import ImagePredictions, bootstrap_interval, placement, score

    assert placement("d/images/val/savanna_far_12_000003_drone_1.jpg") == "savanna_far_12_000003"
    assert placement("photo_7.jpg") == "photo_7"  # not a generated view: a placement of its own
    box = np.array([[0.0, 0, 10, 10], [20, 20, 40, 50]])
    hit, miss = np.concatenate([box, [[0.9], [0.8]]], 1), np.concatenate([box + 100, [[0.7], [0.6]]], 1)
    per_image = [ImagePredictions(f"w_far_1_00000{k}_drone_{d}.jpg", hit if k == 0 else miss, box, np.zeros((0, 4)),
                                  640) for k in (0, 1) for d in range(3)]
    b = bootstrap_interval(per_image, 400, seed=5)
    assert b["placements"] == 2 and b["samples"] == 400 and b["seed"] == 5
    assert b["mAP50 95%"] == pytest.approx([0.0, 1.0], abs=1e-9)
    assert b["mAP50 95%"][0] <= score(per_image).map50 <= b["mAP50 95%"][1]
    assert bootstrap_interval(per_image, 400, seed=5) == b


def test_model_sizes_and_shapes() -> None:
    n, s = build_model(ModelConfig(size="n")), build_model(ModelConfig(size="s"))
    assert 2.5e6 < count_parameters(n) < 3.5e6 and 10e6 < count_parameters(s) < 12.5e6
    n.eval()
    with torch.no_grad():
        out = n(torch.rand(2, 3, 256, 320))
    assert out.shape == (2, (32 * 40 + 16 * 20 + 8 * 10), 5)
    assert (out[..., 4] >= 0).all() and (out[..., 4] <= 1).all()
    with pytest.raises(ParameterError, match="model"):
        ModelConfig(size="xl")


def test_checkpoint_round_trip_and_bad_files(tmp_path: Path) -> None:
    model = build_model(ModelConfig(size="n", imgsz=320)).eval()
    save_checkpoint(tmp_path / "a.pt", model, epoch=3, metrics={"mAP50": 0.5})
    loaded, ckpt = load_model(tmp_path / "a.pt")
    assert ckpt["epoch"] == 3 and loaded.cfg == model.cfg
    x = torch.rand(1, 3, 320, 320)
    with torch.no_grad():
        torch.testing.assert_close(loaded(x), model(x), atol=1e-4, rtol=1e-4)  # folded BN, channels-last: float noise
    with pytest.raises(ParameterError, match="weights"):
        read_checkpoint(tmp_path / "missing.pt")
    (tmp_path / "bad.pt").write_bytes((tmp_path / "a.pt").read_bytes()[:5000])
    with pytest.raises(AssetError, match="cannot be read"):
        read_checkpoint(tmp_path / "bad.pt")
    torch.save({"format": "something else"}, tmp_path / "other.pt")
    with pytest.raises(AssetError, match="not a"):
        read_checkpoint(tmp_path / "other.pt")


def test_export_blends_a_fine_tuned_checkpoint_with_its_base(tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    """``export --blend-base B --blend a``: every float tensor is (1 - a) B + a W, through the CLI; the record
    says so; a base of another architecture and a share outside 0..1 are refused by name."""
    from zebra_sim_ros.cli import main as cli_main

    torch.manual_seed(0)
    base, tuned = build_model(ModelConfig(size="n", imgsz=256)), build_model(ModelConfig(size="n", imgsz=256))
    for m in (base, tuned):
        for p in m.parameters():
            p.data.normal_()
    save_checkpoint(tmp_path / "base.pt", base)
    save_checkpoint(tmp_path / "tuned.pt", tuned, epoch=7)
    out = tmp_path / "blend.pt"
    assert cli_main(["export", "--weights", str(tmp_path / "tuned.pt"), "--format", "pt", "--blend-base",
                     str(tmp_path / "base.pt"), "--blend", "0.25", "--out", str(out)]) == 0
    ck = read_checkpoint(out)
    assert ck["blended"]["alpha"] == pytest.approx(0.25) and ck["epoch"] == 7
    b, t = base.state_dict(), tuned.state_dict()
    for k, v in ck["model"].items():
        if v.dtype.is_floating_point:  # stored as fp16, like every serving checkpoint
            torch.testing.assert_close(v.float(), (0.75 * b[k] + 0.25 * t[k]).half().float(), atol=1e-3, rtol=1e-3)
        else:
            assert torch.equal(v, t[k])
    save_checkpoint(tmp_path / "small.pt", build_model(ModelConfig(size="s", imgsz=256)))
    capsys.readouterr()
    assert cli_main(["export", "--weights", str(tmp_path / "tuned.pt"), "--format", "pt", "--blend-base",
                     str(tmp_path / "small.pt"), "--blend", "0.5", "--out", str(out)]) == 2
    assert "'--blend-base'" in capsys.readouterr().err
    assert cli_main(["export", "--weights", str(tmp_path / "tuned.pt"), "--format", "pt", "--blend-base",
                     str(tmp_path / "base.pt"), "--blend", "1.5", "--out", str(out)]) == 2
    assert "'--blend'" in capsys.readouterr().err
    # a share without a base would be dropped without a word: refused, naming both options
    assert cli_main(["export", "--weights", str(tmp_path / "tuned.pt"), "--format", "pt", "--blend", "0.5",
                     "--out", str(tmp_path / "alone.pt")]) == 2
    err = capsys.readouterr().err
    assert "'--blend'" in err and "--blend-base" in err and not (tmp_path / "alone.pt").exists()


def test_a_p2_run_blends_with_its_three_level_base_on_the_shared_tensors() -> None:
    """``--blend-base`` of a four-level (``--p2``) fine-tune and the three-level checkpoint it started from: the
    shared tensors are blended, the stride-4 level is the fine-tune's; the other way round is refused by name."""
    from zebra_sim_ros.detection.export import blend_weights

    torch.manual_seed(1)
    base, tuned = build_model(ModelConfig(size="n")), build_model(ModelConfig(size="n", p2=True))
    for m in (base, tuned):
        for p in m.parameters():
            p.data.normal_()
    b, t = base.state_dict(), tuned.state_dict()
    out = blend_weights(t, b, 0.25)
    assert set(out) == set(t)
    level = [k for k in t if k not in b]
    assert level and level == p2_tensors(t)
    for k, v in out.items():
        if k in level or not v.dtype.is_floating_point:
            assert torch.equal(v, t[k])
        else:
            torch.testing.assert_close(v, 0.75 * b[k] + 0.25 * t[k])
    with pytest.raises(ParameterError, match="'--blend-base'.*box_head_p2|'--blend-base'.*cls_head_p2|"
                                             "'--blend-base'.*td2"):
        blend_weights(b, t, 0.5)


def test_onnx_export_gives_the_same_boxes(tmp_path: Path) -> None:
    ort = pytest.importorskip("onnxruntime")
    from zebra_sim_ros.detection.export import export_onnx

    torch.manual_seed(0)
    model = build_model(ModelConfig(size="n", imgsz=256)).eval()
    save_checkpoint(tmp_path / "m.pt", model)
    path = export_onnx(tmp_path / "m.pt", tmp_path / "m.onnx")
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    x = torch.rand(2, 3, 256, 256)
    onnx_out = torch.from_numpy(sess.run(None, {"images": x.numpy()})[0])
    with torch.no_grad():
        torch_out = model(x)
    torch.testing.assert_close(onnx_out, torch_out, atol=1e-4, rtol=1e-4)
    for a, b in zip(postprocess(onnx_out, 0.01, 0.7), postprocess(torch_out, 0.01, 0.7), strict=True):
        assert len(a) == len(b)
        torch.testing.assert_close(a, b, atol=1e-3, rtol=1e-3)


def test_serving_checkpoint_keeps_the_weights_and_sets_the_default_size(tmp_path: Path) -> None:
    from zebra_sim_ros.cli import main
    from zebra_sim_ros.detection.predict import detect

    torch.manual_seed(0)
    model = build_model(ModelConfig(size="n", imgsz=256)).eval()
    save_checkpoint(tmp_path / "m.pt", model, epoch=3, train_args={"imgsz": 256, "model": "n"})
    assert main(["export", "--weights", str(tmp_path / "m.pt"), "--format", "pt", "--imgsz", "320",
                 "--out", str(tmp_path / "s.pt")]) == 0
    ckpt = read_checkpoint(tmp_path / "s.pt")
    assert ckpt["config"]["imgsz"] == 320 and ckpt["train_args"]["imgsz"] == 256 and ckpt["epoch"] == 3
    assert ckpt["exported"] == {"from_config_imgsz": 256, "imgsz": 320, "frame": 0, "previous": None}
    assert "optimizer" not in ckpt and all(v.dtype == torch.float16 for v in ckpt["model"].values()
                                           if v.dtype.is_floating_point)
    src, _ = load_model(tmp_path / "m.pt")
    served, _ = load_model(tmp_path / "s.pt")
    img = np.random.default_rng(0).integers(0, 255, (180, 320, 3), dtype=np.uint8)
    a = detect(src, [img], imgsz=320, conf=0.0)[0]
    b = detect(served, [img], conf=0.0)[0]  # the default size is now 320
    assert len(a) > 0 and len(a) == len(b)
    torch.testing.assert_close(torch.as_tensor(b)[:, :4], torch.as_tensor(a)[:, :4], atol=0.5, rtol=0.01)  # fp16
    assert main(["export", "--format", "tflite", "--out", str(tmp_path / "x")]) == 2  # named on stderr
    assert not (tmp_path / "x").exists()
    # --frame records the training frames of a checkpoint that predates the record: 320 px at 160 px frames is a
    # scale of 2, so a 320 px frame is served at 640; exporting again keeps the history.
    (tmp_path / "recipe.txt").write_text("zebra-sim generate --seed 5 ...\nzebra-sim train ...\n")
    assert main(["export", "--weights", str(tmp_path / "s.pt"), "--format", "pt", "--frame", "160",
                 "--recipe", str(tmp_path / "recipe.txt"), "--out", str(tmp_path / "f.pt")]) == 0
    framed = read_checkpoint(tmp_path / "f.pt")
    assert framed["config"]["frame"] == 160 and framed["exported"]["previous"] == ckpt["exported"]
    assert framed["recipe"] == (tmp_path / "recipe.txt").read_text()  # kept verbatim
    assert main(["export", "--weights", str(tmp_path / "s.pt"), "--format", "pt", "--recipe",
                 str(tmp_path / "missing.txt"), "--out", str(tmp_path / "bad.pt")]) == 2
    assert load_model(tmp_path / "f.pt")[0].cfg.serve_size(320) == 640
    for bad in (["--frame", "0"], ["--frame", "160", "--format", "onnx"]):
        assert main(["export", "--weights", str(tmp_path / "s.pt"), "--format", "pt", *bad,
                     "--out", str(tmp_path / "bad.pt")]) == 2
    assert not (tmp_path / "bad.pt").exists()


@pytest.mark.parametrize("rect", [True, False])
def test_letterbox_geometry_round_trips_boxes(rect: bool) -> None:
    from zebra_sim_ros.detection.predict import preprocess, unletterbox

    wide = np.zeros((360, 640, 3), np.uint8)
    wide[100:140, 200:260] = 255  # a white block at x 200..260, y 100..140
    tall = np.zeros((300, 200, 3), np.uint8)
    assert preprocess([wide, tall], 320, rect=rect)[0].shape == (2, 3, 320, 320)  # one shape fits the batch
    odd = np.zeros((175, 320, 3), np.uint8)  # 175 * 352 / 320 = 192.5: both roundings must agree
    assert preprocess([odd], 352, rect=rect)[0].shape == ((1, 3, 224, 352) if rect else (1, 3, 352, 352))
    x, meta = preprocess([wide], 320, rect=rect)
    assert x.shape == ((1, 3, 192, 320) if rect else (1, 3, 320, 320))  # 180 -> next multiple of 32
    r, left, top = meta[0]
    ys, xs = np.nonzero(x[0, 0].numpy() > 0.9)
    found = torch.tensor([[xs.min(), ys.min(), xs.max() + 1, ys.max() + 1]], dtype=torch.float32)
    back = unletterbox(found, r, left, top, 640, 360)[0].tolist()
    assert back == pytest.approx([200, 100, 260, 140], abs=2.5)
    model = build_model(ModelConfig(size="n", imgsz=320)).eval()
    with torch.no_grad():
        feats = model.features(x)  # rectangular input through the whole network
        out = model(x)
    h, w = x.shape[2:]
    assert [tuple(f.shape[2:]) for f in feats] == [(h // s, w // s) for s in (8, 16, 32)]
    assert out.shape == (1, sum((h // s) * (w // s) for s in (8, 16, 32)), 5)


def test_inference_size_is_one_rule_scaled_from_the_checkpoints_training_frames() -> None:
    from zebra_sim_ros.detection.predict import NATIVE, inference_size

    served = ModelConfig(imgsz=1088, frame=640)  # the shipped weights: 1088 px for 640 px frames, a scale of 1.7
    assert inference_size(served, 640) == 1088  # exactly the serving size on frames of the training size
    assert inference_size(served, 1280) == 2176  # twice the frame, twice the input: zebras stay the size learnt
    assert inference_size(served, 320) == 544
    assert inference_size(served, 1000) == 1728  # 1700 rounded up to a multiple of 32
    assert inference_size(served, 30) == 64 and inference_size(served, 4000) == 4096  # within the model's range
    assert inference_size(served, 1280, imgsz=640) == 640  # --imgsz overrides
    assert inference_size(served, 1280, imgsz=640, scale=1.3) == 1664  # and scale overrides both
    assert inference_size(served, 1000, imgsz=NATIVE) == 1024  # -1: the frame's own side, to a multiple of 32
    unknown = ModelConfig(imgsz=832)  # a checkpoint that does not record its training frames
    assert [inference_size(unknown, s) for s in (320, 640, 1280)] == [832, 832, 832]
    assert [inference_size(ModelConfig(imgsz=i, frame=f), 1280) for i, f in ((832, 640), (640, 640), (1088, 1280))] \
        == [1664, 1280, 1088]
    with pytest.raises(ParameterError, match="'frame'"):
        ModelConfig(frame=-1)


def test_detect_sizes_each_batch_by_the_rule() -> None:
    from zebra_sim_ros.detection.predict import NATIVE, detect

    model = build_model(ModelConfig(size="n", imgsz=128, frame=150)).eval()  # serves at 128/150 of the frame
    frame = np.random.default_rng(0).integers(0, 256, (180, 300, 3), np.uint8)

    def same(a: list[np.ndarray], b: list[np.ndarray]) -> bool:  # one code path run twice: equal to float noise
        return a[0].shape == b[0].shape and np.allclose(a[0], b[0], atol=1e-3)

    by_rule = detect(model, [frame], conf=0.0, max_det=50)  # 300 px long side -> 256
    assert same(by_rule, detect(model, [frame], 256, conf=0.0, max_det=50))
    assert not same(by_rule, detect(model, [frame], 128, conf=0.0, max_det=50))  # config.imgsz alone is not it
    native = detect(model, [frame], NATIVE, conf=0.0, max_det=50)
    assert same(native, detect(model, [frame], 320, conf=0.0, max_det=50))
    scaled = detect(model, [frame], 128, conf=0.0, max_det=50, scale=1.3)  # scale wins over imgsz: 390 -> 416
    assert same(scaled, detect(model, [frame], 416, conf=0.0, max_det=50))
    assert not same(scaled, native)


def test_served_ms_per_image_leaves_the_first_batch_out() -> None:
    """val's serving cost is ms per image over the batches after the first (its start-up) where others ran."""
    from zebra_sim_ros.detection.evaluate import steady_ms_per_image

    assert steady_ms_per_image([(5.0, 2), (1.0, 2), (1.4, 2), (0.6, 2)]) == pytest.approx(500.0)  # not 1,000
    assert steady_ms_per_image([(9.0, 8), (4.0, 8), (0.9, 1)]) == pytest.approx(4900 / 9)  # a short last batch counts
    assert steady_ms_per_image([(3.0, 4)]) == pytest.approx(750.0)  # one batch: all there is
    assert steady_ms_per_image([]) == pytest.approx(0.0)


def test_validation_serves_each_image_as_detect_does(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """val sizes each image by the detector's rule and letterboxes it as inference does (sides padded to a multiple
    of 32, not to a square), so val, the node and bag eval see the same pixels; frames of several sizes share a
    batch."""
    import cv2

    from zebra_sim_ros.detection.evaluate import make_loader, predictions
    from zebra_sim_ros.detection.predict import detect, inference_size

    torch.manual_seed(0)
    model = build_model(ModelConfig(size="n", imgsz=128, frame=150)).eval()
    rng = np.random.default_rng(3)
    frames = {"a": rng.integers(0, 256, (180, 300, 3), np.uint8), "b": rng.integers(0, 256, (100, 70, 3), np.uint8)}
    (tmp_path / "images").mkdir()
    for name, f in frames.items():
        cv2.imwrite(str(tmp_path / "images" / f"{name}.png"), f[..., ::-1])
    loader = make_loader(tmp_path / "images", lambda side: inference_size(model.cfg, side), batch=2)
    imgs, _, metas = next(iter(loader))
    assert [m.imgsz for m in metas] == [256, 96]  # 300 px x 128/150 -> 256; 100 px -> 85.3, up to 96
    assert [m.input for m in metas] == [(160, 256), (96, 96)]  # 154x256 and 96x67, sides up to multiples of 32
    assert tuple(imgs.shape) == (2, 3, 160, 256)  # one batch: the smaller image padded at the bottom and right
    batches: list[tuple[float, int]] = []
    got = predictions(model, loader, conf=0.0, batch_seconds=batches)
    assert len(batches) == 1 and batches[0][1] == 2 and batches[0][0] > 0  # one batch of both images, timed
    for p, name in zip(got, sorted(frames), strict=True):
        want = detect(model, [frames[name]], conf=0.0)[0]  # the same default max_det as predictions
        assert p.imgsz == inference_size(model.cfg, max(frames[name].shape[:2]))
        assert p.detections.shape == (len(want), 5)
        np.testing.assert_allclose(p.detections, want[:, :5], atol=1e-2)
    # The command line: the sizes it served at, and a scale that overrides them; a bad scale is refused by name.
    from zebra_sim_ros.cli import main

    save_checkpoint(tmp_path / "m.pt", model)
    for extra, sizes in (([], [96, 256]), (["--imgsz", "128", "--bootstrap", "20"], 128),
                         (["--scale", "0.5"], [64, 160])):
        assert main(["val", "--weights", str(tmp_path / "m.pt"), "--data", str(tmp_path / "images"), "--device", "cpu",
                     "--json", "--plots", str(tmp_path / "plots"), *extra]) == 0
        text = capsys.readouterr().out
        out = json.loads(text.splitlines()[-1])
        assert out["imgsz"] == sizes, extra
        assert out["ms_per_image"] > 0 and f"{out['ms_per_image']} ms per image on cpu" in text  # the serving cost
        assert set(out["ap_by_size"]) == {"<8", "8-16", "16-32", "32-96", ">=96", "small", "medium", "large"}
        assert out["count"]["conf"] == pytest.approx(0.25) and out["count"]["images"] == 2  # the detector's conf
        assert f"count at conf 0.25: {out['count']['counted']} counted for {out['count']['true']} zebras" in text
        assert all(cv2.imread(out["plots"][k]) is not None for k in ("pr_curve", "predictions"))
        if "--bootstrap" in extra:  # two images, each its own placement; nothing labelled, so AP 0 in every draw
            assert out["bootstrap"] == {"samples": 20, "seed": 0, "placements": 2, "mAP50 95%": [0.0, 0.0],
                                        "mAP50-95 95%": [0.0, 0.0]}
            assert "95% intervals over 20 resamples of the 2 placements (seed 0)" in text
    for bad in (["--bootstrap", "-1"], ["--bootstrap", "5", "--bootstrap-seed", "-2"]):  # refused before any work
        assert main(["val", "--data", str(tmp_path / "images"), *bad]) == 2
        assert bad[-2] in capsys.readouterr().err
    for bad in ("9", "-0.5", "0.2"):
        assert main(["val", "--data", str(tmp_path / "images"), "--scale", bad]) == 2
        assert f"argument --scale: '{bad}': allowed 0 (off) or 0.25..4" in capsys.readouterr().err


def _min_sqdiff(image: np.ndarray, template: np.ndarray) -> int:
    """The smallest sum of squared differences of ``template`` over every position in ``image``, in exact integers.

    cv2.matchTemplate(TM_SQDIFF) computes it in float32 (sum of squares minus twice a correlation), so an exact
    match reads 0.0, 2.3e-10 or 0.5 depending on the CPU's code path (IPP, AVX-512 or not)."""
    windows = np.lib.stride_tricks.sliding_window_view(image.astype(np.int64), template.shape)
    return int(((windows - template.astype(np.int64)) ** 2).sum(axis=(-3, -2, -1)).min())


@pytest.mark.parametrize("imgsz", [96, 48])  # enlarging and shrinking the 60x40 frame
def test_mosaic_tiles_are_resized_as_inference_resizes(tmp_path: Path, imgsz: int) -> None:
    """Training at an imgsz above the frames' size must upsample them as letterbox does when served."""
    import cv2

    from zebra_sim_ros.detection.data import Augment, YoloDataset, letterbox

    frame = np.random.default_rng(1).integers(0, 256, (40, 60, 3), np.uint8)
    (tmp_path / "images").mkdir()
    cv2.imwrite(str(tmp_path / "images" / "a.png"), frame[..., ::-1])
    still = replace(Augment.none(), mosaic=1.0)
    served, r, (left, top) = letterbox(frame, imgsz)
    tile = served[top:top + round(40 * r), left:left + round(60 * r)]  # the frame as inference sees it
    th, tw = tile.shape[:2]
    k = 6
    corners = [tile[:k, :k], tile[:k, tw - k:], tile[th - k:, :k], tile[th - k:, tw - k:]]
    for epoch in range(3):  # three random mosaic centres
        ds = YoloDataset(tmp_path / "images", imgsz, still, seed=epoch)
        sample = (ds[0][0].numpy().transpose(1, 2, 0) * 255).round().astype(np.uint8)
        # every tile is this frame; the mosaic centre shows a corner of each of the four, one at least whole
        best = min(_min_sqdiff(sample, c) for c in corners)
        assert best == 0, (epoch, best)  # pixel for pixel: one grey level off anywhere in a corner would be >= 1


@pytest.mark.parametrize(("setting", "named"), [({"imgsz": 100}, "'--imgsz'"), ({"val_every": 0}, "'--val-every'"),
                                                ({"workers": -1}, "'--workers'"), ({"lr0": 0.0}, "'--lr0'"),
                                                ({"max_train_images": -1}, "'--max-train-images'"),
                                                ({"close_mosaic": -2}, "'--close-mosaic'"),
                                                ({"warmup_epochs": -1.0}, "'--warmup-epochs'"),
                                                ({"amp": "fp8"}, "'--amp'"), ({"crop": 640}, "'--crop'"),
                                                ({"crop": 100}, "'--crop'")])
def test_train_settings_are_checked_before_training(setting: dict[str, object], named: str) -> None:
    from zebra_sim_ros.detection.train import TrainConfig

    with pytest.raises(ParameterError, match=named):
        TrainConfig(data="d.yaml", out="o", **setting).check()  # type: ignore[arg-type]


def test_autocast_dtype_follows_the_device(monkeypatch: pytest.MonkeyPatch) -> None:
    from zebra_sim_ros.detection.checkpoint import amp_dtype

    cpu, cuda = torch.device("cpu"), torch.device("cuda")
    assert amp_dtype("auto", cuda) == torch.float16 and amp_dtype("off", cuda) is None
    assert amp_dtype("bf16", cpu) == torch.bfloat16 and amp_dtype("off", cpu) is None
    with pytest.raises(ParameterError, match="'--amp'"):
        amp_dtype("fp16", cpu)
    for var in ("ONEDNN_MAX_CPU_ISA", "DNNL_MAX_CPU_ISA"):  # oneDNN uncapped, whatever this process was given
        monkeypatch.delenv(var, raising=False)
    for bf16, amx, want in ((True, False, torch.bfloat16), (False, True, torch.bfloat16), (False, False, None)):
        monkeypatch.setattr(torch.cpu, "_is_avx512_bf16_supported", lambda v=bf16: v)
        monkeypatch.setattr(torch.cpu, "_is_amx_tile_supported", lambda v=amx: v)
        assert amp_dtype("auto", cpu) == want  # emulated bfloat16 is slower than float32: not chosen
    monkeypatch.setattr(torch.cpu, "_is_avx512_bf16_supported", lambda: True)  # the instructions, but oneDNN capped:
    for cap, want in (("AVX2", None), ("avx512_core_vnni", None), ("AVX512_CORE_BF16", torch.bfloat16),
                      ("AVX512_CORE_AMX", torch.bfloat16), ("ALL", torch.bfloat16), ("", torch.bfloat16)):
        monkeypatch.setenv("ONEDNN_MAX_CPU_ISA", cap)
        assert amp_dtype("auto", cpu) == want, cap


AVX2_PROBE = """
import ctypes, json, cv2, numpy, torch
from numpy._core._multiarray_umath import __cpu_features__ as f
from zebra_sim_ros.detection.checkpoint import amp_dtype
conv = torch.nn.Conv2d(16, 32, 3).to(memory_format=torch.channels_last)
with torch.no_grad():  # oneDNN says which instructions it ran this with (ONEDNN_VERBOSE)
    conv(torch.randn(2, 16, 64, 64).to(memory_format=torch.channels_last))
core = None  # the OpenBLAS that numpy loaded, found among the process's mapped files
for lib in {line.split()[-1] for line in open("/proc/self/maps") if "openblas" in line.lower()}:
    for name in ("scipy_openblas_get_corename64_", "scipy_openblas_get_corename", "openblas_get_corename"):
        if hasattr(ctypes.CDLL(lib), name):
            core = getattr(ctypes.CDLL(lib), name)
            core.restype = ctypes.c_char_p
print(json.dumps({"aten": torch.backends.cpu.get_cpu_capability(), "x86_v4": bool(f.get("X86_V4", False)),
                  "opencv": cv2.getCPUFeaturesLine().split(), "openblas": core().decode() if core else None,
                  "amp": str(amp_dtype("auto", torch.device("cpu")))}))
"""
AVX2_ENV = Path(__file__).resolve().parents[1] / "scripts" / "cpu_avx2.env"
# what the file sets, and oneDNN's older name for its cap: none is taken from the environment the tests run in
CPU_CAPS = {*re.findall(r"^export (\w+)=", AVX2_ENV.read_text(), re.M), "DNNL_MAX_CPU_ISA"}


def test_the_avx2_environment_keeps_every_library_off_avx512() -> None:
    """``ZEBRA_SIM_CPU=avx2 bash scripts/test.sh`` sources scripts/cpu_avx2.env to run the suite as on our CPUs
    without AVX-512: in a process started under it oneDNN's convolutions and torch's ATen kernels run AVX2 code,
    NumPy dispatches no x86-64-v4 loops and its OpenBLAS takes the Haswell kernels, OpenCV reports its AVX-512
    dispatch switched off, and ``--amp auto`` trains in float32. Only where there is AVX2 to fall back to."""
    if platform.machine() not in ("x86_64", "AMD64") or torch.backends.cpu.get_cpu_capability() == "DEFAULT":
        pytest.skip(f"not an x86-64 CPU with AVX2 ({platform.machine()}, "
                    f"{torch.backends.cpu.get_cpu_capability()}): nothing to cap")
    root = Path(__file__).resolve().parents[1]
    env = {k: v for k, v in os.environ.items() if k not in CPU_CAPS} | {"ONEDNN_VERBOSE": "1"}
    out = subprocess.run(["bash", "-c", 'source scripts/cpu_avx2.env && exec "$0" -c "$1"', sys.executable,
                          AVX2_PROBE], cwd=root, env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "Trying to disable unknown CPU feature" not in out.stderr, out.stderr  # a name OpenCV does not know
    got = json.loads(out.stdout.strip().splitlines()[-1])
    isas = {line.split("isa:")[1].split(",")[0] for line in out.stdout.splitlines() if ",isa:" in line}
    assert isas == {"Intel AVX2"}, isas  # oneDNN's own report of the convolution
    assert got["aten"] == "AVX2" and not got["x86_v4"] and got["amp"] == "None", got
    assert got["openblas"] == "Haswell", f"numpy's OpenBLAS: {got['openblas']} (None: not found in the process)"
    assert all(w.endswith("?") for w in got["opencv"] if "AVX512" in w), got  # compiled in, switched off


def test_serving_in_bfloat16_decodes_boxes_in_float32(tmp_path: Path) -> None:
    """``amp``: the features in bfloat16, the anchors, strides and boxes in float32. On a 2176 px wide input the
    stride-8 cell centres reach 272.5, which bfloat16 rounds by up to a cell: boxes decoded under autocast are off
    by pixels, ours by a hair. A bad mode is refused naming the option that set it."""
    from zebra_sim_ros.detection.checkpoint import load_model

    torch.manual_seed(0)
    model = build_model(ModelConfig(size="n", imgsz=640)).eval().fuse()
    x = torch.rand(1, 3, 64, 2176)
    with torch.no_grad():
        ref = model(x)
        with torch.autocast("cpu", dtype=torch.bfloat16):  # the whole forward in bfloat16: what must not happen
            naive = model(x)
        model.serve_dtype = torch.bfloat16
        served = model(x)
    assert isinstance(served, torch.Tensor) and served.dtype == torch.float32
    assert float((naive[..., :4].float() - ref[..., :4]).abs().max()) > 4.0  # the rounding this guards against
    assert float((served[..., :4] - ref[..., :4]).abs().max()) < 0.5
    torch.testing.assert_close(served[..., 4:], ref[..., 4:], atol=0.02, rtol=0.0)  # probabilities
    save_checkpoint(tmp_path / "w.pt", build_model(ModelConfig(size="n", imgsz=128)))
    assert load_model(tmp_path / "w.pt", amp="bf16")[0].serve_precision == "bfloat16"
    assert load_model(tmp_path / "w.pt")[0].serve_precision == "float32"  # unless asked
    with pytest.raises(ParameterError, match="'amp'.*auto"):
        load_model(tmp_path / "w.pt", amp="half", amp_name="amp")


def test_a_dataset_yaml_may_list_several_training_sets(tmp_path: Path) -> None:
    from zebra_sim_ros.detection.data import YoloDataset, generate_settings, resolve_split, resolve_splits

    for name, n in (("far", 3), ("low", 2)):  # two generated sets: images, labels and their generate.json
        for split in ("train", "val"):
            (tmp_path / name / "images" / split).mkdir(parents=True)
        for k in range(n):
            (tmp_path / name / "images" / "train" / f"{name}{k}.jpg").write_bytes(b"")
        (tmp_path / name / "images" / "val" / f"{name}v.jpg").write_bytes(b"")
        (tmp_path / name / "generate.json").write_text(json.dumps({"config": {"strategy": name, "seed": n}}))
    y = tmp_path / "both.yaml"
    y.write_text("path: .\ntrain: [far/images/train, low/images/train]\nval: far/images/val\nnc: 1\n")
    folders = resolve_splits(y, "train")
    assert folders == [tmp_path / "far/images/train", tmp_path / "low/images/train"]
    ds = YoloDataset(folders, 64)
    assert [f.name for f in ds.files] == ["far0.jpg", "far1.jpg", "far2.jpg", "low0.jpg", "low1.jpg"]
    assert resolve_split(y, "val") == tmp_path / "far/images/val"  # a single folder reads as before
    with pytest.raises(ParameterError, match="one 'train' folder here \\(2 listed\\)"):
        resolve_split(y, "train")  # a command that reads one folder says so
    g = generate_settings(y)  # a checkpoint records every listed set's settings
    assert g is not None and sorted(c["strategy"] for c in g["sets"].values()) == ["far", "low"]
    bad = tmp_path / "bad.yaml"
    bad.write_text("path: .\ntrain: [far/images/train, nowhere/images/train]\nval: far/images/val\n")
    with pytest.raises(ParameterError, match="nowhere"):
        resolve_splits(bad, "train")
    (tmp_path / "empty" / "images" / "train").mkdir(parents=True)
    with pytest.raises(ParameterError, match="empty"):
        YoloDataset([tmp_path / "far/images/train", tmp_path / "empty/images/train"], 64)


def test_a_malformed_label_file_is_named_with_its_line(tmp_path: Path) -> None:
    from zebra_sim_ros.detection.data import read_labels

    good = tmp_path / "good.txt"
    good.write_text("0 0.5 0.5 0.2 0.1\n\n")
    np.testing.assert_allclose(read_labels(good, 100, 50), [[0, 40, 22.5, 60, 27.5]])
    for text, line in (("0 0.5 0.5 0.2 0.1\n0 0.5 oops 0.1 0.1\n", 2), ("0 0.5 0.5\n", 1)):
        bad = tmp_path / "bad.txt"
        bad.write_text(text)
        with pytest.raises(AssetError, match=rf"bad\.txt line {line} "):
            read_labels(bad, 100, 50)


def test_dont_care_boxes_are_left_out_of_the_classification_loss() -> None:
    """A zebra under the label filters is neither zebra nor background: raising the scores where it lies changes
    nothing, while as plain background the same raise costs loss; the labelled zebra's points still count."""
    from zebra_sim_ros.detection.loss import DetectionLoss, candidates
    from zebra_sim_ros.detection.model import make_anchors

    torch.manual_seed(0)
    model = build_model(ModelConfig(size="n", imgsz=128)).train()
    with torch.no_grad():
        feats = model(torch.rand(1, 3, 128, 128))
    zebra, dont_care = [0.0, 0.0, 20.0, 20.0, 44.0, 36.0], [0.0, -1.0, 80.0, 80.0, 86.0, 86.0]
    anchors, strides = make_anchors(feats, model.strides)
    sizes = [f.shape[2] * f.shape[3] for f in feats]

    def raised(box: list[float]) -> list[torch.Tensor]:
        """The class logits raised by 5 at the points the box has as candidates."""
        near = candidates(anchors * strides, strides[:, 0], torch.tensor([box[2:]])).any(0)
        out = []
        for f, m in zip(feats, near.split(sizes), strict=True):
            g = f.clone()
            g[0, -1].view(-1)[m] += 5.0
            out.append(g)
        return out

    loss = DetectionLoss(model)
    both, background = torch.tensor([zebra, dont_care]), torch.tensor([zebra])
    cls = {name: loss(feats, t)[1][1] for name, t in (("both", both), ("background", background))}
    # "changes nothing" up to float32 rounding (the loss is ~0.6; a raise it counted would cost ~3)
    assert float(loss(raised(dont_care), both)[1][1]) == pytest.approx(float(cls["both"]), rel=1e-5, abs=1e-6)
    assert loss(raised(dont_care), background)[1][1] > cls["background"] + 0.1
    assert abs(float(loss(raised(zebra), both)[1][1]) - float(cls["both"])) > 0.1
    assert cls["both"] < cls["background"]  # fewer background points: the untrained model's scores cost less


def test_training_targets_carry_the_dont_care_boxes(tmp_path: Path) -> None:
    """With dont_care the ignore/ boxes join the training targets as class -1, placed as the labels are; without
    it (or in validation, which keeps them in meta) they are not targets."""
    import cv2

    from zebra_sim_ros.cli import build_parser
    from zebra_sim_ros.detection.data import DONT_CARE, Augment, YoloDataset

    for sub in ("images", "labels", "ignore"):
        (tmp_path / sub).mkdir()
    cv2.imwrite(str(tmp_path / "images" / "a.png"), np.zeros((50, 100, 3), np.uint8))
    (tmp_path / "labels" / "a.txt").write_text("0 0.5 0.5 0.2 0.2\n")
    (tmp_path / "ignore" / "a.txt").write_text("0 0.1 0.1 0.04 0.04\n0 0.9 0.9 0.06 0.04\n")
    still = Augment.none()
    # letterbox to 128: scale 1.28, 32 px of padding above
    targets = YoloDataset(tmp_path / "images", 128, still, dont_care=True)[0][1].numpy()
    np.testing.assert_allclose(targets, [[0, 51.2, 57.6, 76.8, 70.4], [DONT_CARE, 10.24, 37.12, 15.36, 39.68],
                                         [DONT_CARE, 111.36, 88.32, 119.04, 90.88]], atol=1e-4)
    assert len(YoloDataset(tmp_path / "images", 128, still)[0][1]) == 1
    _, labels, meta = YoloDataset(tmp_path / "images", 128, dont_care=True)[0]
    assert len(labels) == 1 and len(meta.ignore) == 2
    base = ["train", "--data", "d.yaml", "--out", "o"]
    assert build_parser().parse_args(base).dont_care
    assert not build_parser().parse_args([*base, "--no-dont-care"]).dont_care


def test_bf16_autocast_trains_where_the_cpu_has_bf16_instructions() -> None:
    """``--amp auto`` picks bf16 only on CPUs with AVX512-BF16 or AMX; there, one training step in bf16 must give
    the float32 loss within bf16's precision and finite gradients. Elsewhere the path is not taken: skipped."""
    from zebra_sim_ros.detection.checkpoint import amp_dtype
    from zebra_sim_ros.detection.loss import DetectionLoss

    if amp_dtype("auto", torch.device("cpu")) is None:
        pytest.skip("no AVX512-BF16 or AMX on this CPU (or oneDNN capped below them): --amp auto trains in "
                    "float32 here, bf16 is not used")
    torch.manual_seed(0)
    model = build_model(ModelConfig(size="n", imgsz=128)).train().to(memory_format=torch.channels_last)
    criterion = DetectionLoss(model)
    x = torch.rand(2, 3, 128, 128).contiguous(memory_format=torch.channels_last)
    targets = torch.tensor([[0, 0, 20.0, 30, 60, 70], [1, 0, 50.0, 40, 110, 90]])
    losses = {}
    for dtype in (None, torch.bfloat16):
        model.zero_grad(set_to_none=True)
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=dtype is not None):
            feats = model(x)
        assert all(f.dtype == (dtype or torch.float32) for f in feats)
        loss, _ = criterion([f.float() for f in feats], targets)
        loss.backward()
        grads = [p.grad for p in model.parameters() if p.grad is not None]
        assert grads and all(torch.isfinite(g).all() for g in grads)
        losses[dtype] = float(loss.detach())
    # bf16 keeps 8 bits of mantissa: the loss of a fresh model agrees to a few percent, not to the last bit
    assert losses[torch.bfloat16] == pytest.approx(losses[None], rel=0.05)


# -- augmentations that break the synthetic shortcuts ------------------------------------------------------------

def _one_zebra_set(tmp_path: Path, box_px: tuple[int, int] = (24, 12)) -> Path:
    """A 640x360 grey frame with one small white 'zebra' box (w, h px) at (400, 200) and its YOLO label."""
    import cv2

    for sub in ("images", "labels"):
        (tmp_path / sub).mkdir(parents=True, exist_ok=True)
    img = np.full((360, 640, 3), 90, np.uint8)
    w, h = box_px
    img[200:200 + h, 400:400 + w] = 255
    cv2.imwrite(str(tmp_path / "images" / "a.png"), img)
    (tmp_path / "labels" / "a.txt").write_text(f"0 {(400 + w / 2) / 640} {(200 + h / 2) / 360} {w / 640} {h / 360}\n")
    return tmp_path / "images"


def test_zoom_makes_a_large_zebra_from_a_small_one(tmp_path: Path) -> None:
    from zebra_sim_ros.detection.data import Augment, YoloDataset

    folder = _one_zebra_set(tmp_path)
    sides = []
    for seed in range(12):
        img, lab, _ = YoloDataset(folder, 320, replace(Augment.none(), zoom=1.0), seed=seed)[0]
        assert len(lab) == 1
        x0, y0, x1, y1 = lab[0, 1:].numpy()
        sides.append(max(x1 - x0, y1 - y0))
        # the box still frames the white object: its inside is white, drawn from the enlarged frame
        inner = img[:, int(y0) + 2:int(y1) - 2, int(x0) + 2:int(x1) - 2]
        assert inner.numel() and float(inner.mean()) > 0.95
    # enlarged up to 4x (24 px -> at most 96 px) and never beyond; the plain pipeline keeps it at 24 * 0.5 px
    assert max(sides) <= 96.5 and min(sides) > 24 and np.median(sides) > 40
    plain = YoloDataset(folder, 320, Augment.none())[0][1]
    assert float(plain[0, 3] - plain[0, 1]) == pytest.approx(12.0, abs=0.1)


def test_zoom_sized_to_the_crop_window_fits_small_and_large_zebras_to_it(tmp_path: Path) -> None:
    """``--aug-zoom-crop``: with ``--crop`` a zoomed zebra spans 15-80% of the window the model sees (a small one
    enlarged up to ``--aug-zoom-max``, a large one shrunk), the window around it; the sample-sized rule enlarges a
    small zebra by the cap and leaves a large one larger than the window."""
    from zebra_sim_ros.detection.data import Augment, YoloDataset

    def sides(folder: Path, **aug: float) -> list[float]:
        out = []
        for seed in range(16):
            img, lab, _ = YoloDataset(folder, 640, replace(Augment.none(), zoom=1.0, **aug), seed=seed, crop=128)[0]
            assert tuple(img.shape) == (3, 128, 128) and len(lab) == 1  # the zoomed zebra is in the window
            x0, y0, x1, y1 = lab[0, 1:].numpy()
            inner = img[:, int(y0) + 2:int(y1) - 2, int(x0) + 2:int(x1) - 2]
            assert inner.numel() == 0 or float(inner.mean()) > 0.9  # and the box frames it
            out.append(float(max(x1 - x0, y1 - y0)))
        return out

    small = _one_zebra_set(tmp_path / "s", (24, 12))
    to_window = sides(small, zoom_crop=1.0, zoom_max=16.0)
    # 15-80% of 128 px (19-102), often cut by the window's edge; spread over the range, not one size
    assert max(to_window) <= 0.8 * 128 + 0.5 and min(to_window) < 40 and np.ptp(to_window) > 30
    capped = sides(small, zoom_crop=1.0, zoom_max=2.0)
    assert max(capped) <= 48.5  # the cap still holds
    by_sample = sides(small)  # the sample's rule: 15-80% of 640 px is beyond the 4x cap, so always 96 px (or cut)
    assert max(by_sample) == pytest.approx(96.0, abs=0.5) and np.median(by_sample) > 75
    large = _one_zebra_set(tmp_path / "l", (200, 100))
    shrunk = sides(large, zoom_crop=1.0, zoom_max=16.0)
    assert max(shrunk) <= 102.9 and np.median(shrunk) < 80  # whole large zebras in the window
    assert np.median(sides(large)) > 120  # before: most of them cut by the window, larger than it
    with pytest.raises(ParameterError, match="'--aug-zoom-max'"):
        replace(Augment(), zoom_max=0.5).check()
    with pytest.raises(ParameterError, match="'--aug-zoom-max'"):
        replace(Augment(), zoom_max=17.0).check()
    Augment.none().check()


def test_crops_keep_the_zebras_scale_and_frame_it(tmp_path: Path) -> None:
    from zebra_sim_ros.detection.data import Augment, YoloDataset

    folder = _one_zebra_set(tmp_path, (40, 20))
    whole = YoloDataset(folder, 640, Augment.none())[0][1]
    assert float(whole[0, 3] - whole[0, 1]) == pytest.approx(40.0, abs=0.1)
    offsets = set()
    for seed in range(10):
        img, lab, _ = YoloDataset(folder, 640, Augment.none(), seed=seed, crop=128)[0]
        assert tuple(img.shape) == (3, 128, 128) and len(lab) == 1
        x0, y0, x1, y1 = lab[0, 1:].numpy()
        # the same size as in the whole 640 sample (no rescaling) unless the window's edge cuts it
        for lo, hi, side in ((x0, x1, 40.0), (y0, y1, 20.0)):
            if 0.5 < lo and hi < 127.5:
                assert hi - lo == pytest.approx(side, abs=0.1)
            else:
                assert side * 0.3 < hi - lo < side and min(lo, 128 - hi) < 0.5
        inner = img[:, int(y0) + 1:int(y1) - 1, int(x0) + 1:int(x1) - 1]
        assert float(inner.mean()) > 0.95  # the box frames the white object
        assert float(img[:, :, :].mean()) < 0.6  # and the window is mostly the grey ground around it
        offsets.add((round(float(x0)), round(float(y0))))
    assert len(offsets) >= 5  # the zebra lands in different places of the window


def test_a_crop_draws_only_its_window_with_the_same_pixels() -> None:
    """``train --crop`` warps only the window of the augmented sample; it must be the window of the whole
    sample (up to OpenCV's fixed-point rounding: a few grey levels on a few pixels), flipped samples included."""
    import cv2

    from zebra_sim_ros.detection.data import _Sample

    rng = np.random.default_rng(5)
    src = (rng.uniform(0, 255, (90, 160, 3))).astype(np.uint8)
    src = cv2.resize(src, (1280, 720), interpolation=cv2.INTER_CUBIC)  # smooth, like a photograph
    m = np.array([[1.63, 0.0, -210.7], [0.0, 1.63, 301.2]])
    sample = _Sample(src, m, 2176)
    full = sample.full()
    for x0, y0 in ((0, 0), (1003, 517), (2176 - 320, 2176 - 320), (40, 1856)):
        win = sample.window(x0, y0, 320).astype(int)
        ref = full[y0:y0 + 320, x0:x0 + 320].astype(int)
        assert np.abs(win - ref).max() <= 3 and (win != ref).mean() < 0.01
        mirror = cv2.flip(sample.window(2176 - x0 - 320, y0, 320), 1).astype(int)
        assert np.abs(mirror - cv2.flip(full, 1)[y0:y0 + 320, x0:x0 + 320].astype(int)).max() <= 3
    beyond = sample.window(0, 2000, 320)  # past the sample's edge: grey padding, as a whole sample's crop pads
    assert (beyond[176:] == 114).all() and np.abs(beyond[:176].astype(int) - full[2000:, :320]).max() <= 3
    plain = _Sample(full, None, 2176)  # no affine: a slice
    assert np.array_equal(plain.window(100, 200, 320), full[200:520, 100:420])


def test_background_zooms_centre_on_other_species_or_ground(tmp_path: Path) -> None:
    import cv2

    from zebra_sim_ros.detection.data import Augment, YoloDataset, other_species_boxes

    folder = _one_zebra_set(tmp_path)  # a white 24x12 'zebra' at (400, 200)
    img = cv2.imread(str(folder / "a.png"))
    img[60:100, 100:160] = (0, 0, 255)  # a red 60x40 'buffalo' far from it, in the frame's record only
    cv2.imwrite(str(folder / "a.png"), img)
    (tmp_path / "annotations").mkdir()
    record = {"labels": {"zebras": [
        {"species": "zebra", "box_visible": [400, 200, 424, 212], "visible_pixels": 288},
        {"species": "buffalo", "box_visible": [100, 60, 160, 100], "visible_pixels": 2400},
        {"species": "impala", "box_visible": [10, 10, 13, 13], "visible_pixels": 9}]}}  # too few pixels to count
    (tmp_path / "annotations" / "a.json").write_text(json.dumps(record))
    assert other_species_boxes(folder / "a.png").tolist() == [[100, 60, 160, 100]]
    assert other_species_boxes(tmp_path / "nowhere" / "b.png").shape == (0, 4)  # no record: none, no error
    kept = YoloDataset(folder, 320, Augment.none(), other_class=1)
    assert kept.read_other_boxes() == 1  # read once, up front (train does this before its loader starts)
    (tmp_path / "annotations" / "a.json").rename(tmp_path / "a.json.moved")
    assert kept.load(0)[1][:, 0].tolist() == [0.0, 1.0]  # the kept boxes, not a second read of the record
    assert YoloDataset(folder, 320, Augment.none(), other_class=1).load(0)[1][:, 0].tolist() == [0.0]
    (tmp_path / "a.json.moved").rename(tmp_path / "annotations" / "a.json")

    def red_share(x: torch.Tensor) -> float:
        r, g, b = x.numpy()
        return float(((r > 0.9) & (g < 0.1) & (b < 0.1)).mean())

    on_buffalo = on_zebra = 0
    for seed in range(24):
        x, lab, _ = YoloDataset(folder, 320, replace(Augment.none(), zoom=1.0, background=1.0), seed=seed)[0]
        on_buffalo += red_share(x) > 0.04  # the 60x40 buffalo enlarged to 15-80% of the side fills over 4%
        for row in lab.numpy():  # a zebra in view keeps its label, on the white object
            x0, y0, x1, y1 = row[1:]
            inner = x[:, int(y0) + 2:int(y1) - 2, int(x0) + 2:int(x1) - 2]
            assert inner.numel() == 0 or float(inner.mean()) > 0.9
            on_zebra += 1
    assert 6 <= on_buffalo <= 20  # half the negatives centre on the other animal, the rest on random points
    assert on_zebra < 12  # and the zebra is rarely in view: it is no longer the centre
    for seed in range(12):  # zebra-centred zooms (the default) keep the zebra, never the buffalo, in view
        x, lab, _ = YoloDataset(folder, 320, replace(Augment.none(), zoom=1.0), seed=seed)[0]
        assert len(lab) == 1 and red_share(x) < 1e-9  # no red pixel at all
    # with crops: the window goes around the negative's centre too, not back to the zebra
    crops = [YoloDataset(folder, 640, replace(Augment.none(), zoom=1.0, background=1.0), seed=s, crop=128)[0]
             for s in range(24)]
    assert sum(red_share(x) > 0.04 for x, _, _ in crops) >= 6 and sum(len(lab) for _, lab, _ in crops) < 12


def test_photometric_augmentations_do_what_they_say(tmp_path: Path) -> None:
    from zebra_sim_ros.detection.data import Augment, YoloDataset

    folder = _one_zebra_set(tmp_path, (120, 60))
    base = Augment.none()

    def sample(**kw: float) -> np.ndarray:
        return YoloDataset(folder, 320, replace(base, **kw), seed=3)[0][0].numpy()

    plain = sample()
    assert np.array_equal(sample(gamma=0.0, white_balance=0.0, blur=0.0), plain)  # all off: nothing changes
    grey = sample(grayscale=1.0)
    assert np.abs(grey[0] - grey[1]).max() < 1e-6 and np.abs(grey[1] - grey[2]).max() < 1e-6
    noisy = sample(noise=1.0)
    assert 1.5 / 255 < float((noisy - plain).std()) < 12 / 255
    blurred = sample(blur=1.0)
    edge = lambda x: float(np.abs(np.diff(x[0], axis=1)).max())  # noqa: E731
    assert edge(blurred) < 0.9 * edge(plain)  # the white box's hard edge is softened
    jpeg = sample(jpeg=1.0)
    assert 0 < float(np.abs(jpeg - plain).mean()) < 0.05
    tinted = sample(white_balance=0.3)
    assert np.abs(tinted - plain).max() > 0.01
    labels = YoloDataset(folder, 320, replace(base, grayscale=1.0, noise=1.0, jpeg=1.0, blur=1.0), seed=3)[0][1]
    assert np.allclose(labels.numpy(), YoloDataset(folder, 320, base, seed=3)[0][1].numpy())  # boxes untouched


def test_cutout_drops_boxes_it_hides(tmp_path: Path) -> None:
    from zebra_sim_ros.detection.data import _cutout

    img = np.zeros((100, 100, 3), np.uint8)
    lab = np.array([[0, 10, 10, 14, 14], [0, 60, 60, 95, 95]], np.float32)
    kept_counts = set()
    for seed in range(60):
        out, kept = _cutout(img, lab, np.random.default_rng(seed), 1.0)
        assert (out > 0).any()
        for row in lab:
            x0, y0, x1, y1 = row[1:].astype(int)
            covered = float((out[y0:y1, x0:x1].max(axis=2) > 0).mean())
            if covered > 0.99:  # wholly under one grey rectangle: it must be gone
                assert not any(np.array_equal(row, k) for k in kept)
        kept_counts.add(len(kept))
    assert 2 in kept_counts and min(kept_counts) < 2
    assert _cutout(img, lab, np.random.default_rng(0), 0.0)[0] is img


def test_augment_options_are_checked_recorded_and_held_on_resume(tmp_path: Path) -> None:
    from zebra_sim_ros.cli import build_parser
    from zebra_sim_ros.cli.detect import augment_from_args
    from zebra_sim_ros.detection.data import Augment
    from zebra_sim_ros.detection.train import TrainConfig, check_resume

    args = build_parser().parse_args(["train", "--data", "d.yaml", "--out", "o", "--aug-zoom", "0.6",
                                      "--aug-jpeg", "0"])
    aug = augment_from_args(args)
    assert aug.zoom == 0.6 and aug.jpeg == 0.0 and aug.mosaic == Augment().mosaic
    with pytest.raises(ParameterError, match="'--aug-zoom'"):
        TrainConfig(data="d.yaml", out="o", aug=replace(aug, zoom=1.5)).check()
    cfg = TrainConfig(data="d.yaml", out="o", aug=aug)
    from dataclasses import asdict

    check_resume(cfg, asdict(cfg), tmp_path / "last.pt")  # the same settings resume
    with pytest.raises(ParameterError, match="'--aug-zoom'"):
        check_resume(replace(cfg, aug=replace(aug, zoom=0.2)), asdict(cfg), tmp_path / "last.pt")
    assert Augment.from_dict(asdict(aug)) == aug and Augment.from_dict(None) == Augment()


# -- a second class: other animals ------------------------------------------------------------------------------

def test_other_animals_join_the_labels_and_zooms_stay_on_zebras(tmp_path: Path) -> None:
    """``train --other-animals``: a generated frame's animal of another species (from its annotation) is a label of
    class 1, moved with the image; zooms and crops still centre on zebras, never on it."""
    import cv2

    from zebra_sim_ros.detection.data import Augment, YoloDataset

    folder = _one_zebra_set(tmp_path)  # a white 24x12 'zebra' at (400, 200)
    img = cv2.imread(str(folder / "a.png"))
    img[60:100, 100:160] = (0, 0, 255)  # a red 60x40 'buffalo'
    cv2.imwrite(str(folder / "a.png"), img)
    (tmp_path / "annotations").mkdir()
    (tmp_path / "annotations" / "a.json").write_text(json.dumps({"labels": {"zebras": [
        {"species": "zebra", "box_visible": [400, 200, 424, 212], "visible_pixels": 288},
        {"species": "buffalo", "box_visible": [100, 60, 160, 100], "visible_pixels": 2400}]}}))
    plain = YoloDataset(folder, 640, Augment.none(), other_class=1)[0][1].numpy()
    # letterboxed 640x360 -> 640x640: y moves down by 140 px
    np.testing.assert_allclose(plain[np.argsort(plain[:, 0])], [[0, 400, 340, 424, 352], [1, 100, 200, 160, 240]],
                               atol=0.01)
    assert len(YoloDataset(folder, 640, Augment.none())[0][1]) == 1  # without it: the zebra alone
    val = YoloDataset(folder, 640, other_class=1)[0][2]  # validation
    assert val.labels[:, 0].tolist() == [0, 1]
    for seed in range(12):  # a zoom centres on the zebra, never on the other animal
        x, lab, _ = YoloDataset(folder, 320, replace(Augment.none(), zoom=1.0), seed=seed, other_class=1)[0]
        zebra = lab[lab[:, 0] == 0]
        assert len(zebra) == 1
        x0, y0, x1, y1 = zebra[0, 1:].numpy()
        assert float(x[:, int(y0) + 2:int(y1) - 2, int(x0) + 2:int(x1) - 2].mean()) > 0.9
    for seed in range(12):  # and so does a crop
        _, lab, _ = YoloDataset(folder, 640, Augment.none(), seed=seed, crop=128, other_class=1)[0]
        assert (lab[:, 0] == 0).sum() == 1


def test_postprocess_lets_an_other_animal_box_suppress_a_zebra_box() -> None:
    pred = torch.zeros(1, 3, 6)  # [x0, y0, x1, y1, p(zebra), p(other_animal)]
    pred[0, 0] = torch.tensor([10.0, 10, 50, 50, 0.5, 0.1])  # 'zebra' on a buffalo, weaker
    pred[0, 1] = torch.tensor([11.0, 10, 51, 50, 0.2, 0.8])  # 'other animal' on the same buffalo
    pred[0, 2] = torch.tensor([100.0, 10, 140, 50, 0.7, 0.1])  # a zebra elsewhere
    agnostic = postprocess(pred, conf=0.25, iou=0.5)[0]
    assert sorted(agnostic[:, 5].tolist()) == [0, 1] and agnostic[agnostic[:, 5] == 0][0, 0] == pytest.approx(100)
    per_class = postprocess(pred, conf=0.25, iou=0.5, agnostic=False)[0]
    assert sorted(per_class[:, 5].tolist()) == [0, 0, 1]  # each class on its own: the zebra box stays


def test_validation_scores_zebras_only() -> None:
    """A model's other_animal detections are neither true nor false zebras in ``val``."""
    from torch import nn

    from zebra_sim_ros.detection.data import ImageMeta
    from zebra_sim_ros.detection.evaluate import predictions, predictions_by_class, score

    class Fixed(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.w = nn.Parameter(torch.zeros(1))

        def forward(self, x: torch.Tensor) -> torch.Tensor:
            out = torch.zeros(len(x), 2, 6)
            out[:, 0] = torch.tensor([10.0, 10, 50, 50, 0.9, 0.0])  # the labelled zebra
            out[:, 1] = torch.tensor([100.0, 10, 140, 50, 0.0, 0.95])  # another animal
            return out + 0.0 * self.w  # an output that needs no_grad to become numpy, as a real model's

    meta = ImageMeta("a.png", (64, 160), 1.0, (0, 0), 160, (64, 160), np.array([[0, 10, 10, 50, 50]], np.float32),
                     np.zeros((0, 5), np.float32))
    loader = [(torch.zeros(1, 3, 64, 160), torch.zeros(0, 6), [meta])]
    per = predictions(Fixed(), loader)  # type: ignore[arg-type]
    assert len(per[0].detections) == 1
    m = score(per)
    assert (m.map50, m.precision) == (pytest.approx(1.0), pytest.approx(1.0))
    both = predictions_by_class(Fixed(), loader, (0, 1))  # type: ignore[arg-type]  # one pass, split by class
    np.testing.assert_allclose(both[0][0].detections, per[0].detections, atol=1e-4)
    np.testing.assert_allclose(both[1][0].detections[:, :4], [[100.0, 10.0, 140.0, 50.0]], atol=1e-4)
    assert both[1][0].labels.tolist() == per[0].labels.tolist()  # labels travel with every class's list


def test_init_grows_a_zebra_checkpoint_into_two_classes() -> None:
    from zebra_sim_ros.detection.train import load_init_weights

    one = build_model(ModelConfig(size="n"))
    two = build_model(ModelConfig(size="n", nc=2, names=("zebra", "other_animal")))
    fresh = {k: v.clone() for k, v in two.state_dict().items()}
    with torch.no_grad():
        for p in one.parameters():
            p.add_(0.01)  # so that copied and fresh values differ
    grown = load_init_weights(two, one.state_dict())
    assert sorted(grown) == sorted(f"cls_head.{i}.2.{k}" for i in range(3) for k in ("weight", "bias"))
    state = two.state_dict()
    for k, v in one.state_dict().items():
        if k in grown:
            torch.testing.assert_close(state[k][:1], v)
            torch.testing.assert_close(state[k][1:], fresh[k][1:])  # other_animal: the fresh prior
        else:
            torch.testing.assert_close(state[k], v)
    with pytest.raises(ParameterError, match="'names'.*'zebra' as class 0"):
        ModelConfig(nc=2, names=("other_animal", "zebra"))


def test_p2_adds_a_stride_4_level_and_starts_from_a_three_level_checkpoint() -> None:
    """``p2``: four output levels, the finest at stride 4; a three-level checkpoint loads into it with every other
    output unchanged and the new level left as freshly initialised."""
    from zebra_sim_ros.detection.train import load_init_weights

    base = build_model(ModelConfig(size="n"))
    with torch.no_grad():
        for p in base.parameters():
            p.add_(0.01 * torch.randn_like(p))  # trained-looking weights, unlike a fresh model's
    p2 = build_model(ModelConfig(size="n", p2=True))
    fresh = {k: v.clone() for k, v in p2.state_dict().items()}
    assert p2.strides == (4, 8, 16, 32) and base.strides == (8, 16, 32)
    assert 0 < count_parameters(p2) - count_parameters(base) < 0.05 * count_parameters(base)
    assert load_init_weights(p2, base.state_dict()) == []
    state = p2.state_dict()
    new = p2_tensors(state)
    assert new and len(state) == len(base.state_dict()) + len(new) and not p2_tensors(base.state_dict())
    for k in new:
        torch.testing.assert_close(state[k], fresh[k])
    base.eval(), p2.eval()
    x = torch.rand(2, 3, 256, 320)
    with torch.no_grad():
        fb, fp = base.features(x), p2.features(x)
        out = p2(x)
    assert [tuple(f.shape[2:]) for f in fp] == [(64, 80), (32, 40), (16, 20), (8, 10)]
    for a, b in zip(fb, fp[1:], strict=True):
        torch.testing.assert_close(a, b)
    assert out.shape == (2, 64 * 80 + 32 * 40 + 16 * 20 + 8 * 10, 5)
    first = out[0, : 64 * 80, :4]  # the stride-4 boxes lie around their cells' centres, 4 px apart
    centres = (first[:, :2] + first[:, 2:]) / 2
    assert centres[1, 0] - centres[0, 0] == pytest.approx(4.0, abs=2.0)
    assert ModelConfig.from_dict({**ModelConfig().to_dict()} | {"p2": True}).p2
    old = ModelConfig().to_dict()
    del old["p2"]  # checkpoints written before the option
    assert ModelConfig.from_dict(old).p2 is False
    with pytest.raises(ParameterError, match="'p2'"):
        ModelConfig(p2="yes")  # type: ignore[arg-type]


def test_image_size_reads_png_and_jpeg_headers(tmp_path: Path) -> None:
    import cv2

    from zebra_sim_ros.detection.data import image_size

    img = np.random.default_rng(0).integers(0, 255, (37, 61, 3), dtype=np.uint8)
    for name in ("a.png", "a.jpg", "p.jpg"):
        params = [cv2.IMWRITE_JPEG_PROGRESSIVE, 1] if name == "p.jpg" else []
        cv2.imwrite(str(tmp_path / name), img, params)
        assert image_size(tmp_path / name) == (61, 37), name
    jpg = (tmp_path / "a.jpg").read_bytes()
    exif = b"\xff\xe1" + (8).to_bytes(2, "big") + b"Exif\x00\x00"  # an Exif segment: the decoder may rotate
    (tmp_path / "exif.jpg").write_bytes(jpg[:2] + exif + jpg[2:])
    (tmp_path / "cut.jpg").write_bytes(jpg[:40])  # truncated before its frame header
    (tmp_path / "x.bmp").write_bytes(b"BM" + bytes(60))
    for name in ("exif.jpg", "cut.jpg", "x.bmp", "missing.png"):
        assert image_size(tmp_path / name) is None, name


def _count_decodes(ds: Any) -> list[int]:
    """Make ``ds`` note the index of every image it decodes in the returned list."""
    decoded: list[int] = []
    image = ds.image

    def counted(i: int) -> Any:
        decoded.append(i)
        return image(i)

    ds.image = counted
    return decoded


def test_a_mosaic_crop_draws_its_window_from_the_frames_it_shows(tmp_path: Path) -> None:
    """A mosaic's window, drawn tile by tile from the four frames, is the window of the whole mosaic canvas up to
    interpolation (one bilinear warp instead of a resize and a warp) and the pixel row at a tile's edge; the
    labels are the canvas's; and a frame the window does not show is never decoded."""
    import cv2

    from zebra_sim_ros.detection.data import Augment, YoloDataset

    rng = np.random.default_rng(3)
    (tmp_path / "images").mkdir()
    (tmp_path / "labels").mkdir()
    for k, (w, h, ext) in enumerate(((1280, 720, "jpg"), (640, 360, "png"), (1280, 720, "png"), (480, 640, "jpg"))):
        small = rng.uniform(0, 255, (h // 16, w // 16, 3)).astype(np.uint8)
        cv2.imwrite(str(tmp_path / "images" / f"f{k}.{ext}"), cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC),
                    [cv2.IMWRITE_JPEG_QUALITY, 98] if ext == "jpg" else [])
        (tmp_path / "labels" / f"f{k}.txt").write_text("".join(f"0 {0.1 + 0.2 * j} 0.5 0.04 0.05\n" for j in range(5)))
    for imgsz in (1088, 512):  # frames enlarged, and shrunk (by area, then warped)
        ds = YoloDataset(tmp_path / "images", imgsz, Augment(), seed=0, crop=256)
        decoded = _count_decodes(ds)
        diffs = []
        for seed in range(16):
            sample, lab = ds._mosaic(seed % 4, np.random.default_rng(seed))
            full = sample.full()
            assert sorted(decoded) == sorted({t.index for t in sample.tiles})  # the canvas: each frame, once
            canvas_lab = lab
            for x0, y0 in rng.integers(0, imgsz - 64, (3, 2)):
                x0, y0 = int(x0), int(y0)
                for t in sample.tiles:
                    t.img = None  # drawn afresh: count what this window decodes
                decoded.clear()
                win = sample.window(x0, y0, 256).astype(int)
                ref = np.full((256, 256, 3), 114)
                part = full[y0:y0 + 256, x0:x0 + 256]
                ref[:part.shape[0], :part.shape[1]] = part
                d = np.abs(win - ref)
                diffs.append(d.mean())
                assert (d > 24).mean() < 0.02, (imgsz, seed, x0, y0)  # only along a tile's edge
                assert len(decoded) == len(set(decoded)) and set(decoded) <= {t.index for t in sample.tiles}
            for t in sample.tiles:
                t.img = None
            decoded.clear()
            beyond = sample.window(imgsz, imgsz, 256)  # wholly past the sample: grey, and nothing decoded
            assert (beyond == 114).all() and decoded == []
            assert lab is canvas_lab
        assert np.median(diffs) < 1.5, (imgsz, np.median(diffs))
    # the window of a 512 px mosaic, 256 px across, shows one to four of the frames: some decode fewer than four
    ds = YoloDataset(tmp_path / "images", 2176, Augment(), seed=0, crop=256)
    decoded = _count_decodes(ds)
    counts = []
    for seed in range(20):
        sample, _ = ds._mosaic(0, np.random.default_rng(seed))
        decoded.clear()
        sample.window(900, 900, 256)
        counts.append(len(decoded))
    assert min(counts) >= 1 and np.mean(counts) < 3


def test_widening_n_to_s_keeps_the_function_and_parts_the_copies() -> None:
    """``widen_state``: the shipped nano's weights in an ``s`` model compute the same boxes and scores, in
    evaluation and in training mode; the copies of a channel get unequal shares of their old weights, so one
    backward pass gives them different gradients; the same seed gives the same shares, another seed others;
    sizes it does not widen between are refused by name."""
    from zebra_sim_ros.detection.checkpoint import SHIPPED

    ck = read_checkpoint(SHIPPED)
    narrow = build_model(ck["config"])
    narrow.load_state_dict({k: v.float() for k, v in ck["model"].items()})
    state = widen_state(ck["model"], ck["config"], "s", seed=3)
    wide = build_model({**ck["config"], "size": "s"})
    wide.load_state_dict(state)
    assert count_parameters(wide) > 3.5 * count_parameters(narrow)
    x = torch.rand(2, 3, 256, 320, generator=torch.Generator().manual_seed(0))
    with torch.no_grad():
        a, b = narrow.eval()(x), wide.eval()(x)
    assert a[..., 4].max() > 0.05  # the shipped weights see something in noise: the scores compared are not all 0
    torch.testing.assert_close(b[..., :4], a[..., :4], atol=0.01, rtol=0)  # px on a 320 px input
    torch.testing.assert_close(b[..., 4:], a[..., 4:], atol=1e-4, rtol=0)
    with torch.no_grad():  # batch statistics: the copies see the same batch, so they normalise alike
        for fa, fb in zip(narrow.train()(x), wide.train()(x), strict=True):
            torch.testing.assert_close(fb, fa, atol=1e-3, rtol=1e-3)
    w = state["stem.1.conv.weight"]  # 32 -> 64 outputs, 16 -> 32 inputs: copies share each old weight
    old = ck["model"]["stem.1.conv.weight"].float()
    torch.testing.assert_close(w[::2, ::2] + w[::2, 1::2], old, atol=1e-5, rtol=1e-4)
    share = w[::2, ::2] / old.where(old.abs() > 1e-3, torch.ones_like(old))
    assert share[old.abs() > 1e-3].min() >= 0.25 - 1e-4 and share[old.abs() > 1e-3].max() <= 0.75 + 1e-4
    assert share[old.abs() > 1e-3].std() > 0.1  # drawn, not halves
    wide.train()
    sum(f.float().pow(2).mean() for f in wide(x)).backward()
    g = wide.stem[0].conv.weight.grad  # the first layer's output copies: identical weights, unequal downstream
    assert g is not None and (g[::2] - g[1::2]).abs().max() > 0.01 * g.abs().max()
    again, other = widen_state(ck["model"], ck["config"], "s", seed=3), widen_state(ck["model"], ck["config"], "s", 4)
    assert all(torch.equal(again[k], v) for k, v in state.items())
    assert not torch.equal(other["stem.1.conv.weight"], w)
    with pytest.raises(ParameterError, match="'--model' = 'm'.*'s', the size a 'n' checkpoint widens to"):
        widen_state(ck["model"], ck["config"], "m", seed=3)
    with pytest.raises(ParameterError, match="'--model' = 'n'.*a 's' checkpoint does not widen"):
        widen_state(state, {**ck["config"], "size": "s"}, "n", seed=3)
    with pytest.raises(ParameterError, match="'--blend-base'.*tensor"):
        widen_state({k: v for k, v in ck["model"].items() if k != "stem.0.conv.weight"}, ck["config"], "s", 3,
                    "--blend-base")


def test_a_widening_record_reads_back_and_a_malformed_one_is_refused_by_the_option_that_gave_it() -> None:
    """Checkpoints keep :class:`Widening` as a plain dict; it reads back equal, no record reads as None, a record
    from before the digest was kept reads with none, and one with a field missing or of the wrong kind is refused
    with the option, the checkpoint's path and what it holds."""
    record = Widening("runs/n/best.pt", "n", 5, "0123456789ab")
    assert record.to_dict() == {"from": "runs/n/best.pt", "size": "n", "seed": 5, "digest": "0123456789ab"}
    assert Widening.from_dict(record.to_dict(), "--init", "x.pt") == record
    assert Widening.from_dict(None, "--init", "x.pt") is None
    old = {k: v for k, v in record.to_dict().items() if k != "digest"}
    assert Widening.from_dict(old, "--init", "x.pt") == Widening("runs/n/best.pt", "n", 5, None)
    good = record.to_dict()
    for bad, shown in (({**good, "seed": "5"}, "'seed': '5'"), ({**good, "seed": True}, "'seed': True"),
                       ({k: v for k, v in good.items() if k != "size"}, "'seed': 5"), (["n", 5], "['n', 5]"),
                       ({**good, "from": None}, "'from': None"), ({**good, "digest": 7}, "'digest': 7"),
                       ({**good, "width": 2}, "'width': 2")):
        with pytest.raises(ParameterError, match="'--resume'") as err:
            Widening.from_dict(bad, "--resume", "runs/s/last.pt")
        assert "runs/s/last.pt" in str(err.value) and shown in str(err.value), bad


@pytest.mark.parametrize("cfg", [ModelConfig(size="n", p2=True), ModelConfig(size="n", nc=2, names=("zebra", "x"))],
                         ids=["p2", "two-classes"])
def test_widening_keeps_the_function_with_a_stride_4_level_and_two_classes(cfg: ModelConfig) -> None:
    """The stride-4 level (its C2f joins the upsampled stride-8 features with the stem's) and a second class
    widen like the rest: random weights and batch-norm statistics, the same raw outputs at every level."""
    torch.manual_seed(4)
    narrow = randomise_batch_norms(build_model(cfg))
    wide = build_model(replace(cfg, size="s"))
    wide.load_state_dict(widen_state(narrow.state_dict(), cfg, "s", seed=1))
    x = torch.rand(1, 3, 128, 160, generator=torch.Generator().manual_seed(0))
    with torch.no_grad():
        fa, fb = narrow.eval().features(x), wide.eval().features(x)
    assert len(fa) == len(narrow.strides) == len(fb)
    for a, b in zip(fa, fb, strict=True):
        assert a.shape == b.shape and a.abs().max() > 0.1  # outputs that are not all near 0
        torch.testing.assert_close(b, a, atol=1e-4, rtol=1e-4)
