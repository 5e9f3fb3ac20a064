"""Benchmark: what moves the real-photo score. Each row adds one change to the generator or the training recipe and
gets the same CPU budget (the same number of training images at the same size, from the same starting weights and
seeds); every row is scored on the real sets (``bench_real``) and on a held-out synthetic set made by the default
``generate`` command with an unseen seed.

    python benchmarks/bench_ablation.py [--frames 600] [--images 2400] [--imgsz 416] [--init shipped] [--json]

Rows (cumulative):

1. today: the plain look, a perfect camera, no randomisation, zebras only, far and closeby cameras, YOLO's own
   augmentation (mosaic, affine, flip, HSV);
2. + realistic image formation (the photographic look, weather, the photograph's camera model);
3. + structured domain randomisation (``--randomise 0.5``);
4. + distractor species (``--other-animals 20``);
5. + low and nadir views (``--strategy all``);
6. + the transfer augmentations (zoom crops, cut-out, grey, gamma, white balance, blur, noise, JPEG).

Data and runs are cached under ``--cache`` (default ``out/ablation``) in a folder named after the animal asset's
digest, so an interrupted benchmark continues and a changed asset starts afresh; the table goes to stdout (and
BENCHMARKS.md unless ``--no-append``).
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_real import find_sets, fmt3, score_set  # noqa: E402

from zebra_sim_ros.zebra.asset import appearance_digest  # noqa: E402

ZS = [sys.executable, "-m", "zebra_sim_ros.cli"]
TODAY_GEN = ["--look", "plain", "--sensor-strength", "0", "--randomise", "0", "--other-animals", "0",
             "--strategy", "both"]
YOLO_AUG = ["--aug-zoom", "0", "--aug-grayscale", "0", "--aug-gamma", "0", "--aug-white-balance", "0",
            "--aug-blur", "0", "--aug-noise", "0", "--aug-jpeg", "0", "--aug-cutout", "0"]


def _gen(*overrides: str) -> list[str]:
    """TODAY_GEN with some options replaced."""
    out = list(TODAY_GEN)
    for k in range(0, len(overrides), 2):
        i = out.index(overrides[k])
        out[i + 1] = overrides[k + 1]
    return out


ROWS: list[tuple[str, list[str], list[str]]] = [
    ("today's data and recipe", TODAY_GEN, YOLO_AUG),
    ("+ realistic image formation", _gen("--look", "photo", "--sensor-strength", "1"), YOLO_AUG),
    ("+ domain randomisation", _gen("--look", "photo", "--sensor-strength", "1", "--randomise", "0.5"), YOLO_AUG),
    ("+ distractor species", _gen("--look", "photo", "--sensor-strength", "1", "--randomise", "0.5",
                                  "--other-animals", "20"), YOLO_AUG),
    ("+ low and nadir views", _gen("--look", "photo", "--sensor-strength", "1", "--randomise", "0.5",
                                   "--other-animals", "20", "--strategy", "all"), YOLO_AUG),
    ("+ transfer augmentations", _gen("--look", "photo", "--sensor-strength", "1", "--randomise", "0.5",
                                      "--other-animals", "20", "--strategy", "all"), []),
]


def run(cmd: list[str], log: Path) -> None:
    with open(log, "a", encoding="utf-8") as f:
        f.write(f"$ {' '.join(cmd)}\n")
        f.flush()
        subprocess.run(cmd, check=True, stdout=f, stderr=subprocess.STDOUT, cwd=ROOT)


def dataset(cache: Path, gen: list[str], frames: int, seed: int, log: Path) -> Path:
    """Generate (once) the set a row's generator options give; same seed and frame count for every row."""
    key = "_".join(v.lstrip("-") for v in gen).replace(".", "p")
    out = cache / "data" / key
    if not (out / "dataset.yaml").exists() or len(list((out / "annotations").glob("*.json"))) < frames:
        run([*ZS, "generate", "--frames", str(frames), "--imgsz", "640", "--worlds", "all", "--seed", str(seed),
             "--depth", "none", "--workers", "2", "--quiet", "--out", str(out), *gen], log)
    return out / "dataset.yaml"


def heldout(cache: Path, log: Path, frames: int = 36, seed: int = 4242) -> Path:
    """The default ``generate`` command's frames with a seed no row trains on (every frame to val)."""
    out = cache / f"heldout_default_{seed}"
    if not (out / "dataset.yaml").exists():
        run([*ZS, "generate", "--frames", str(frames), "--seed", str(seed), "--val-fraction", "0", "--depth", "none",
             "--quiet", "--out", str(out)], log)
    return out / "dataset.yaml"


