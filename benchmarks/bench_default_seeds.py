"""Benchmark: the issue's gauge, ``val`` on a default ``generate``, over several new seeds at once.

One default set (``generate --frames 36``: 1280x720, savanna, far and close-by, the photographic look, other
species, domain randomisation) holds 12 placements; its mAP50 moves by 0.13 from one seed to the next, more than a
training stage moves it. This scores every ``--weights`` on the default set of each ``--seeds`` (generated once
with every frame in one split and no depth, cached under ``--cache`` as ``def_<seed>_<appearance digest>``; seeds used
to train or choose weights say nothing about new ones) exactly as default ``zebra-sim val`` does (the checkpoint's own
inference-size rule, conf 0.001, up to 300 detections per image, don't-care boxes honoured), and prints per seed,
their median, and all seeds' frames pooled into one COCO evaluation (the steadiest single figure).

``--bootstrap N`` also resamples the placements (the three views of one placement drawn together) N times, the same
draws for every row: each row's pooled mAP50 gets a 95% interval, and each row after the first the paired difference
from the first row (median, 95% interval, and the share of draws in which it scores higher): how far a difference
between two weights on these frames would move on new placements.

    python benchmarks/bench_default_seeds.py --seeds 4242 8888 9191 --weights shipped runs/x/best.pt [--bootstrap 1000]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import torch

from zebra_sim_ros.dataset.generate import GenerateConfig, generate
from zebra_sim_ros.detection.checkpoint import load_model
from zebra_sim_ros.detection.evaluate import ImagePredictions, make_loader, matched, placement, predictions, score
from zebra_sim_ros.detection.metrics import MatchedImage, interval95, paired_bootstrap
from zebra_sim_ros.detection.predict import inference_size
from zebra_sim_ros.detection.verify import Verifier, load_verifier, read_rgb, rescore
from zebra_sim_ros.zebra.asset import appearance_digest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_real import verifier_label  # noqa: E402

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


def matched_all(per_seed: dict[int, list[ImagePredictions]]) -> list[MatchedImage]:
    """Every seed's images, in order, matched for the bootstrap."""
    return matched([x for ps in per_seed.values() for x in ps])


