"""The crop verifier: crops, rescoring, checkpoints, training on generated frames, and its place in detect/val."""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch
from cli_helpers import CliRun

from zebra_sim_ros.dataset.generate import GenerateConfig, generate
from zebra_sim_ros.detection.config import TrainVerifierConfig, VerifierConfig
from zebra_sim_ros.detection.verify import (
    SHIPPED_VERIFIER,
    Verifier,
    ensemble_verifiers,
    judged_side,
    load_verifier,
    rescore,
    reserve_verifier,
    save_verifier,
    square_crop,
    verify,
    zebra_probability,
)
from zebra_sim_ros.detection.verify_train import (
    KINDS,
    collect_crops,
    draw_clutter,
    held_out,
    train_verifier,
)
from zebra_sim_ros.errors import AssetError, ParameterError


def constant(p: float, cfg: VerifierConfig | None = None) -> Verifier:
    """A verifier that says p(zebra) = p of every crop (zero weights into the head, its bias the logit of p)."""
    net = Verifier(cfg or VerifierConfig(widths=(8, 16)))
    with torch.no_grad():
        net.head.weight.zero_()
        net.head.bias.fill_(math.log(p / (1 - p)))
    return net.eval()


def test_a_square_crop_past_the_edge_is_the_nearest_edge_pixels_exactly() -> None:
    """Crops across an edge, a corner, or wholly outside the image (a shifted training crop) equal a reference built
    pixel by pixel: each pixel of the square taken from the nearest pixel of the image, then resized as inside."""
    import cv2

    rng = np.random.default_rng(5)
    img = rng.integers(0, 256, (120, 200, 3), dtype=np.uint8)
    cases = [((-30, 10, 20, 60), 1.5, (0.0, 0.0)), ((170, 90, 230, 130), 2.0, (0.0, 0.0)),
             ((5, 5, 25, 25), 3.0, (0.0, 0.0)), ((150, 40, 190, 80), 1.0, (3.0, -2.5)),
             ((0, 0, 200, 120), 1.2, (0.0, 0.0))]
    for _ in range(40):
        x0, y0 = rng.uniform(-60, 200), rng.uniform(-60, 120)
        cases.append(((x0, y0, x0 + rng.uniform(2, 90), y0 + rng.uniform(2, 90)), float(rng.uniform(1, 3)),
                      (float(rng.uniform(-1, 1)), float(rng.uniform(-1, 1)))))
    outside = 0
    for box, context, shift in cases:
        x0, y0, x1, y1 = box
        side = max(2, int(round(max(x1 - x0, y1 - y0) * context)))
        cx, cy = (x0 + x1) / 2 + shift[0] * (x1 - x0), (y0 + y1) / 2 + shift[1] * (y1 - y0)
        left, top = int(round(cx - side / 2)), int(round(cy - side / 2))
        outside += left >= 200 or top >= 120 or left + side <= 0 or top + side <= 0
        rows = np.clip(np.arange(top, top + side), 0, 119)
        cols = np.clip(np.arange(left, left + side), 0, 199)
        want = cv2.resize(img[rows[:, None], cols[None, :]], (24, 24),
                          interpolation=cv2.INTER_AREA if side > 24 else cv2.INTER_LINEAR)
        np.testing.assert_array_equal(square_crop(img, box, context, 24, shift), want, err_msg=str(box))
    assert outside >= 1  # the wholly-outside case is among them


def test_a_square_crop_is_the_box_and_its_context_and_repeats_the_edge() -> None:
    img = np.zeros((200, 300, 3), np.uint8)
    img[50:90, 100:180] = 255  # an 80 x 40 white box
    whole = square_crop(img, (100, 50, 180, 90), 1.0, 32)  # an 80 px square: the box, plus 20 px above and below
    assert whole.shape == (32, 32, 3) and whole.dtype == np.uint8
    assert whole[12:20].min() == 255 and whole[:6].max() == 0 and whole[-6:].max() == 0
    wide = square_crop(img, (100, 50, 180, 90), 2.0, 32)  # 160 px: the box is the middle half across
    assert wide[14:18, 10:22].min() == 255 and wide[14:18, :6].max() == 0
    edge = square_crop(img, (280, 180, 300, 200), 1.5, 16)  # past the corner: the edge pixels, repeated
    assert edge.shape == (16, 16, 3) and edge.max() == 0
    moved = square_crop(img, (100, 50, 180, 90), 1.0, 32, shift=(0.5, 0.0))  # centre moved 40 px right
    assert moved[12:20, :12].min() == 255 and moved[12:20, -6:].max() == 0


def test_rescore_multiplies_the_large_zebra_boxes_drops_those_now_under_conf_and_reorders() -> None:
    net = constant(0.25)
    img = np.full((400, 600, 3), 90, np.uint8)
    dets = np.array([[10, 10, 110, 60, 0.90, 0],  # large zebra: 0.225
                     [200, 200, 210, 215, 0.50, 0],  # 15 px: under min_side, keeps 0.50
                     [300, 100, 400, 200, 0.80, 1],  # another class: untouched
                     [400, 300, 480, 380, 0.30, 0]], np.float32)  # large zebra: 0.075, under conf 0.1
    out = rescore(net, img, dets, conf=0.1, cls=0)
    assert out.shape == (3, 6)
    np.testing.assert_allclose(out[:, 4], [0.80, 0.50, 0.225], rtol=1e-5)
    assert list(out[:, 5]) == [1, 0, 0]
    np.testing.assert_array_equal(out[:, :4], dets[[2, 1, 0], :4])
    assert rescore(net, img, dets[:0], 0.1).shape == (0, 6)
    five = verify(net, img, dets[:, :5])  # five columns, every row looked at: the order and length kept
    np.testing.assert_allclose(five[:, 4], [0.225, 0.50, 0.20, 0.075], rtol=1e-5)


