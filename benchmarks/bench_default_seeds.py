"""Benchmark: the issue's gauge, ``val`` on a default ``generate``, over several new seeds at once.

One default set (``generate --frames 36``: 1280x720, savanna, far and close-by, the photographic look, other
species, domain randomisation) holds 12 placements; its mAP50 moves by 0.13 from one seed to the next, more than a
training stage moves it. This scores every ``--weights`` on the default set of each ``--seeds`` (generated once
with every frame in one split and no depth, cached under ``--cache`` as ``def_<seed>_<appearance digest>``; seeds used
to train or choose weights say nothing about new ones) exactly as default ``zebra-sim val`` does (the checkpoint's own
inference-size rule, conf 0.001, up to 300 detections per image, don't-care boxes honoured), and prints per seed,
their median, and all seeds' frames pooled into one COCO evaluation (the steadiest single figure).

    python benchmarks/bench_default_seeds.py --seeds 4242 8888 9191 --weights shipped runs/x/best.pt
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from functools import partial
from pathlib import Path
from typing import Any

import torch

from zebra_sim_ros.dataset.generate import GenerateConfig, generate
from zebra_sim_ros.detection.checkpoint import load_model
from zebra_sim_ros.detection.evaluate import ImagePredictions, make_loader, predictions, score
from zebra_sim_ros.detection.predict import inference_size
from zebra_sim_ros.detection.verify import Verifier, load_verifier, read_rgb, rescore
from zebra_sim_ros.zebra.asset import appearance_digest

DEFAULT_FRAMES = 36  # README's default generate
VAL_CONF = 0.001  # default val: every detection above it counts into AP


def default_set(cache: Path, seed: int, frames: int, workers: int) -> Path:
    """The image folder of the default ``generate`` of ``seed`` (made once; a rerun reuses it). The folder is named
    after the seed and the appearance digest (asset and coats): a set rendered with other animals' shapes or hides is
    never reused."""
    root = cache / f"def_{seed}_{appearance_digest()[:8]}"
    if not (root / "dataset.yaml").exists():
        generate(GenerateConfig(out=str(root), frames=frames, seed=seed, val_fraction=0.0, depth="none",
                                workers=workers), progress=lambda *a: None)
    return root / "images" / "train"


def scored(per_image: list[ImagePredictions]) -> dict[str, float | int]:
    m = score(per_image)
    return {"images": m.images, "zebras": m.instances, "mAP50": round(m.map50, 4), "mAP50-95": round(m.map50_95, 4)}


def verified(net: Verifier, p: ImagePredictions) -> ImagePredictions:
    """``p`` with its detections rescored by ``net`` on crops of its image file (those now under val's conf
    dropped), as the detector node's verifier rescores them."""
    d = p.detections  # zebras only: every row is rescored
    return p._replace(detections=rescore(net, read_rgb(p.file), d, VAL_CONF)) if len(d) else p


def row(weights: str, per_seed: dict[int, list[ImagePredictions]], seconds: float) -> dict[str, Any]:
    seeds = {s: scored(p) for s, p in per_seed.items()}
    return {"weights": weights, "seeds": seeds,
            "median mAP50": round(statistics.median(x["mAP50"] for x in seeds.values()), 4),
            "pooled": scored([x for p in per_seed.values() for x in p]), "seconds": round(seconds, 1)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[4242, 8888, 9191])
    ap.add_argument("--weights", nargs="+", default=["shipped"], help="checkpoints ('shipped': the package's own)")
    ap.add_argument("--frames", type=int, default=DEFAULT_FRAMES)
    ap.add_argument("--workers", type=int, default=2, help="generation workers (the frames do not depend on it)")
    ap.add_argument("--cache", type=Path, default=Path("datasets"))
    ap.add_argument("--verifier", default="", help="also score each weights with this verifier ('shipped': the "
                    "package's) rescoring its zebra boxes, as the detector node's verifier parameter does")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    if args.frames < 1:
        raise SystemExit(f"--frames must be 1 or more, got {args.frames}")
    if args.workers < 1:
        raise SystemExit(f"--workers must be 1 or more, got {args.workers}")
    if any(s < 0 for s in args.seeds) or len(set(args.seeds)) != len(args.seeds):
        raise SystemExit(f"--seeds must be distinct and 0 or more, got {args.seeds}")
    folders = {s: default_set(args.cache, s, args.frames, args.workers) for s in args.seeds}
    rows: list[dict[str, Any]] = []
    net = load_verifier(args.verifier, "cpu", "--verifier")[0] if args.verifier else None
    for w in args.weights:
        model, _ = load_model(None if w == "shipped" else w, torch.device("cpu"))
        rule = partial(inference_size, model.cfg)  # each frame at the checkpoint's own scale, as val serves it
        t0 = time.perf_counter()
        per_seed = {s: predictions(model, make_loader(f, rule), VAL_CONF) for s, f in folders.items()}
        rows.append(row(w, per_seed, time.perf_counter() - t0))
        if net is not None:  # the same detections rescored, as predictions(..., verifier=net) would give them
            t0 = time.perf_counter()
            per_seed = {s: [verified(net, x) for x in p] for s, p in per_seed.items()}
            rows.append(row(w + " + verifier", per_seed, time.perf_counter() - t0))
    if args.json:
        print(json.dumps({"machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
                          "frames": args.frames, "rows": rows}, indent=1))
        return
    print(f"| weights | {' | '.join(f'seed {s}' for s in args.seeds)} | median | pooled ({args.frames} x "
          f"{len(args.seeds)} frames) |")
    print("| --- " * (len(args.seeds) + 3) + "|")
    for r in rows:
        cells = [f"{v['mAP50']:.3f} / {v['mAP50-95']:.3f}" for v in r["seeds"].values()]
        p = r["pooled"]
        print(f"| {r['weights']} | {' | '.join(cells)} | {r['median mAP50']:.3f} | "
              f"{p['mAP50']:.3f} / {p['mAP50-95']:.3f} ({p['zebras']} zebras) |")


if __name__ == "__main__":
    main()