def val(weights: Path, data: Path) -> dict[str, Any]:
    out = subprocess.run([*ZS, "val", "--weights", str(weights), "--data", str(data), "--split", "train", "--json"],
                         check=True, capture_output=True, text=True, cwd=ROOT).stdout
    return json.loads(out.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    ap.add_argument("--frames", type=int, default=600, help="frames of each row's training set")
    ap.add_argument("--images", type=int, default=2400, help="training images seen per row (the budget)")
    ap.add_argument("--imgsz", type=int, default=416)
    ap.add_argument("--batch", type=int, default=16)
    ap.add_argument("--init", default="shipped", help="starting weights of every row ('shipped' or a checkpoint; "
                    "'none': random)")
    ap.add_argument("--seed", type=int, default=2000, help="seed of the training sets (the held-out set: 4242)")
    ap.add_argument("--rows", default="", help="comma-separated row numbers (default: all)")
    ap.add_argument("--cache", type=Path, default=ROOT / "out" / "ablation")
    ap.add_argument("--no-append", action="store_true")
    args = ap.parse_args()
    args.cache = args.cache / f"asset_{appearance_digest()[:8]}"  # data and runs of other animals are not reused
    args.cache.mkdir(parents=True, exist_ok=True)
    log = args.cache / "log.txt"
    init = "" if args.init == "none" else str(ROOT / "zebra_sim_ros/detection/weights/zebra_yolo_n.pt") \
        if args.init == "shipped" else args.init
    held = heldout(args.cache, log)
    results_file = args.cache / "results.jsonl"
    done = {json.loads(ln)["row"]: json.loads(ln) for ln in results_file.read_text().splitlines()} \
        if results_file.exists() else {}
    wanted = [int(r) for r in args.rows.split(",")] if args.rows else list(range(1, len(ROWS) + 1))
    for k in wanted:
        name, gen, aug = ROWS[k - 1]
        if k in done:
            continue
        data = dataset(args.cache, gen, args.frames, args.seed, log)
        train_imgs = sum(1 for _ in (data.parent / "images" / "train").glob("*.jpg"))
        epochs = max(1, round(args.images / max(train_imgs, 1)))
        runs = args.cache / "runs" / f"row{k}"
        t0 = time.perf_counter()
        if not (runs / "last.pt").exists():
            run([*ZS, "train", "--data", str(data), "--imgsz", str(args.imgsz), "--epochs", str(epochs),
                 "--batch", str(args.batch), "--workers", "1", "--warmup-epochs", "0.5", "--close-mosaic", "0",
                 "--lr0", "0.005", "--seed", "0", "--val-every", str(epochs), "--out", str(runs),
                 *(["--init", init] if init else []), *aug], log)
        seconds = time.perf_counter() - t0
        weights = runs / "last.pt"
        real = {r["set"]: r for r in (score_set(str(weights), s, 0) for s in find_sets())}
        synth = val(weights, held)
        row = {"row": k, "name": name, "generate": gen, "aug": aug or "defaults", "train_images": train_imgs,
               "epochs": epochs, "train_seconds": round(seconds), "real": real,
               "heldout": {"mAP50": synth["mAP50"], "mAP50-95": synth["mAP50-95"]}}
        with open(results_file, "a", encoding="utf-8") as f:
            f.write(json.dumps(row) + "\n")
        done[k] = row
        print(f"row {k} {name}: {json.dumps({s: r['mAP50'] for s, r in real.items()})} held-out "
              f"{synth['mAP50']:.3f}", flush=True)
    sets = sorted({s for r in done.values() for s in r["real"]})
    lines = [f"`bench_ablation.py --frames {args.frames} --images {args.images} --imgsz {args.imgsz} --init "
             f"{args.init}` {dt.date.today().isoformat()}, {platform.processor() or platform.machine()}, "
             f"{os.cpu_count()} cores", "",
             "| row | " + " | ".join(f"{s} mAP50 / mAP50-95 (det/img on other species)" for s in sets)
             + " | held-out synthetic (default generate, seed 4242) mAP50 / mAP50-95 | train s |",
             "| --- | " + " | ".join("---" for _ in sets) + " | --- | --- |"]
    for k in sorted(done):
        r = done[k]
        cells = [f"{fmt3(r['real'][s]['mAP50'])} / {fmt3(r['real'][s]['mAP50-95'])} "
                 f"({fmt3(r['real'][s]['other_det_per_image'])})" if s in r["real"] else "" for s in sets]
        lines.append(f"| {k}. {r['name']} | " + " | ".join(cells)
                     + f" | {r['heldout']['mAP50']:.3f} / {r['heldout']['mAP50-95']:.3f} | {r['train_seconds']} |")
    print("\n".join(lines))
    if not args.no_append:
        with open(ROOT / "BENCHMARKS.md", "a", encoding="utf-8") as f:
            f.write("\n" + "\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