def test_a_size_share_judges_boxes_from_a_side_that_grows_with_the_image() -> None:
    """min_side_fraction 0.0375: 24 px on a 640 px photo, 48 px on a 1280x720 frame, never under min_side; a box
    between the two is judged on the photo and keeps its score on the frame."""
    cfg = VerifierConfig(widths=(8, 16), min_side_fraction=0.0375)
    assert judged_side(cfg, (480, 640, 3)) == pytest.approx(24.0)
    assert judged_side(cfg, (720, 1280, 3)) == pytest.approx(48.0)
    assert judged_side(cfg, (200, 320, 3)) == pytest.approx(24.0)  # the share is 12 px: min_side holds
    assert judged_side(VerifierConfig(), (720, 1280, 3)) == pytest.approx(24.0)  # off: min_side alone
    net = constant(0.5, cfg)
    dets = np.array([[10, 10, 46, 40, 0.8, 0],  # 36 px
                     [100, 100, 160, 150, 0.8, 0]], np.float32)  # 60 px
    photo = verify(net, np.full((480, 640, 3), 90, np.uint8), dets)
    frame = verify(net, np.full((720, 1280, 3), 90, np.uint8), dets)
    np.testing.assert_allclose(photo[:, 4], [0.4, 0.4], rtol=1e-5)
    np.testing.assert_allclose(frame[:, 4], [0.8, 0.4], rtol=1e-5)
    with pytest.raises(ParameterError, match="min_side_fraction.*0.6"):
        VerifierConfig(min_side_fraction=0.6).check()
    old = {"crop": 96, "context": 1.2, "min_side": 24.0, "widths": [8, 16]}  # a checkpoint from before the share
    assert VerifierConfig.from_dict(old).min_side_fraction == pytest.approx(0.0)


def test_a_power_weighs_the_verifier_more_on_boxes_that_fill_their_image() -> None:
    """power 3 from 0.1 of the image's long side: a judged box that long scores s·p³, a smaller judged box s·p, an
    unjudged one s; the same boxes on a larger image fall under the share; power 1 is s·p whatever the share, and
    from 0 every judged box is cubed. Checkpoints from before the power read back as s·p; bad values are named."""
    cfg = VerifierConfig(widths=(8, 16), power=3.0, power_from=0.1)
    net = constant(0.5, cfg)
    dets = np.array([[10, 10, 30, 25, 0.8, 0],  # 20 px: under min_side, not judged
                     [100, 100, 150, 140, 0.8, 0],  # 50 px: judged, under a tenth of 640
                     [200, 100, 300, 180, 0.8, 0]], np.float32)  # 100 px: a tenth of 640 or more
    photo = verify(net, np.full((480, 640, 3), 90, np.uint8), dets)
    np.testing.assert_allclose(photo[:, 4], [0.8, 0.4, 0.1], rtol=1e-5)
    frame = verify(net, np.full((720, 1280, 3), 90, np.uint8), dets)  # a tenth is 128 px: none that long
    np.testing.assert_allclose(frame[:, 4], [0.8, 0.4, 0.4], rtol=1e-5)
    every = verify(constant(0.5, replace(cfg, power_from=0.0)), np.full((720, 1280, 3), 90, np.uint8), dets)
    np.testing.assert_allclose(every[:, 4], [0.8, 0.1, 0.1], rtol=1e-5)
    plain = verify(constant(0.5, replace(cfg, power=1.0)), np.full((480, 640, 3), 90, np.uint8), dets)
    np.testing.assert_allclose(plain[:, 4], [0.8, 0.4, 0.4], rtol=1e-5)
    assert photo.dtype == dets.dtype
    old = {"crop": 96, "context": 1.2, "min_side": 24.0, "widths": [8, 16]}  # a checkpoint from before the power
    before = VerifierConfig.from_dict(old)
    assert (before.power, before.power_from) == pytest.approx((1.0, 0.0))
    assert VerifierConfig.from_dict(cfg.to_dict()) == cfg
    for field, value in (("power", 0.5), ("power", float("nan")), ("power_from", 1.5)):
        with pytest.raises(ParameterError, match=f"verifier {field}"):
            replace(cfg, **{field: value}).check()


def test_served_views_average_the_crops_at_each_context_and_their_mirror_images() -> None:
    """contexts (1.2, 1.45) with mirror: p(zebra) is the mean of four single-crop verifiers' answers with the same
    weights, the mirrored ones computed independently, on the mirrored image around the mirrored box."""
    torch.manual_seed(5)
    rng = np.random.default_rng(5)
    img = rng.integers(0, 100, (200, 300, 3), dtype=np.uint8)
    img[:, ::7] = 255  # vertical stripes, brightest in the left half: not the same mirrored
    img[:, 150:] //= 2
    boxes = np.array([[100, 50, 180, 90], [20, 100, 60, 180]], np.float32)
    flipped = np.ascontiguousarray(img[:, ::-1])
    fboxes = np.stack([300 - boxes[:, 2], boxes[:, 1], 300 - boxes[:, 0], boxes[:, 3]], 1)
    base = Verifier(VerifierConfig(widths=(8, 16), contexts=(1.2, 1.45), mirror=True)).eval()
    with torch.no_grad():
        base.head.weight.mul_(200)  # a random head says about 0.5 to everything: spread its answers
    assert base.cfg.views() == [(1.2, False), (1.2, True), (1.45, False), (1.45, True)]
    singles = []
    for ctx in (1.2, 1.45):
        one = Verifier(VerifierConfig(widths=(8, 16), context=ctx)).eval()
        one.load_state_dict(base.state_dict())
        singles += [zebra_probability(one, img, boxes), zebra_probability(one, flipped, fboxes)]
    assert np.abs(singles[0] - singles[1]).max() > 1e-4  # the mirror image is another view, not the same crop
    np.testing.assert_allclose(zebra_probability(base, img, boxes), np.mean(singles, 0), rtol=1e-5, atol=1e-6)
    assert VerifierConfig().views() == [(1.2, False)]  # the default: one crop at the training context
    assert VerifierConfig(context=1.5, mirror=True).views() == [(1.5, False), (1.5, True)]
    with pytest.raises(ParameterError, match="contexts.*0.5"):
        VerifierConfig(contexts=(1.2, 0.5)).check()
    with pytest.raises(ParameterError, match="contexts"):
        VerifierConfig(contexts=(1.2, 1.2)).check()
    old = {"crop": 96, "context": 1.2, "min_side": 24.0, "widths": [8, 16]}  # a checkpoint from before the views
    assert VerifierConfig.from_dict(old).views() == [(1.2, False)]


