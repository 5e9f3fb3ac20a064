"""The shipped detector weights on freshly generated, held-out synthetic sets.

The shipped model (stage 17, README "Shipped weights") is a weight-space blend (0.5 stage 16 + 0.5 its fine-tuning
on our CPU on 240 savanna frames of herds packed into a smaller rectangle, seed 7300). Stage 16 was a blend (0.5
stage 15 + 0.5 its fine-tuning on our CPU on stage 14's sets, the close views of other species rendered again with a
hide). Stage 15 was a blend (0.5 stage 14 + 0.5 its fine-tuning on a GPU on 910 frames of stage 14's sets, the close
views of other species rendered again with their own shapes). Stage 14 was a blend (0.5 stage 13 + 0.5 its
fine-tuning on our CPU on the same sets plus ground-level close views of other species, seed 3300). Stage 13 was a
blend (0.5 stage 12 + 0.5 its fine-tuning on our CPU on the sets of stages 11 and 12 together: seeds 6000, 6001,
5000, 5001, 3000 and 3100). Stage 12 was a blend (0.5 stage 11 + 0.5 its fine-tuning on 504 savanna 1280x720 frames,
seeds 6000 and 6001, on a GPU). Stage 11 was itself a blend (0.3 stage 10 + 0.7 its fine-tuning on 320 px crops of
2176 px samples of 1280x720 frames, seeds 5000 and 5001, all worlds, far and close-by, and 640x360 frames, seed
3000, all strategies). Stage 10 was fine-tuned from stage 7 (stage 8 on whole frames, stages 9 and 10 on crops
around zebras) on 2,448 photographic frames of all twelve worlds and four strategies (``generate --seed 1000
--worlds all --strategy all``; each world and strategy its own placer stream) and 900 ground-level frames (``--seed
2000 --strategy low``); stages 1-7 used seeds 100, 200 and 400 on seven worlds.
Here small sets are generated with seed 777, whose streams none of those share, with
the generator's defaults (the photographic look, weather, the camera model, domain
randomisation, other species), and scored with our COCO metrics at the shipped file's own inference-size rule
(1280x720 frames at 2176 and 640 px frames at 1088: a scale of 1.7), zebras seen but below
the label filters as don't-care regions:

- 640x360 frames of six worlds (four of them new in stage 8), far, close-by, low and nadir, one drone's view of
  each placement: a regression floor under what the weights measured when they were shipped;
- a default ``generate`` (1280x720, savanna, far and close-by): what ``val`` on a default set gives, a floor under
  the measured figure (the issue's goal, 0.85, is not reached: see README "Shipped weights").

Figures count up to 300 detections per image (the detector's ``max_det``), as ``val`` does.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from zebra_sim_ros.dataset.generate import STRATEGY_SETS, GenerateConfig, generate, stream_seed
from zebra_sim_ros.detection.checkpoint import SHIPPED, read_checkpoint
from zebra_sim_ros.detection.evaluate import evaluate
from zebra_sim_ros.world.presets import PRESETS

SEVEN_WORLDS = ("savanna", "grassland", "meadow", "woodland", "moorland", "scrubland", "farmland")
HELD_OUT_SEED = 777  # never used for training data
SIX_WORLDS = ("savanna", "woodland", "snowy_highland", "zoo", "waterhole", "dusty_plain")
TRAINING_STREAMS = ({100, 1_000_103} | {stream_seed(s, w, k) for s in (200, 400) for w in SEVEN_WORLDS for k in (0, 1)}
                    | {stream_seed(s, w, k) for s in (1000, 2000, 3000, 3100, 3300, 5000, 5001, 6000, 6001, 7300)
                       for w in PRESETS for k in range(4)})


def _held_out_set(root: Path, frames: int, **kw: object) -> Path:
    # two workers: the frames are the same as one worker's (each job has its own seeded streams), in about half
    # the time on two cores (24 placements of six worlds, 72 images: 103 s against 188 s, the same mAP to the last
    # digit)
    cfg = GenerateConfig(out=str(root), frames=frames, seed=HELD_OUT_SEED, val_fraction=0.0, depth="none",
                         workers=2, **kw)  # type: ignore[arg-type]
    generate(cfg, progress=lambda *a: None)
    return root / "dataset.yaml"


def test_shipped_weights_are_ours_and_say_how_they_were_trained() -> None:
    held_out = {stream_seed(HELD_OUT_SEED, w, k) for w in PRESETS for k in range(4)}
    assert not held_out & TRAINING_STREAMS  # the held-out frames are no training frames
    ckpt = read_checkpoint(SHIPPED)
    assert SHIPPED.stat().st_size < 20 << 20
    args = ckpt["train_args"]
    assert args["model"] == "n" and args["imgsz"] == 2176  # 1280x720 frames at the scale they are served at
    assert args["crop"] == 320 and args["aug"]["zoom"] == pytest.approx(0.5) and args["device"] != "cuda"
    # the recipe's last run: 12 epochs on our CPU from stage 16 (the package's file then), 0.5 of it blended with it
    assert args["init"].endswith("zebra_yolo_n.pt") and not args["resume"] and args["epochs"] == 12
    assert args["seed"] == 33 and args["lr0"] == pytest.approx(0.004) and args["batch"] == 16
    assert args["aug"]["zoom_crop"] == pytest.approx(1.0) and args["aug"]["background"] == pytest.approx(0.3)
    assert ckpt["blended"]["alpha"] == pytest.approx(0.5) and ckpt["blended"]["base"].endswith("stage16.pt")
    assert ckpt["blended"]["base_config"]["imgsz"] == 2176  # stage 16: 1280x720 frames served at 2176
    # served at 2176 on 1280x720 frames, and at the same scale (1.7) on frames of any other size (1088 for 640)
    assert ckpt["config"]["imgsz"] == 2176 and ckpt["config"]["frame"] == 1280
    assert ckpt["exported"]["imgsz"] == 2176
    # the last run's data's generate settings and the whole recipe, every stage and its sets, travel with the weights
    gen = list(ckpt["data_generate"]["sets"].values())
    assert [(g["seed"], g["worlds"], g["strategy"], g["width"], g["look"]) for g in gen] == [
        (7300, ["savanna"], "both", 1280, "photo")]
    assert (gen[0]["placer"]["rect_min"], gen[0]["placer"]["rect_max"]) == (15, 45)  # the herd packed (default 40-120)
    recipe = ckpt["recipe"]
    assert recipe == SHIPPED.with_name("zebra_yolo_n.recipe.txt").read_text()  # the file beside it, verbatim
    assert "zebra-sim generate" in recipe and all(f"--blend-base stage1{k}.pt" in recipe for k in range(7))
    assert "scripts/gpu/pack.py" in recipe and "scripts/gpu/train.sh" in recipe and "--keep-every" in recipe
    # every stage's data travels by its generate seed (the TRAINING_STREAMS above)
    assert all(f"--seed {s} " in recipe for s in (1000, 2000, 3000, 3100, 3300, 5000, 5001, 6000, 6001, 7300))
    assert set(STRATEGY_SETS["all"]) == {"far", "closeby", "low", "nadir"}
    floats = [v for v in ckpt["model"].values() if v.dtype.is_floating_point]
    assert floats and all(v.dtype == torch.float16 for v in floats)  # fp16 on disk


def test_shipped_weights_on_new_seeds_of_six_worlds_and_four_views(tmp_path: Path) -> None:
    # one drone (num_cameras 1): a placement per world and view, 24 frames with 974 zebras, where three drones made
    # 72 frames and took twice as long (123 s against 61-63 s on a 2-core EPYC without AVX-512), 0.660 / 0.327 on them
    data = _held_out_set(tmp_path / "six_worlds", 24, worlds=SIX_WORLDS, strategy="all", width=640, height=360,
                         placer={"num_cameras": 1})
    m, facts = evaluate(None, data, split="train")
    assert facts["imgsz"] == 1088 and m.images == 24 and m.instances > 700
    assert m.map50 >= 0.60, m.to_dict()  # measured: 0.664 (the 72 frames when shipped: 0.660; stage 16: 0.668)
    assert m.map50_95 >= 0.27, m.to_dict()  # measured: 0.331 (72 frames: 0.327; stage 16: 0.334)


def test_shipped_weights_on_a_default_generate(tmp_path: Path) -> None:
    data = _held_out_set(tmp_path / "default", 12)
    m, facts = evaluate(None, data, split="train")
    assert facts["imgsz"] == 2176 and m.images == 12 and m.instances > 500
    assert m.map50 >= 0.73, m.to_dict()  # measured when shipped: 0.804 (README "Shipped weights"; stage 16: 0.802)
    assert m.map50_95 >= 0.40, m.to_dict()  # measured: 0.466 (stage 16: 0.465)
