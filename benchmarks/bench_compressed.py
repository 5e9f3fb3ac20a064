"""Benchmark: what the camera's ``image_raw/compressed`` costs and saves, on the frames a default camera renders.

Renders ``--steps`` steps of the default world with the default placer and the camera node's default settings
(photographic look, the per-frame camera model with its noise, 1280x720), three drones each, and for every view
encodes the RGB image as the camera node does (``recording.images.compress_rgb``: png, jpeg at 90 and at 75) and
decodes it as the detector does (``decompress_rgb``). Reports per format the median bytes per frame and their ratio
to the raw rgb8 image, the median encode and decode milliseconds and their ratio to the same view's render time
(measured in the same run), and the jpeg's PSNR against the raw image.

    python benchmarks/bench_compressed.py [--steps 6] [--json]
    python benchmarks/bench_compressed.py --val DATASET [--split train] [--bootstrap 1000] [--json]

``--val``: what the compression costs the shipped detector. Every image of a generated set (``zebra-sim generate``
writes jpeg 95) is decoded and encoded again at jpeg 90 and at jpeg 75 (the camera node would encode its raw image
once: this is a little harsher), and ``val`` (the shipped weights, the default serving rule) scores the set as
written and each copy; with the mAP50 differences' 95% intervals over placements resampled, paired.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import statistics
import time
from typing import Any

import numpy as np

from zebra_sim_ros.placement.config import PlacerConfig
from zebra_sim_ros.placement.placer import Placer
from zebra_sim_ros.recording.images import PNG_LEVEL, compress_rgb, decompress_rgb
from zebra_sim_ros.rendering.config import CameraConfig
from zebra_sim_ros.simulation import Simulator
from zebra_sim_ros.world.world import load_world
from zebra_sim_ros.zebra.asset import load_library

FORMATS = (("png", 0), ("jpeg", 90), ("jpeg", 75))


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return math.inf if mse == 0 else 10 * math.log10(255.0**2 / mse)


def val_costs(dataset: str, split: str, samples: int) -> dict[str, Any]:
    """mAP50 / mAP50-95 of the shipped weights on ``dataset``'s ``split`` as written and re-encoded at jpeg 90 and
    75, and the paired differences' intervals (see the module's docstring)."""
    import tempfile
    from pathlib import Path

    import cv2

    from zebra_sim_ros.detection.data import resolve_split
    from zebra_sim_ros.detection.evaluate import evaluate, matched, placement
    from zebra_sim_ros.detection.metrics import interval95, paired_bootstrap

    folder = resolve_split(dataset, split)
    root = folder.parent.parent
    out: dict[str, Any] = {"data": str(folder), "runs": {}}
    runs, names = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for quality in (0, 90, 75):
            if quality:
                copy = Path(tmp) / f"q{quality}"
                (copy / "images" / folder.name).mkdir(parents=True)  # labels are found under labels/<its name>
                for sub in ("labels", "ignore"):
                    if (root / sub).is_dir():
                        (copy / sub).symlink_to((root / sub).resolve())
                for f in sorted(p for p in folder.iterdir() if p.suffix.lower() in (".jpg", ".jpeg", ".png")):
                    bgr = cv2.imread(str(f), cv2.IMREAD_COLOR)
                    if bgr is None:
                        raise SystemExit(f"cannot read {f}")
                    _, data = compress_rgb(np.ascontiguousarray(bgr[..., ::-1]), "jpeg", quality)
                    (copy / "images" / folder.name / f"{f.stem}.jpg").write_bytes(data)
                where = copy / "images" / folder.name
            else:
                where = folder
            m, facts = evaluate(None, where, split)
            name = f"jpeg {quality}" if quality else "as written"
            names.append(name)
            runs.append(facts["per_image"])
            out["runs"][name] = {"mAP50": round(m.map50, 4), "mAP50-95": round(m.map50_95, 4),
                                 "images": m.images, "seconds": facts["seconds"]}
    stems = [[Path(p.file).stem for p in r] for r in runs]
    if any(s != stems[0] for s in stems):
        raise SystemExit("the copies' images do not pair with the set's, image by image")
    groups = [placement(p.file) for p in runs[0]]
    ap = paired_bootstrap([matched(r) for r in runs], groups, samples, 0)
    for k, name in enumerate(names[1:], 1):
        out["runs"][name]["mAP50 minus as written, 95%"] = [round(x, 4)
                                                            for x in interval95(ap[:, k, 0] - ap[:, 0, 0])]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=6)
    ap.add_argument("--val", default="", help="a generated set: score the shipped detector on it re-encoded")
    ap.add_argument("--split", default="train")
    ap.add_argument("--bootstrap", type=int, default=1000)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    if args.val:
        result = val_costs(args.val, args.split, args.bootstrap)
        print(json.dumps(result, indent=1))
        return
    pc, cc = PlacerConfig(), CameraConfig()
    world = load_world(pc.world, pc.terrain_prim, pc.world_seed)
    lib = load_library()
    placer = Placer(pc, world, lib)
    sim = Simulator(world, lib, cc.render_options(), sensor=cc.sensor_model())
    names = placer.camera_names
    render_ms: list[float] = []
    rows: dict[str, dict[str, list[float]]] = {f"{k} {q}" if q else k: {"bytes": [], "enc": [], "dec": [],
                                                                         "psnr": []} for k, q in FORMATS}
    raw_bytes = 0
    for step in range(args.steps):
        scene = placer.scene(step)
        sim.render(scene, names[:1])  # warm: this step's coats are baked before timing
        for name in names:
            t0 = time.perf_counter()
            view = sim.render(scene, [name])[0]
            render_ms.append((time.perf_counter() - t0) * 1e3)
            rgb = view.rgb
            raw_bytes = rgb.nbytes
            for kind, q in FORMATS:
                r = rows[f"{kind} {q}" if q else kind]
                t0 = time.perf_counter()
                fmt, data = compress_rgb(rgb, kind, q or 90)
                t1 = time.perf_counter()
                back = decompress_rgb(fmt, data)
                t2 = time.perf_counter()
                r["bytes"].append(len(data))
                r["enc"].append((t1 - t0) * 1e3)
                r["dec"].append((t2 - t1) * 1e3)
                r["psnr"].append(psnr(back, rgb))
    sim.release()
    med_render = statistics.median(render_ms)
    out: dict[str, Any] = {"date": time.strftime("%Y-%m-%d"), "machine": f"{platform.processor() or platform.machine()}"
                           f", {os.cpu_count()} cores", "frames": len(render_ms),
                           "size": f"{cc.width}x{cc.height}", "raw_bytes": raw_bytes, "png_level": PNG_LEVEL,
                           "render_ms_median": round(med_render, 1), "formats": {}}
    for key, r in rows.items():
        enc = [e / m for e, m in zip(r["enc"], render_ms, strict=True)]
        out["formats"][key] = {
            "bytes_median": int(statistics.median(r["bytes"])),
            "of_raw": round(statistics.median(r["bytes"]) / raw_bytes, 4),
            "encode_ms_median": round(statistics.median(r["enc"]), 2),
            "decode_ms_median": round(statistics.median(r["dec"]), 2),
            "encode_over_render_median": round(statistics.median(enc), 4),
            "psnr_db_median": round(statistics.median(r["psnr"]), 2) if key != "png" else "lossless",
        }
    if args.json:
        print(json.dumps(out, indent=1))
        return
    print(f"{out['frames']} views at {out['size']} ({raw_bytes} bytes raw), render median {med_render:.1f} ms")
    print("| format | bytes (median) | of raw | encode ms | decode ms | encode / render | PSNR dB |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for key, f in out["formats"].items():
        print(f"| {key} | {f['bytes_median']} | {f['of_raw']:.3f} | {f['encode_ms_median']} | "
              f"{f['decode_ms_median']} | {f['encode_over_render_median']:.3f} | {f['psnr_db_median']} |")


if __name__ == "__main__":
    main()