def test_an_ensemble_averages_its_members_probabilities_and_records_them(
        tmp_path: Path, cli: CliRun) -> None:
    """Three verifiers saved apart, joined on the command line: the ensemble's p(zebra) of every box is the mean of
    the members' own (not the sigmoid of their mean logit), its record names each member's file by sha256, and it
    serves the views it is given. Members of another shape, too few, an ensemble as a member and training an
    ensemble are refused by name."""
    rng = np.random.default_rng(8)
    img = rng.integers(0, 255, (160, 240, 3), dtype=np.uint8)
    boxes = np.array([[20, 30, 90, 80], [120, 40, 200, 150], [60, 100, 110, 140]], np.float32)
    cfg = VerifierConfig(widths=(8, 16), min_side=10)
    paths, singles = [], []
    for k in range(3):
        torch.manual_seed(40 + k)
        net = Verifier(cfg).eval()
        with torch.no_grad():
            net.head.weight.mul_(300)  # spread the answers: a random head says about 0.5 to everything
            net.head.bias.fill_(2.0 * k - 2.0)  # and the members apart
        paths.append(tmp_path / f"m{k}.pt")
        save_verifier(paths[-1], net, seed=40 + k)
        singles.append(zebra_probability(net, img, boxes))
    assert np.ptp(np.stack(singles), 0).max() > 0.05  # the members disagree
    done = cli(["verifier-ensemble", *paths, "--out", tmp_path / "e.pt"])
    assert done.returncode == 0, done.stderr
    ens, record = load_verifier(tmp_path / "e.pt")
    assert ens.cfg == replace(cfg, members=3)
    assert [m["sha256"] for m in record["members"]] == [hashlib.sha256(p.read_bytes()).hexdigest() for p in paths]
    assert [m["seed"] for m in record["members"]] == [40, 41, 42]
    np.testing.assert_allclose(zebra_probability(ens, img, boxes), np.mean(singles, 0), rtol=1e-5, atol=1e-6)
    logit_mean = 1 / (1 + np.exp(-np.mean([np.log(s / (1 - s)) for s in singles], 0)))
    assert np.abs(logit_mean - np.mean(singles, 0)).max() > 1e-3  # the test tells the two means apart
    dets = np.concatenate([boxes, np.full((3, 1), 0.8, np.float32)], 1)
    np.testing.assert_allclose(verify(ens, img, dets)[:, 4], 0.8 * np.mean(singles, 0), rtol=1e-5)
    # stored in float16, it answers within float16's rounding and serves in float32
    assert cli(["verifier-ensemble", *paths, "--half", "--out", tmp_path / "h.pt"]).returncode == 0
    half, hrec = load_verifier(tmp_path / "h.pt")
    assert hrec["float16"] is True and next(half.parameters()).dtype == torch.float32
    assert (tmp_path / "h.pt").stat().st_size < 0.7 * (tmp_path / "e.pt").stat().st_size
    np.testing.assert_allclose(zebra_probability(half, img, boxes), np.mean(singles, 0), atol=0.02)
    # the views given on the command line are served; the weights are the same
    views = ensemble_verifiers(paths[:2], tmp_path / "v.pt", contexts=(1.2, 1.45), mirror=True)
    assert views["config"]["contexts"] == [1.2, 1.45] and views["config"]["mirror"] is True
    assert load_verifier(tmp_path / "v.pt")[0].cfg.views() == [(1.2, False), (1.2, True), (1.45, False), (1.45, True)]
    save_verifier(tmp_path / "wide.pt", Verifier(VerifierConfig(widths=(8, 24), min_side=10)))
    refused = cli(["verifier-ensemble", paths[0], tmp_path / "wide.pt", "--out", tmp_path / "x.pt"])
    assert refused.returncode == 2 and "widths" in refused.stderr and "wide.pt" in refused.stderr
    refused = cli(["verifier-ensemble", paths[0], "--out", tmp_path / "x.pt"])
    assert refused.returncode == 2 and "2..8 verifier checkpoints" in refused.stderr
    refused = cli(["verifier-ensemble", paths[0], paths[1], paths[0], "--out", tmp_path / "x.pt"])
    assert refused.returncode == 2 and "an earlier member's" in refused.stderr and "m0.pt" in refused.stderr
    refused = cli(["verifier-ensemble", tmp_path / "e.pt", paths[0], "--out", tmp_path / "x.pt"])
    assert refused.returncode == 2 and "ensemble already" in refused.stderr
    refused = cli(["verifier-ensemble", *paths[:2], "--contexts", "0.5", "--out", tmp_path / "x.pt"])
    assert refused.returncode == 2 and "'--contexts' = (0.5,)" in refused.stderr
    assert not (tmp_path / "x.pt").exists()
    raw = torch.load(tmp_path / "e.pt", weights_only=True)
    assert raw["version"] == 2 and torch.load(paths[0], weights_only=True)["version"] == 1
    from zebra_sim_ros.detection.checkpoint import read_checkpoint

    with pytest.raises(AssetError, match="checkpoint version 2; this build reads 1"):
        read_checkpoint(tmp_path / "e.pt", "verifier", "zebra_sim_ros/verifier", 1)
    raw["config"]["members"] = 1  # weights of three networks under the config of one
    torch.save(raw, tmp_path / "bad.pt")
    with pytest.raises(AssetError, match=r"bad\.pt: its weights do not fit its config"):
        load_verifier(tmp_path / "bad.pt")
    (tmp_path / "set" / "annotations").mkdir(parents=True)
    with pytest.raises(ParameterError, match="verifier members"):
        TrainVerifierConfig(data=(str(tmp_path / "set"),), out="y", model=replace(cfg, members=2)).check()
    with pytest.raises(ParameterError, match="verifier members"):
        VerifierConfig(members=0).check()


