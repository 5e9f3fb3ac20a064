"""Benchmark: one training sample of ``train --crop`` drawn whole and then cut, against drawing only its window.

The data loader of a crop run builds each augmented ``--imgsz`` sample (mosaic, zoom or single frame, random
scale and translation, flip) and keeps a ``--crop`` window around a zebra. Drawing the whole sample costs its
full warp (at 2176 px: 4.7 M pixels, to keep 0.1 M); :class:`~zebra_sim_ros.detection.data._Sample` warps only
the window. A mosaic's window can be cut from its whole 2 x imgsz canvas of four resized frames, or drawn tile
by tile from the frames it shows (:class:`~zebra_sim_ros.detection.data._MosaicSample`, which decodes no other).
Three arms run here on the same set, the same indices and seeds, interleaved in rounds: ``whole`` (the whole
sample, then cut), ``canvas`` (the window of the whole mosaic canvas) and ``window`` (today's loader). The report
is the median ms per sample of each arm and their ratios, and checks that all gave the same labels.

    python benchmarks/bench_loader.py DATASET_FOLDER_OR_YAML [--imgsz 2176] [--crop 320] [--samples 48]
        [--rounds 5] [--json]
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import time
from typing import Any

import numpy as np

from zebra_sim_ros.detection.data import Augment, YoloDataset, _MosaicSample, _Sample, resolve_split


def _whole_then_cut(self: _Sample, x0: int, y0: int, side: int) -> np.ndarray:
    """The former way: warp the whole sample, then slice the window (padded beyond the sample)."""
    full = self.full()
    out = np.full((side, side, 3), 114, np.uint8)
    part = full[y0:y0 + side, x0:x0 + side]
    out[:part.shape[0], :part.shape[1]] = part
    return out


def _canvas_then_window(self: _MosaicSample, x0: int, y0: int, side: int) -> np.ndarray:
    """The way before tile by tile: the whole mosaic canvas (every frame decoded and resized), then the window."""
    self.full()  # draws the canvas into self.src (and warps it, which this arm does not need: a little extra)
    return _Sample.window(self, x0, y0, side)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data", help="a dataset.yaml (its train split) or a folder of images")
    ap.add_argument("--imgsz", type=int, default=2176)
    ap.add_argument("--crop", type=int, default=320)
    ap.add_argument("--aug-zoom", type=float, default=0.5)
    ap.add_argument("--samples", type=int, default=48)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    folder = resolve_split(args.data, "train") if str(args.data).endswith((".yaml", ".yml")) else args.data
    ds = YoloDataset(folder, args.imgsz, Augment(zoom=args.aug_zoom), seed=0, dont_care=True, crop=args.crop)
    idx = np.linspace(0, len(ds) - 1, min(args.samples, len(ds))).round().astype(int)
    window, mosaic_window = _Sample.window, _MosaicSample.window
    arms = {"whole": (_whole_then_cut, _whole_then_cut), "canvas": (window, _canvas_then_window),
            "window": (window, mosaic_window)}
    times: dict[str, list[float]] = {k: [] for k in arms}
    labels: dict[str, list[np.ndarray]] = {k: [] for k in arms}
    order = list(arms)
    for r in range(args.rounds):
        for arm in order[r % 3:] + order[:r % 3]:
            _Sample.window, _MosaicSample.window = arms[arm]  # type: ignore[method-assign]
            t0 = time.perf_counter()
            got = [ds[int(i)][1].numpy() for i in idx]
            times[arm].append(1000 * (time.perf_counter() - t0) / len(idx))
            if r == 0:
                labels[arm] = got
    _Sample.window, _MosaicSample.window = window, mosaic_window  # type: ignore[method-assign]
    same = all(a.shape == b.shape and np.allclose(a, b, atol=1e-4) for arm in ("canvas", "window")
               for a, b in zip(labels["whole"], labels[arm], strict=True))
    med = {k: statistics.median(v) for k, v in times.items()}
    res: dict[str, Any] = {"data": str(folder), "imgsz": args.imgsz, "crop": args.crop, "aug_zoom": args.aug_zoom,
                           "samples": len(idx), "rounds": args.rounds,
                           **{f"ms_per_sample_{k}": round(v, 1) for k, v in med.items()},
                           "window_over_whole": round(med["whole"] / med["window"], 2),
                           "window_over_canvas": round(med["canvas"] / med["window"], 2), "same_labels": same,
                           "machine": f"{platform.machine()}, {platform.processor() or 'cpu'}"}
    print(f"{len(idx)} samples at {args.imgsz} px, crops of {args.crop}, median of {args.rounds} rounds: whole "
          f"then cut {med['whole']:.1f} ms/sample, window of the whole mosaic canvas {med['canvas']:.1f}, window "
          f"only {med['window']:.1f} ({res['window_over_whole']:.2f}x and {res['window_over_canvas']:.2f}x); "
          f"same labels: {same}")
    if args.json:
        print(json.dumps(res))


if __name__ == "__main__":
    main()