def bootstrap_rows(rows: list[dict[str, Any]], runs: list[list[MatchedImage]], groups: list[tuple[int, str]],
                   samples: int, seed: int) -> None:
    """Add each row's pooled mAP50 interval and, after the first row, its paired difference from the first."""
    draws = paired_bootstrap(runs, groups, samples, seed, map50_only=True)[:, :, 0]
    for r, row_ in enumerate(rows):
        row_["pooled mAP50 95%"] = [round(x, 4) for x in interval95(draws[:, r])]
        if r:
            d = draws[:, r] - draws[:, 0]
            row_["minus first row"] = {"median of paired draws": round(float(np.median(d)), 4),
                                       "95%": [round(x, 4) for x in interval95(d)],
                                       "share higher": round(float(np.mean(d > 0)), 3),
                                       "share lower": round(float(np.mean(d < 0)), 3)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[4242, 8888, 9191])
    ap.add_argument("--weights", nargs="+", default=["shipped"], help="checkpoints ('shipped': the package's own)")
    ap.add_argument("--frames", type=int, default=DEFAULT_FRAMES)
    ap.add_argument("--workers", type=int, default=2, help="generation workers (the frames do not depend on it)")
    ap.add_argument("--cache", type=Path, default=Path("datasets"))
    ap.add_argument("--verifier", nargs="+", default=[], help="also score each weights with each of these "
                    "verifiers ('shipped': the package's), the same detections rescored as the detector node's "
                    "verifier parameter does")
    ap.add_argument("--bootstrap", type=int, default=0, help="resamples of the placements (0: none)")
    ap.add_argument("--bootstrap-seed", type=int, default=0)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    if args.bootstrap < 0:
        raise SystemExit(f"--bootstrap must be 0 or more, got {args.bootstrap}")
    if args.bootstrap_seed < 0:
        raise SystemExit(f"--bootstrap-seed must be 0 or more, got {args.bootstrap_seed}")
    if args.frames < 1:
        raise SystemExit(f"--frames must be 1 or more, got {args.frames}")
    if args.workers < 1:
        raise SystemExit(f"--workers must be 1 or more, got {args.workers}")
    if any(s < 0 for s in args.seeds) or len(set(args.seeds)) != len(args.seeds):
        raise SystemExit(f"--seeds must be distinct and 0 or more, got {args.seeds}")
    folders = {s: default_set(args.cache, s, args.frames, args.workers) for s in args.seeds}
    rows: list[dict[str, Any]] = []
    runs: list[list[MatchedImage]] = []
    groups: list[tuple[int, str]] = []
    if any(v in ("", "none") for v in args.verifier):  # bench_real's word for no verifier: here always a row
        raise SystemExit("--verifier: 'shipped' or checkpoints (each weights' row without a verifier is always there)")
    nets = [(v, load_verifier(v, "cpu", "--verifier")[0]) for v in args.verifier]
    for w in args.weights:
        model, _ = load_model(None if w == "shipped" else w, torch.device("cpu"))
        rule = partial(inference_size, model.cfg)  # each frame at the checkpoint's own scale, as val serves it
        t0 = time.perf_counter()
        per_seed = {s: predictions(model, make_loader(f, rule), VAL_CONF) for s, f in folders.items()}
        rows.append(row(w, per_seed, time.perf_counter() - t0))
        if args.bootstrap:
            runs.append(matched_all(per_seed))
            groups = [(s, placement(x.file)) for s, ps in per_seed.items() for x in ps]
        for v, net in nets:  # the same detections rescored, as predictions(..., verifier=net) would give them
            t0 = time.perf_counter()
            rescored = {s: [verified(net, x) for x in p] for s, p in per_seed.items()}
            rows.append(row(w + verifier_label(v), rescored, time.perf_counter() - t0))
            if args.bootstrap:
                runs.append(matched_all(rescored))
    if args.bootstrap:
        bootstrap_rows(rows, runs, groups, args.bootstrap, args.bootstrap_seed)
    if args.json:
        boot = ({"samples": args.bootstrap, "seed": args.bootstrap_seed, "placements": len(set(groups))}
                if args.bootstrap else None)
        print(json.dumps({"machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
                          "frames": args.frames, "bootstrap": boot, "rows": rows}, indent=1))
        return
    print(f"| weights | {' | '.join(f'seed {s}' for s in args.seeds)} | median | pooled ({args.frames} x "
          f"{len(args.seeds)} frames) |")
    print("| --- " * (len(args.seeds) + 3) + "|")
    for r in rows:
        cells = [f"{v['mAP50']:.3f} / {v['mAP50-95']:.3f}" for v in r["seeds"].values()]
        p = r["pooled"]
        print(f"| {r['weights']} | {' | '.join(cells)} | {r['median mAP50']:.3f} | "
              f"{p['mAP50']:.3f} / {p['mAP50-95']:.3f} ({p['zebras']} zebras) |")
    if args.bootstrap:
        print(f"\n{args.bootstrap} resamples of the {len(set(groups))} placements (seed {args.bootstrap_seed}), pooled "
              f"mAP50, the same draws for every row:\n")
        print(f"| weights | 95% interval | minus {rows[0]['weights']}: median of paired draws | its 95% interval | "
              "share of draws higher |")
        print("| --- | --- | --- | --- | --- |")
        for r in rows:
            lo, hi = r["pooled mAP50 95%"]
            d = r.get("minus first row")
            rest = (f"{d['median of paired draws']:+.4f} | {d['95%'][0]:+.4f} to {d['95%'][1]:+.4f} | "
                    f"{d['share higher']:.3f}" if d else "- | - | -")
            print(f"| {r['weights']} | {lo:.4f} to {hi:.4f} | {rest} |")


if __name__ == "__main__":
    main()