def test_a_verifier_served_otherwise_keeps_its_weights_and_record(tmp_path: Path, cli: CliRun) -> None:
    """``verifier-serving`` writes a verifier again with the serving settings given (power, the share it starts
    from, views), the others kept: the same weights tensor for tensor, the same training record, and the scores
    the new settings give. A bad setting is refused naming its option, and nothing is written."""
    torch.manual_seed(5)
    net = Verifier(VerifierConfig(widths=(8, 16), min_side=10)).eval()
    with torch.no_grad():
        net.head.weight.mul_(300)
    save_verifier(tmp_path / "v.pt", net, seed=5, crops={"zebra": 7})
    done = cli(["verifier-serving", tmp_path / "v.pt", "--power", "3", "--power-from", "0.25", "--mirror",
                "--out", tmp_path / "p.pt", "--json"])
    assert done.returncode == 0, done.stderr
    served, record = load_verifier(tmp_path / "p.pt")
    assert served.cfg == replace(net.cfg, power=3.0, power_from=0.25, mirror=True)
    assert record["seed"] == 5 and record["crops"] == {"zebra": 7}
    a, b = torch.load(tmp_path / "v.pt", weights_only=True), torch.load(tmp_path / "p.pt", weights_only=True)
    assert a["model"].keys() == b["model"].keys() and all(torch.equal(a["model"][k], b["model"][k]) for k in a["model"])
    rng = np.random.default_rng(3)
    img = rng.integers(0, 255, (160, 240, 3), dtype=np.uint8)
    dets = np.array([[20, 30, 90, 80, 0.9], [120, 40, 140, 60, 0.9]], np.float32)  # 70 px: a quarter of 240 or more
    p = zebra_probability(served, img, dets)  # with the mirror images, as served
    assert 0.05 < p[0] < 0.95, p  # where p³ and p differ
    np.testing.assert_allclose(verify(served, img, dets)[:, 4], [0.9 * p[0] ** 3, 0.9 * p[1]], rtol=1e-5)
    again = reserve_verifier(tmp_path / "p.pt", tmp_path / "q.pt", power=1.0)  # the others kept
    assert again["config"] == replace(served.cfg, power=1.0).to_dict()
    refused = cli(["verifier-serving", tmp_path / "v.pt", "--power", "0.5", "--out", tmp_path / "x.pt"])
    assert refused.returncode == 2 and "'--power' = 0.5" in refused.stderr
    refused = cli(["verifier-serving", tmp_path / "v.pt", "--contexts", "4", "--out", tmp_path / "x.pt"])
    assert refused.returncode == 2 and "'--contexts' = (4.0,)" in refused.stderr
    assert not (tmp_path / "x.pt").exists()
    with pytest.raises(ParameterError, match="'crop'.*serving settings"):
        reserve_verifier(tmp_path / "v.pt", tmp_path / "x.pt", crop=64)  # a training setting


def test_detect_with_a_verifier_is_detect_rescored(tmp_path: Path) -> None:
    """The shipped detector on a rendered frame: with a verifier of p = 0.5 every zebra box of 24 px or more scores
    half, smaller ones the same, and those now under conf are gone."""
    from zebra_sim_ros.detection.checkpoint import load_model
    from zebra_sim_ros.detection.predict import detect

    out = tmp_path / "ds"
    generate(GenerateConfig(out=str(out), frames=3, strategy="low", worlds=("savanna",), seed=11, width=640,
                            height=360, depth="none"), progress=lambda *a: None)
    from zebra_sim_ros.detection.verify import read_rgb

    img = read_rgb(next((out / "images").rglob("*.jpg")))
    model, _ = load_model(None)
    plain = detect(model, [img], conf=0.05)[0]
    half = detect(model, [img], conf=0.05, verifier=constant(0.5))[0]
    side = np.maximum(plain[:, 2] - plain[:, 0], plain[:, 3] - plain[:, 1])
    want = plain[:, 4] * np.where(side >= 24, 0.5, 1.0)
    assert len(plain) > 0 and (side >= 24).any()
    np.testing.assert_allclose(np.sort(half[:, 4])[::-1], np.sort(want[want >= 0.05])[::-1], rtol=1e-4)


