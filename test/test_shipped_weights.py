"""The shipped detector weights on freshly generated, held-out synthetic sets.

The shipped model was trained on seven worlds in five stages, 1-4 and 7 (README, "Shipped weights");
snowy_highland was left out. Stages 1-3 used seeds 100 and 1000103 (closeby) for every world, stage 4 a second
set with seed 200 and stage 7 a third with seed 400 (each world and strategy its own stream, half the steps with a
recoloured ground). Here small sets are generated with seed 777, whose streams none of those share, and scored
with our COCO metrics:

- the training worlds, new seeds: a regression floor under what the weights measured when they were shipped;
- the left-out world, new seeds: the issue's bar (mAP50 >= 0.8).

The weights were trained on the plain look (flat ground colours, bare coats, a perfect camera: ``--look plain
--sensor-strength 0``), before photographic rendering became the default; they are scored on that look here
until weights trained on photographic renders replace them.

Both at the shipped file's own inference size (1088 px for these 640x360 frames, chosen on the val split of seven
training worlds, README "Shipped weights"), zebras seen but below the label filters as don't-care regions.
"""

from __future__ import annotations

from pathlib import Path

import torch

from zebra_sim_ros.dataset.generate import GenerateConfig, generate, stream_seed
from zebra_sim_ros.detection.checkpoint import SHIPPED, read_checkpoint
from zebra_sim_ros.detection.evaluate import evaluate
from zebra_sim_ros.labels.config import LabelFilters

TRAINING_WORLDS = ("savanna", "grassland", "meadow", "woodland", "moorland", "scrubland", "farmland")
HELD_OUT_WORLD = "snowy_highland"
HELD_OUT_SEED = 777  # never used for training data
TRAINING_STREAMS = {100, 1_000_103} | {stream_seed(s, w, k) for s in (200, 400) for w in TRAINING_WORLDS
                                       for k in (0, 1)}


def _held_out_set(root: Path, worlds: tuple[str, ...], frames: int) -> Path:
    cfg = GenerateConfig(out=str(root), frames=frames, strategy="both", worlds=worlds, seed=HELD_OUT_SEED,
                         width=640, height=360, val_fraction=0.0, depth="none", look="plain", sensor_strength=0.0,
                         other_animals=0,
                         filters=LabelFilters(min_visible_pixels=25))
    generate(cfg, progress=lambda *a: None)
    return root / "dataset.yaml"


def test_shipped_weights_are_ours_and_say_how_they_were_trained() -> None:
    held_out = {stream_seed(HELD_OUT_SEED, w, k) for w in (*TRAINING_WORLDS, HELD_OUT_WORLD) for k in (0, 1)}
    assert not held_out & TRAINING_STREAMS  # the held-out frames are no training frames
    ckpt = read_checkpoint(SHIPPED)
    assert SHIPPED.stat().st_size < 20 << 20
    args = ckpt["train_args"]
    assert args["model"] == "n" and args["imgsz"] == 832  # last trained at 832, served at 1088 (zebra-sim export)
    # served at 1088 on its 640x360 training frames, and at the same scale (1.7) on frames of any other size
    assert ckpt["config"]["imgsz"] == 1088 and ckpt["config"]["frame"] == 640
    assert ckpt["exported"]["previous"] == {"from_config_imgsz": 832, "imgsz": 1088}
    floats = [v for v in ckpt["model"].values() if v.dtype.is_floating_point]
    assert floats and all(v.dtype == torch.float16 for v in floats)  # fp16 on disk


def test_shipped_weights_on_new_seeds_of_the_training_worlds(tmp_path: Path) -> None:
    data = _held_out_set(tmp_path / "seen_worlds", TRAINING_WORLDS, 42)
    m, facts = evaluate(None, data, split="train")
    assert facts["imgsz"] == 1088 and m.instances > 200
    assert m.map50 >= 0.90, m.to_dict()  # measured when shipped: 0.937 (BENCHMARKS.md; the weights before: 0.934)
    assert m.map50_95 >= 0.58, m.to_dict()  # measured: 0.615 (before: 0.603)


def test_shipped_weights_reach_the_bar_on_a_world_left_out_of_training(tmp_path: Path) -> None:
    data = _held_out_set(tmp_path / "unseen_world", (HELD_OUT_WORLD,), 24)
    m, facts = evaluate(None, data, split="train")
    assert facts["imgsz"] == 1088 and m.instances > 100
    assert m.map50 >= 0.8, m.to_dict()  # measured when shipped: 0.856 (the weights before: 0.820)