def test_a_served_verifier_has_its_batch_norms_folded_and_answers_as_the_trained_one(tmp_path: Path) -> None:
    """load_verifier folds the shipped verifier's batch norms (their running statistics) into its convolutions, as
    served; its p(zebra) of crops of every kind is the unfused network's to float32 rounding, and the folded network
    is neither trained nor saved by mistake."""
    plain, _ = load_verifier("shipped", fuse=False)
    served, _ = load_verifier("shipped")
    assert not plain.fused and served.fused
    assert any(isinstance(m, torch.nn.BatchNorm2d) for m in plain.modules())
    assert not any(isinstance(m, torch.nn.BatchNorm2d) for m in served.modules())
    rng = np.random.default_rng(12)
    img = rng.integers(0, 256, (240, 320, 3), dtype=np.uint8)
    img[:, ::9] = 255  # stripes here and there, flat and noisy patches elsewhere
    img[100:, 200:] = (90, 120, 60)
    x0, y0 = rng.uniform(-20, 300, 24), rng.uniform(-20, 220, 24)
    side = rng.uniform(24, 120, 24)
    boxes = np.stack([x0, y0, x0 + side, y0 + side * rng.uniform(0.5, 1.5, 24)], 1).astype(np.float32)
    want = zebra_probability(plain, img, boxes)
    assert np.ptp(want) > 0.05  # the boxes are told apart, so the comparison says something
    np.testing.assert_allclose(zebra_probability(served, img, boxes), want, rtol=0, atol=2e-5)
    with pytest.raises(RuntimeError, match="fused verifier"):
        served.train()
    with pytest.raises(ParameterError, match="unfused verifier"):
        save_verifier(tmp_path / "x.pt", served)
    assert not (tmp_path / "x.pt").exists()
    ens = Verifier(VerifierConfig(widths=(8, 16), members=2))  # built in training mode
    ens.members[0].fuse()  # type: ignore[operator]
    assert ens.fused  # one member folded: the whole cannot be trained or saved
    assert not ens.fuse().training and len(zebra_probability(ens, img, boxes)) == len(boxes)


def test_checkpoints_round_trip_and_bad_files_name_themselves(tmp_path: Path) -> None:
    net = constant(0.7, VerifierConfig(crop=48, context=1.5, min_side=30, widths=(8, 16, 24), contexts=(1.3, 1.6),
                                       mirror=True))
    save_verifier(tmp_path / "v.pt", net, seed=3)
    back, ckpt = load_verifier(tmp_path / "v.pt")
    assert back.cfg == net.cfg and ckpt["seed"] == 3 and "model" not in ckpt
    x = torch.rand(2, 3, 48, 48)
    torch.testing.assert_close(torch.sigmoid(back(x)), torch.full((2,), 0.7), rtol=1e-4, atol=1e-4)
    with pytest.raises(ParameterError, match=r"'verifier'.*nope\.pt"):
        load_verifier(tmp_path / "nope.pt")
    (tmp_path / "junk.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(AssetError, match="junk.pt"):
        load_verifier(tmp_path / "junk.pt")
    from zebra_sim_ros.detection.checkpoint import SHIPPED

    with pytest.raises(AssetError, match="not a zebra_sim_ros/verifier"):
        load_verifier(SHIPPED)  # the detector's weights are not a verifier
    with pytest.raises(ParameterError, match="verifier crop"):
        Verifier(VerifierConfig(crop=8))


@pytest.fixture(scope="module")
def frames(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("verify") / "low"
    generate(GenerateConfig(out=str(out), frames=6, strategy="low", worlds=("savanna",), seed=21, width=640,
                            height=360, depth="none", other_animals=8,
                            placer={"low_other_target": 0.5, "low_distance_max": 12.0}), progress=lambda *a: None)
    return out


def test_crops_follow_the_annotations_and_the_seed(frames: Path, tmp_path: Path) -> None:
    cfg = TrainVerifierConfig(data=(str(frames),), out=str(tmp_path / "v.pt"), min_visible_pixels=100, seed=4)
    a, b = collect_crops(cfg), collect_crops(cfg)
    np.testing.assert_array_equal(a.x, b.x)
    other = collect_crops(TrainVerifierConfig(data=(str(frames),), out="x", min_visible_pixels=100, seed=5))
    assert other.x.shape != a.x.shape or not np.array_equal(a.x, other.x)  # another seed, other jitter
    n_zebra = n_other = 0
    for f in (frames / "annotations").glob("*.json"):
        for z in json.loads(f.read_text())["labels"]["zebras"]:
            box = z.get("box_visible")
            if (box and max(box[2] - box[0], box[3] - box[1]) >= 24 and z["visible_pixels"] >= 100
                    and z["visible_fraction"] >= 0.3):
                n_zebra += z.get("species", "zebra") == "zebra"
                n_other += z.get("species", "zebra") != "zebra"
    counts = a.counts()
    assert (counts["zebra"], counts["other species"]) == (2 * n_zebra, 2 * n_other)  # two jittered crops each
    assert counts["zebra"] > 0 and counts["background"] > 0
    assert a.x.shape[1:] == (112, 112, 3) and set(np.unique(a.y)) <= {0.0, 1.0}
    np.testing.assert_array_equal(a.y, (a.kind == 2).astype(np.float32))  # no parts by default


def test_crops_know_their_frame_and_a_frame_split_keeps_each_frame_on_one_side(frames: Path) -> None:
    """Every crop names the frame it was cut from (frames in the datasets' order); ``split="frame"`` holds out every
    crop of a share of the frames, ``"crop"`` a share of the crops drawn as the shipped verifier's were."""
    crops = collect_crops(TrainVerifierConfig(data=(str(frames),), out="x", min_visible_pixels=100, seed=4,
                                              clutter_per_frame=1))  # a crop from every frame
    files = sorted((frames / "annotations").glob("*.json"))
    np.testing.assert_array_equal(np.unique(crops.frame), np.arange(len(files)))
    assert (np.diff(crops.frame) >= 0).all()
    for i, f in enumerate(files):  # the frame's own zebras: two jittered crops of each one big enough
        zebras = [z for z in json.loads(f.read_text())["labels"]["zebras"] if z.get("species", "zebra") == "zebra"
                  and z.get("box_visible") and max(z["box_visible"][2] - z["box_visible"][0],
                                                   z["box_visible"][3] - z["box_visible"][1]) >= 24
                  and z["visible_pixels"] >= 100 and z["visible_fraction"] >= 0.3]
        assert int(((crops.frame == i) & (crops.kind == KINDS.index("zebra"))).sum()) == 2 * len(zebras)
    val, tr = held_out(crops, "frame", 0.34, torch.Generator().manual_seed(1))
    assert len(val) + len(tr) == len(crops.x) and not set(val.tolist()) & set(tr.tolist())
    val_frames, tr_frames = set(crops.frame[val.numpy()].tolist()), set(crops.frame[tr.numpy()].tolist())
    assert len(val_frames) == round(len(files) * 0.34) and not val_frames & tr_frames
    val, tr = held_out(crops, "crop", 0.1, torch.Generator().manual_seed(25))
    perm = torch.randperm(len(crops.x), generator=torch.Generator().manual_seed(25))
    n_val = int(len(crops.x) * 0.1)
    assert torch.equal(val, perm[:n_val]) and torch.equal(tr, perm[n_val:])
    one = type(crops)(crops.x, crops.y, crops.kind, np.zeros_like(crops.frame))
    with pytest.raises(ParameterError, match="'--split'.*two frames"):
        held_out(one, "frame", 0.1, torch.Generator())
    with pytest.raises(ParameterError, match="'--split' = 'animal'"):
        held_out(crops, "animal", 0.1, torch.Generator())


def test_train_verifier_writes_a_checkpoint_that_records_its_recipe(frames: Path, tmp_path: Path) -> None:
    cfg = TrainVerifierConfig(data=(str(frames),), out=str(tmp_path / "v.pt"), epochs=2, batch=16,
                              min_visible_pixels=100, seed=7, model=VerifierConfig(widths=(8, 16, 24)))
    record = train_verifier(cfg, log=lambda s: None)
    net, ckpt = load_verifier(tmp_path / "v.pt")
    assert ckpt["train"]["seed"] == 7 and ckpt["train"]["data"] == [str(frames)] and ckpt["crops"] == record["crops"]
    assert len(ckpt["history"]) == 2 and set(ckpt["val"]) == set(KINDS)
    img = np.full((100, 100, 3), 128, np.uint8)
    p = verify(net, img, np.array([[10, 10, 90, 90, 1.0]]))[0, 4]
    assert 0.0 < p < 1.0
    # the serving views are recorded, never trained on: the same run with them gives the same weights
    served = VerifierConfig(widths=(8, 16, 24), contexts=(1.2, 1.45), mirror=True)
    train_verifier(replace(cfg, out=str(tmp_path / "w.pt"), model=served), log=lambda s: None)
    net2, ckpt2 = load_verifier(tmp_path / "w.pt", fuse=False)  # the weights as trained, both
    assert net2.cfg == served and ckpt2["train"]["model"]["mirror"]
    net = load_verifier(tmp_path / "v.pt", fuse=False)[0]
    for k, v in net.state_dict().items():
        assert torch.equal(v, net2.state_dict()[k]), k


def test_parts_and_clutter_are_added_crops_of_their_own_streams(frames: Path) -> None:
    """``parts_per_animal`` adds that many squares per cropped animal, labelled as the animal is;
    ``clutter_per_frame`` adds drawn squares, never a zebra; the crops of the plain recipe stay exactly the same."""
    base = dict(data=(str(frames),), out="x.pt", min_visible_pixels=100, seed=4)
    plain = collect_crops(TrainVerifierConfig(**base))  # type: ignore[arg-type]
    more = collect_crops(TrainVerifierConfig(**base, parts_per_animal=3, clutter_per_frame=2))  # type: ignore[arg-type]
    n_frames = len(list((frames / "annotations").glob("*.json")))
    counts, before = more.counts(), plain.counts()
    assert counts["drawn clutter"] == 2 * n_frames and before["drawn clutter"] == 0
    assert (counts["parts of zebras"], counts["parts of other species"]) == (
        before["zebra"] // 2 * 3, before["other species"] // 2 * 3)  # two crops per animal, three parts
    assert counts["parts of zebras"] > 0
    np.testing.assert_array_equal(more.y, np.isin(more.kind, (2, 5)).astype(np.float32))
    np.testing.assert_array_equal(more.x[more.kind <= 3], plain.x)
    np.testing.assert_array_equal(more.kind[more.kind <= 3], plain.kind)


def test_drawn_clutter_is_seeded_textured_and_sized() -> None:
    a = draw_clutter(np.random.default_rng(3), 112)
    b = draw_clutter(np.random.default_rng(3), 112)
    c = draw_clutter(np.random.default_rng(4), 112)
    assert a.shape == (112, 112, 3) and a.dtype == np.uint8
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    stds = [float(draw_clutter(np.random.default_rng(s), 64).std()) for s in range(20)]
    assert np.median(stds) > 3.0, stds  # texture, not flat squares


@pytest.mark.parametrize(("field", "value", "named"), [("data", (), "--data"), ("epochs", 0, "--epochs"),
                                                       ("lr", 0.0, "--lr"), ("val_fraction", 0.7, "--val-fraction"),
                                                       ("parts_per_animal", -1, "--parts-per-animal"),
                                                       ("clutter_per_frame", -1, "--clutter-per-frame"),
                                                       ("split", "animal", "--split")])
def test_bad_training_settings_name_themselves(frames: Path, field: str, value: object, named: str) -> None:
    kw: dict[str, object] = {"data": (str(frames),), "out": "x.pt", field: value}
    with pytest.raises(ParameterError, match=named):
        TrainVerifierConfig(**kw).check()  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="--data"):
        TrainVerifierConfig(data=(str(frames / "annotations"),), out="x.pt").check()


def test_the_shipped_verifier_records_its_recipe() -> None:
    """The package's verifier is the one its recipe file and the README's commands make."""
    assert SHIPPED_VERIFIER.is_file()
    recipe = SHIPPED_VERIFIER.with_name("zebra_verifier.recipe.txt").read_text()
    assert "train-verifier --data datasets/cls_3400 datasets/cls_3500 --epochs 10 --seed 25 \\\n" \
        "    --min-visible-pixels 1500 --min-side-fraction 0.0375 --detector stage16.pt --mine-conf 0.3" in recipe
    readme = " ".join((Path(__file__).resolve().parents[1] / "README.md").read_text().replace("\\\n", " ").split())
    assert ("zebra-sim train-verifier --data datasets/cls_3400 datasets/cls_3500 --epochs 10 --seed 25 "
            "--min-visible-pixels 1500 --min-side-fraction 0.0375 --detector stage16.pt --mine-conf 0.3") in readme
    net, ckpt = load_verifier("shipped")
    assert ckpt["train"]["seed"] == 25 and ckpt["train"]["epochs"] == 10
    assert ckpt["train"]["min_visible_pixels"] == 1500
    assert ckpt["train"].get("split", "crop") == "crop"  # trained before the option: its held-out share is of crops
    assert [Path(d).name for d in ckpt["train"]["data"]] == ["cls_3400", "cls_3500"]
    assert net.cfg == VerifierConfig(min_side_fraction=0.0375)
    # hard negatives mined at conf 0.3 by the detector shipped then (stage 16): the recipe names it by its sha256,
    # which the checkpoint records in full; stage 17 is served with this verifier (BENCHMARKS.md, "Stage 17")
    assert ckpt["train"]["detector"] == "shipped" and ckpt["train"]["mine_conf"] == pytest.approx(0.3)
    assert ckpt["detector_sha256"].startswith("0912dfdd2fe6") and "sha256 0912dfdd2fe6..." in recipe


def test_train_verifier_on_the_command_line_records_its_options(frames: Path, tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    """The crop options reach the checkpoint; ``--min-side`` is the size the verifier judges from, and animals
    smaller than it are not cropped."""
    from zebra_sim_ros.cli import main

    out = tmp_path / "v.pt"
    assert main(["train-verifier", "--data", str(frames), "--epochs", "1", "--batch", "16", "--seed", "3",
                 "--min-side", "40", "--min-side-fraction", "0.05", "--min-visible-pixels", "100",
                 "--clutter-per-frame", "1", "--detector", "shipped", "--mine-conf", "0.05", "--split", "frame",
                 "--contexts", "1.2", "1.5", "--mirror", "--crop", "48", "--widths", "8", "16", "24",
                 "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out.splitlines()[-1])
    net, ckpt = load_verifier(out)
    assert net.cfg.crop == 48 and net.cfg.widths == (8, 16, 24)  # the network it built, and its record
    assert ckpt["train"]["model"]["crop"] == 48 and ckpt["train"]["model"]["widths"] == [8, 16, 24]
    assert [m.out_channels for m in net.body if isinstance(m, torch.nn.Conv2d)][::2] == [8, 16, 24]
    assert zebra_probability(net, np.zeros((120, 160, 3), np.uint8), np.array([[10.0, 10, 90, 70]])).shape == (1,)
    assert net.cfg.min_side == 40 and ckpt["train"]["model"]["min_side"] == 40
    assert net.cfg.min_side_fraction == pytest.approx(0.05)
    assert ckpt["train"]["model"]["min_side_fraction"] == pytest.approx(0.05)
    assert net.cfg.contexts == pytest.approx((1.2, 1.5)) and net.cfg.mirror  # serving views, recorded
    assert ckpt["train"]["model"]["contexts"] == pytest.approx([1.2, 1.5]) and ckpt["train"]["model"]["mirror"]
    assert ckpt["train"]["min_visible_pixels"] == 100 and ckpt["train"]["clutter_per_frame"] == 1
    assert ckpt["train"]["split"] == "frame" and ckpt["train"]["batch"] == 16 and ckpt["train"]["seed"] == 3
    default = TrainVerifierConfig(data=(), out="").to_dict()  # flags left out take the config's own defaults
    for key in ("lr", "val_fraction", "background_per_frame", "parts_per_animal", "mine_imgsz", "mine_on_animals"):
        assert ckpt["train"][key] == pytest.approx(default[key]), key
    from zebra_sim_ros.detection.checkpoint import SHIPPED  # the mining weights, by content: "shipped" changes

    assert ckpt["train"]["detector"] == "shipped" and ckpt["train"]["mine_conf"] == pytest.approx(0.05)
    assert ckpt["detector_sha256"] == hashlib.sha256(SHIPPED.read_bytes()).hexdigest()
    n_frames = len(list((frames / "annotations").glob("*.json")))
    assert summary["crops"]["drawn clutter"] == n_frames
    wide = collect_crops(TrainVerifierConfig(data=(str(frames),), out="x", min_visible_pixels=100, seed=3))
    assert summary["crops"]["zebra"] <= wide.counts()["zebra"]  # 24 px boxes are cropped, 40 px ones only here
    assert main(["train-verifier", "--data", str(frames), "--min-side", "0", "--out", str(out)]) == 2
    assert "'--min-side' = 0.0" in capsys.readouterr().err
    assert main(["train-verifier", "--data", str(frames), "--min-side-fraction", "0.9", "--out", str(out)]) == 2
    assert "'--min-side-fraction' = 0.9" in capsys.readouterr().err
    assert main(["train-verifier", "--data", str(frames), "--contexts", "1.2", "4", "--out", str(out)]) == 2
    assert "'--contexts' = (1.2, 4.0)" in capsys.readouterr().err
    assert main(["train-verifier", "--data", str(frames), "--crop", "20", "--out", str(out)]) == 2
    assert "'--crop' = 20" in capsys.readouterr().err
    assert main(["train-verifier", "--data", str(frames), "--widths", "8", "0", "--out", str(out)]) == 2
    assert "'--widths' = (8, 0)" in capsys.readouterr().err


def test_the_command_line_takes_a_verifier_where_the_detector_runs(frames: Path, tmp_path: Path,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """``val --verifier`` scores the rescored boxes (a verifier of p = 0.01 leaves only the small ones above conf
    0.25, so recall at 0.25 can only fall); ``predict`` and ``bag eval`` refuse a missing or misplaced one by name."""
    from zebra_sim_ros.cli import main

    save_verifier(tmp_path / "low.pt", constant(0.01))
    runs = {}
    for name, extra in (("plain", []), ("verified", ["--verifier", str(tmp_path / "low.pt")])):
        assert main(["val", "--data", str(frames), "--split", "train", "--device", "cpu", "--conf", "0.25",
                     "--plots", "", "--json", *extra]) == 0
        runs[name] = json.loads(capsys.readouterr().out.splitlines()[-1])
    assert runs["verified"]["verifier"] == str(tmp_path / "low.pt") and runs["plain"]["verifier"] is None
    assert runs["plain"]["recall"] > 0 and runs["verified"]["recall"] < runs["plain"]["recall"]
    assert main(["predict", str(frames / "images"), "--out", str(tmp_path / "p"), "--verifier",
                 str(tmp_path / "none.pt")]) == 2
    assert "'--verifier'" in capsys.readouterr().err
    assert main(["bag", "eval", str(tmp_path / "x.mcap"), "--verifier", "shipped"]) == 2
    assert "given with --weights" in capsys.readouterr().err


def test_the_shipped_verifier_tells_zebras_from_other_animals_in_new_frames(frames: Path) -> None:
    """On frames of a seed it never saw, the shipped verifier's p(zebra) is high on zebras and low on the other
    species' animals (its held-out crops at training: 96% and 13% called zebra)."""
    from zebra_sim_ros.detection.verify import read_rgb
    from zebra_sim_ros.messages import FrameAnnotation

    net, _ = load_verifier("shipped")
    p: dict[bool, list[float]] = {True: [], False: []}
    for f in sorted((frames / "annotations").glob("*.json")):
        ann = FrameAnnotation.from_json(f.read_text())
        boxes = [(z.is_zebra, z.box_visible) for z in ann.labels.zebras if z.box_visible is not None
                 and max(z.box_visible[2] - z.box_visible[0], z.box_visible[3] - z.box_visible[1]) >= 24
                 and z.visible_pixels >= 300 and z.visible_fraction >= 0.3]
        if boxes:
            probs = verify(net, read_rgb(frames / ann.image), np.array([[*b, 1.0] for _, b in boxes]))[:, 4]
            for (is_zebra, _), q in zip(boxes, probs, strict=True):
                p[is_zebra].append(float(q))
    assert len(p[True]) >= 5 and len(p[False]) >= 3, {k: len(v) for k, v in p.items()}
    assert np.mean(p[True]) > 0.6 and np.mean(p[False]) < 0.4, {k: np.round(v, 2).tolist() for k, v in p.items()}


def test_hard_negatives_are_the_detectors_boxes_on_no_zebra(frames: Path, tmp_path: Path) -> None:
    """``--detector``: its boxes off every zebra become crops of their own kind, drawn from their own stream (the
    other crops are exactly those without it); a box on a zebra, or centred in one's box, never does."""
    from zebra_sim_ros.detection.metrics import iou_matrix
    from zebra_sim_ros.detection.verify_train import _false_boxes

    zebras = np.array([[100, 100, 200, 160]], np.float64)
    det = np.array([[110, 105, 190, 150, 0.9, 0],  # on the zebra
                    [180, 150, 260, 200, 0.8, 0],  # touching it (IoU 0.02), centre outside: a false box
                    [0, 0, 300, 260, 0.75, 0],  # IoU 0.08 but centred in the zebra's box: not false
                    [300, 300, 400, 380, 0.7, 0],  # on nothing
                    [300, 10, 310, 20, 0.7, 0],  # on nothing but 10 px: under min_side
                    [500, 300, 600, 380, 0.6, 1]], np.float32)  # another class
    out = _false_boxes(det, zebras, 24, 0, iou_matrix)
    assert [tuple(r[:2]) for r in out] == [(180, 150), (300, 300)]
    base = TrainVerifierConfig(data=(str(frames),), out="x.pt", min_visible_pixels=100, seed=4)
    plain = collect_crops(base)
    mined = collect_crops(TrainVerifierConfig(data=(str(frames),), out="x.pt", min_visible_pixels=100, seed=4,
                                              detector="shipped", mine_conf=0.001))
    keep = mined.kind != 3
    np.testing.assert_array_equal(mined.x[keep], plain.x)
    assert mined.counts()["detector's false boxes"] > 0 and plain.counts()["detector's false boxes"] == 0
    assert not mined.y[~keep].any()
    off = collect_crops(TrainVerifierConfig(data=(str(frames),), out="x.pt", min_visible_pixels=100, seed=4,
                                            detector="shipped", mine_conf=0.001, mine_on_animals=False))
    np.testing.assert_array_equal(off.x[off.kind != 3], plain.x)
    # boxes on the other species' animals are no longer hard negatives: fewer of them, none new (conf 0.001: stage 17
    # leaves no box off the animals on these frames at 0.01)
    assert 0 < off.counts()["detector's false boxes"] < mined.counts()["detector's false boxes"]
    with pytest.raises(ParameterError, match="--detector"):
        TrainVerifierConfig(data=(str(frames),), out="x.pt", detector=str(tmp_path / "none.pt")).check()
