"""Benchmark: how the detector finds REAL zebras (real photographs are for measuring only, never for training).

    python benchmarks/bench_real.py WEIGHTS [WEIGHTS ...] [--sets real/a real/b] [--imgsz 0 640] [--no-append]

``WEIGHTS``: checkpoints (``shipped``: the package's own). ``--sets``: folders laid out as ``scripts/real_sets/``
rebuilds them: ``images/``, ``labels/`` (YOLO, class 0 = zebra) and optionally ``other_species/`` (the other
animals' boxes, any class). Default: every such folder under ``real/`` and ``../shared/real/``.

For each weights, set and inference size (``0``: the checkpoint's rule, as ``zebra-sim val`` and the detector node
serve a frame; a number: the long side every photo is letterboxed to) it prints and appends to BENCHMARKS.md:

- mAP50 and mAP50-95 (COCO, conf 0.001) over the images that show zebras, and AP50 by box size (sqrt of area, px:
  COCO's small < 32, medium 32-96, large >= 96);
- precision and recall at IoU 0.5 at the detector's default threshold (conf 0.25);
- on the photos that show only other species: detections per image at conf 0.25, and the share of those
  detections that sit on another animal (IoU >= 0.5 with one of its boxes: zebras seen in a buffalo), and the
  share whose centre lies inside an animal's box (a box on part of an animal, or on a herd, counts here too);
  and the same by the species a photo shows (its ``other_species/`` classes; african_wildlife_dev: 0 buffalo,
  1 elephant, 2 rhino): photos, detections per photo, and those centred on an animal of that species;
- for weights with an ``other_animal`` class (``train --other-animals``): the share of those photos' animals it
  finds as other_animal (conf 0.25, IoU >= 0.5).
A set without photos of zebras (only other species) has no zebra figures, and one without photos of other species
no false-detection figures: they print as "-" (null in ``--json``), not as 0.

``--verifier`` (``shipped`` or a verifier checkpoint) rescores every weights' zebra boxes as the detector node's
``verifier`` parameter does; its rows name the weights "+ verifier".

``--bootstrap N`` also resamples each set's photos N times (those with zebras and those of other species each with
replacement; the draws depend only on the seed and the photo counts, so every weights is scored on the same draws):
95% intervals of mAP50 and of the false detections per photo of other species, and for each weights after the first
its paired difference from the first (median and 95% interval) on the same set and size.

The table's header names the date, the machine and each weights' sha256 (first 12 hex digits), and the
verifier's.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import torch

from zebra_sim_ros.detection.checkpoint import SHIPPED, file_sha256, load_model
from zebra_sim_ros.detection.data import image_size, label_path, read_labels
from zebra_sim_ros.detection.evaluate import ImagePredictions, make_loader, predictions_by_class
from zebra_sim_ros.detection.metrics import (
    ap_by_size,
    evaluate_detections,
    interval95,
    iou_matrix,
    match_images,
    paired_bootstrap,
    precision_recall_at,
)
from zebra_sim_ros.detection.model import OTHER_ANIMAL, ZEBRA
from zebra_sim_ros.detection.predict import inference_size
from zebra_sim_ros.detection.verify import SHIPPED_VERIFIER, Verifier, load_verifier, read_rgb, rescore

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_ROOTS = (ROOT / "real", ROOT.parent / "shared" / "real")
CONF = 0.25  # the detector node's default threshold


def find_sets(roots: tuple[Path, ...] = DEFAULT_ROOTS) -> list[Path]:
    """Every ``<root>/<name>/`` that holds ``images/`` and ``labels/``; a name found under several roots is taken
    from the first."""
    found: dict[str, Path] = {}
    for r in roots:
        for p in sorted(r.glob("*/images")) if r.is_dir() else []:
            if (p.parent / "labels").is_dir():
                found.setdefault(p.parent.name, p.parent)
    return [found[k] for k in sorted(found)]


def sha256_12(path: Path) -> str:
    return file_sha256(path)[:12]


def other_labels(p: ImagePredictions) -> np.ndarray:
    """The other species' boxes of an image (n, 5) [class, x0, y0, x1, y1] (its own pixels), from
    ``other_species/``."""
    f = Path(p.file)
    size = image_size(f)  # from the header; else decoded as the loader decodes it (Exif orientation applied)
    if size is None:
        img = cv2.imread(str(f), cv2.IMREAD_COLOR)
        if img is None:
            raise SystemExit(f"not a readable image: {f}")
        size = (img.shape[1], img.shape[0])
    w, h = size
    return read_labels(label_path(f, "other_species"), w, h).astype(np.float64)


def other_boxes(p: ImagePredictions) -> np.ndarray:
    """The other species' boxes of an image (xyxy, its own pixels), from ``other_species/``."""
    return other_labels(p)[:, 1:]


def _centred(d: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """(detections, boxes) bool: each detection's centre inside each box."""
    cx, cy = (d[:, 0] + d[:, 2]) / 2, (d[:, 1] + d[:, 3]) / 2
    return np.asarray((cx[:, None] >= boxes[None, :, 0]) & (cx[:, None] <= boxes[None, :, 2])
                      & (cy[:, None] >= boxes[None, :, 1]) & (cy[:, None] <= boxes[None, :, 3]))


def score_set(weights: str, folder: Path, imgsz: int, sweep: tuple[float, ...] = (), verifier: str = "",
              bootstrap: int = 0, seed: int = 0) -> dict[str, Any]:
    """One weights' row on one set at one size, with ``verifier`` ('' none, 'shipped' or a checkpoint)."""
    return score_sets(weights, folder, imgsz, sweep, (verifier,), bootstrap, seed)[0]


def verifier_label(verifier: str) -> str:
    """What a row's weights name says of its verifier: nothing, `` + verifier`` (the shipped one) or its path."""
    return "" if not verifier else " + verifier" if verifier == "shipped" else f" + verifier {verifier}"


def score_sets(weights: str, folder: Path, imgsz: int, sweep: tuple[float, ...] = (),
               verifiers: tuple[str, ...] = ("",), bootstrap: int = 0, seed: int = 0) -> list[dict[str, Any]]:
    """A row per verifier of ``verifiers`` for one weights on one set at one size: the detector runs once, and each
    verifier rescores its zebra boxes as ``predictions_by_class(..., verifier=)`` would (on the image files, the
    rows under its conf dropped); a row's time is the detector's and its verifier's."""
    model, _ = load_model(None if weights == "shipped" else weights, torch.device("cpu"))

    def rule(long_side: int) -> int:
        return inference_size(model.cfg, long_side, imgsz or None)

    other_class = model.cfg.names.index(OTHER_ANIMAL) if OTHER_ANIMAL in model.cfg.names else None
    classes = (ZEBRA,) if other_class is None else (ZEBRA, other_class)
    t0 = time.perf_counter()
    by_class = predictions_by_class(model, make_loader(folder / "images", rule, batch=4), classes, conf=DETECT_CONF)
    detected = time.perf_counter() - t0
    rows = []
    for verifier in verifiers:
        t0 = time.perf_counter()
        per = by_class[ZEBRA]
        if verifier:
            net = load_verifier(verifier, "cpu", "--verifier")[0]
            per = [_rescored(net, p) for p in per]
        rows.append(_row(weights + verifier_label(verifier), folder, imgsz, per, by_class, other_class,
                         detected + time.perf_counter() - t0, sweep, bootstrap, seed))
    return rows


DETECT_CONF = 0.001  # the detector's threshold for these figures (as val's): every box into AP


def _rescored(net: Verifier, p: ImagePredictions) -> ImagePredictions:
    """``p``'s detections rescored by ``net`` as ``predictions_by_class`` rescores them: in float32, the rows now
    under :data:`DETECT_CONF` dropped."""
    if not len(p.detections):
        return p
    d = rescore(net, read_rgb(p.file), p.detections.astype(np.float32), DETECT_CONF)
    return p._replace(detections=d.astype(np.float64))


def _row(name: str, folder: Path, imgsz: int, per: list[ImagePredictions],
         by_class: dict[int, list[ImagePredictions]], other_class: int | None, seconds: float,
         sweep: tuple[float, ...], bootstrap: int, seed: int) -> dict[str, Any]:
    """The figures of one row: ``per`` the zebra class's predictions (rescored or not), ``by_class`` every class's."""
    zebra = [p for p in per if len(p.labels)]
    others = [p for p in per if not len(p.labels)]
    dets, gts = [p.detections for p in zebra], [p.labels for p in zebra]
    m = evaluate_detections(dets, gts)
    prec, rec = precision_recall_at(dets, gts, CONF)
    sizes = ap_by_size(dets, gts)
    on_other = centre_on = n_other = 0
    found_other = n_animals = 0
    if other_class is not None and (folder / "other_species").is_dir():
        for p in by_class[other_class]:
            if len(p.labels):
                continue  # photos of other species only, as below
            d, ob = p.detections[p.detections[:, 4] >= CONF], other_boxes(p)
            n_animals += len(ob)
            if len(d) and len(ob):
                found_other += int((iou_matrix(ob, d[:, :4]).max(1) >= 0.5).sum())
    species: dict[int, list[int]] = {}  # other_species class: [photos showing it, detections on them, centred on it]
    for p in others:
        d = p.detections[p.detections[:, 4] >= CONF]
        n_other += len(d)
        lab = other_labels(p) if (folder / "other_species").is_dir() else np.zeros((0, 5))
        ob = lab[:, 1:]
        if len(d) and len(ob):
            on_other += int((iou_matrix(d[:, :4], ob).max(1) >= 0.5).sum())
            centre_on += int(_centred(d, ob).any(1).sum())
        for k in sorted(set(lab[:, 0].astype(int).tolist())):
            row = species.setdefault(k, [0, 0, 0])
            row[0] += 1
            row[1] += len(d)
            row[2] += int(_centred(d, lab[lab[:, 0] == k, 1:]).any(1).sum()) if len(d) else 0
    z = _if(bool(zebra))  # a set of other species only has no zebra figures, one of zebras only no false ones
    o = _if(bool(others))
    return {"weights": name, "set": folder.name, "imgsz": imgsz or "rule",
            "served": sorted({p.imgsz for p in per}), "zebra_images": len(zebra), "zebras": m.instances,
            "mAP50": z(round(m.map50, 4)), "mAP50-95": z(round(m.map50_95, 4)), "P@0.25": z(round(prec, 4)),
            "R@0.25": z(round(rec, 4)), "AP50_small": z(sizes["small"]["mAP50"]),
            "AP50_medium": z(sizes["medium"]["mAP50"]), "AP50_large": z(sizes["large"]["mAP50"]),
            "n_small/medium/large": [sizes[k]["instances"] for k in ("small", "medium", "large")],
            "other_images": len(others), "other_det_per_image": o(round(n_other / max(len(others), 1), 4)),
            "other_on_animal_share": o(round(on_other / max(n_other, 1), 4)),
            "other_centre_on_animal_share": o(round(centre_on / max(n_other, 1), 4)),
            "other_animal_recall": round(found_other / n_animals, 4) if n_animals else None,
            "other_by_class": {k: {"photos": n, "det_per_image": round(dn / n, 3), "centred_per_image": round(c / n, 3)}
                               for k, (n, dn, c) in sorted(species.items())},
            "ms_per_image": round(1000 * seconds / max(len(per), 1), 1),
            "sweep": [_operating_point(dets, gts, others, t) for t in sweep],
            "draws": _draws(dets, gts, others, bootstrap, seed) if bootstrap else None}


def _draws(dets: list[np.ndarray], gts: list[np.ndarray], others: list[ImagePredictions], samples: int,
           seed: int) -> dict[str, list[float] | None]:
    """mAP50 over ``samples`` resamples of the zebra photos, and false detections per photo (conf 0.25) over as many
    resamples of the other species' photos; the same draws for every weights scored on the set."""
    ap50 = (paired_bootstrap([match_images(dets, gts)], list(range(len(gts))), samples, seed, map50_only=True)[:, 0, 0]
            if gts else None)
    counts = np.array([int((p.detections[:, 4] >= CONF).sum()) for p in others], dtype=np.float64)
    rng = np.random.default_rng([seed, 1])
    fp = (np.array([counts[rng.integers(0, len(counts), len(counts))].mean() for _ in range(samples)])
          if len(counts) else None)
    return {"mAP50": None if ap50 is None else ap50.tolist(),
            "other_det_per_image": None if fp is None else fp.tolist(), "photos": [len(gts), len(others)]}


def summarise_draws(rows: list[dict[str, Any]], samples: int, seed: int) -> None:
    """Replace each row's draws by what the tables and ``--json`` give: 95% intervals and, after the first weights
    on the same set and size, the paired difference from it (median of the paired draws, 95% interval: key "<figure>
    minus first weights", the first weights' name under "first weights"). Draws are
    paired only over the same photos: rows whose photo counts differ from the first's get no difference."""
    first: dict[tuple[str, str], dict[str, Any]] = {}
    for r in rows:
        draws = r.pop("draws")
        base = first.setdefault((r["set"], str(r["imgsz"])), {**r, "draws": draws})
        out: dict[str, Any] = {"samples": samples, "seed": seed, "photos": draws["photos"]}
        for name in ("mAP50", "other_det_per_image"):
            x = draws[name]
            if x is None:
                continue
            out[f"{name} 95%"] = [round(v, 4) for v in interval95(np.asarray(x))]
            if base["weights"] != r["weights"] and base["draws"]["photos"] == draws["photos"]:
                d = np.asarray(x) - np.asarray(base["draws"][name])
                out["first weights"] = base["weights"]
                out[f"{name} minus first weights"] = {"median of paired draws": round(float(np.median(d)), 4),
                                                      "95%": [round(v, 4) for v in interval95(d)]}
        r["bootstrap"] = out


def bootstrap_table(rows: list[dict[str, Any]]) -> list[str]:
    """Each row's 95% intervals and, after the first weights, its paired difference from the first weights' row on
    the same set and size (:func:`summarise_draws`)."""
    b0 = rows[0]["bootstrap"]
    out = [f"{b0['samples']} resamples of each set's photos (seed {b0['seed']}), the same draws for every weights:", "",
           "| weights | set | imgsz | mAP50 95% | minus the first weights: median of paired draws (95%) | "
           "other det/photo 95% | minus the first weights: median of paired draws (95%) |",
           "| --- | --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        b = r["bootstrap"]
        cells = []
        for name in ("mAP50", "other_det_per_image"):
            iv = b.get(f"{name} 95%")
            cells.append("-" if iv is None else f"{iv[0]:.3f}-{iv[1]:.3f}")
            d = b.get(f"{name} minus first weights")
            cells.append("-" if d is None else f"{d['median of paired draws']:+.3f} ({d['95%'][0]:+.3f} to "
                         f"{d['95%'][1]:+.3f})")
        out.append(f"| {r['weights']} | {r['set']} | {r['imgsz']} | " + " | ".join(cells) + " |")
    return out


def _if(has: bool) -> Callable[[float], float | None]:
    """The figure itself where the photos it is about exist, else None (printed as "-")."""
    return lambda x: x if has else None


def fmt3(x: float | None) -> str:
    """A figure to three decimals, "-" where the set has none (None)."""
    return "-" if x is None else f"{x:.3f}"


def _operating_point(dets: list[np.ndarray], gts: list[np.ndarray], others: list[ImagePredictions],
                     conf: float) -> dict[str, float | None]:
    """Precision and recall on the zebra photos and detections per photo of other species, at threshold ``conf``."""
    prec, rec = precision_recall_at(dets, gts, conf)
    n = sum(int((p.detections[:, 4] >= conf).sum()) for p in others)
    z, o = _if(bool(gts)), _if(bool(others))
    return {"conf": conf, "P": z(round(prec, 4)), "R": z(round(rec, 4)),
            "other_det_per_image": o(round(n / max(len(others), 1), 4))}


def sweep_table(rows: list[dict[str, Any]]) -> list[str]:
    """Operating points (``--conf-sweep``): per weights and set, P / R on zebra photos and other-species detections
    per photo at each threshold."""
    confs = [pt["conf"] for pt in rows[0]["sweep"]]
    out = ["| weights | set | imgsz | " + " | ".join(f"conf {c:g}: P / R / other det per photo" for c in confs) + " |",
           "| --- | --- | --- | " + " | ".join("---" for _ in confs) + " |"]
    for r in rows:
        cells = " | ".join(f"{fmt3(pt['P'])} / {fmt3(pt['R'])} / {fmt3(pt['other_det_per_image'])}"
                           for pt in r["sweep"])
        out.append(f"| {r['weights']} | {r['set']} | {r['imgsz']} | {cells} |")
    return out


def table(rows: list[dict[str, Any]]) -> list[str]:
    out = ["| weights | set | imgsz | zebra images / boxes | mAP50 | mAP50-95 | P / R at 0.25 | AP50 small / medium / "
           "large (boxes) | other-species photos: det/img (on an animal: IoU >= 0.5 / centre inside) | found as "
           "other_animal | other-species photos by the species they show (other_species class: photos, det/img, "
           "of them centred on that species) | ms/img |",
           "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        n = r["n_small/medium/large"]
        sv = r["served"]
        served = str(sv[0]) if len(sv) == 1 else f"{sv[0]}-{sv[-1]}"
        out.append(f"| {r['weights']} | {r['set']} | {r['imgsz']} ({served}) | "
                   f"{r['zebra_images']} / {r['zebras']} | {fmt3(r['mAP50'])} | {fmt3(r['mAP50-95'])} | "
                   f"{fmt3(r['P@0.25'])} / {fmt3(r['R@0.25'])} | {fmt3(r['AP50_small'])} / {fmt3(r['AP50_medium'])} / "
                   f"{fmt3(r['AP50_large'])} ({n[0]}/{n[1]}/{n[2]}) | {fmt3(r['other_det_per_image'])}"
                   + ("" if r["other_on_animal_share"] is None else f" ({100 * r['other_on_animal_share']:.0f}% / "
                      f"{100 * r['other_centre_on_animal_share']:.0f}%)") + " | "
                   f"{'-' if r['other_animal_recall'] is None else format(r['other_animal_recall'], '.3f')} | "
                   f"{_by_class(r['other_by_class'])} | {r['ms_per_image']} |")
    return out


def _by_class(by: dict[int, dict[str, float]]) -> str:
    return "; ".join(f"{k}: {v['photos']}, {v['det_per_image']:.2f} ({v['centred_per_image']:.2f})"
                     for k, v in by.items()) or "-"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    ap.add_argument("weights", nargs="+", help="checkpoints ('shipped': the package's own)")
    ap.add_argument("--sets", nargs="*", type=Path, default=None, help="real set folders (default: all found)")
    ap.add_argument("--imgsz", nargs="+", type=int, default=[0], help="inference long sides (0: the checkpoint's "
                    "rule)")
    ap.add_argument("--conf-sweep", nargs="*", type=float, default=[], metavar="CONF",
                    help="also a table of operating points: P / R on the zebra photos and other-species detections "
                    "per photo at each of these thresholds")
    ap.add_argument("--verifier", nargs="+", default=[""], help="rescore the zebra boxes with this verifier "
                    "('shipped': the package's), as the detector node's verifier parameter does; several: each "
                    "weights scored with each in turn ('' or 'none': without one)")
    ap.add_argument("--bootstrap", type=int, default=0, help="resamples of each set's photos for 95%% intervals "
                    "and paired differences (0: none)")
    ap.add_argument("--bootstrap-seed", type=int, default=0)
    ap.add_argument("--no-append", action="store_true", help="do not append the table to BENCHMARKS.md")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    torch.set_num_threads(max(1, int(os.environ.get("OMP_NUM_THREADS", os.cpu_count() or 1))))
    sets = args.sets if args.sets is not None else find_sets()
    if not sets:
        raise SystemExit("no real sets found: run scripts/real_sets/*.sh first, or pass --sets")
    for s in sets:
        if not (s / "images").is_dir() or not (s / "labels").is_dir():
            raise SystemExit(f"--sets {s}: want a folder with images/ and labels/")
    bad = [c for c in args.conf_sweep if not 0.0 < c < 1.0]
    if bad:
        raise SystemExit(f"--conf-sweep {bad[0]}: want thresholds between 0 and 1")
    if args.bootstrap < 0:
        raise SystemExit(f"--bootstrap {args.bootstrap}: want 0 (none) or more")
    if args.bootstrap_seed < 0:
        raise SystemExit(f"--bootstrap-seed {args.bootstrap_seed}: want 0 or more")
    verifiers = ["" if v == "none" else v for v in args.verifier]
    by_key = {(w, s, n): score_sets(w, s, n, tuple(args.conf_sweep), tuple(verifiers), args.bootstrap,
                                    args.bootstrap_seed) for w in args.weights for s in sets for n in args.imgsz}
    rows = [by_key[(w, s, n)][k] for w in args.weights for k in range(len(verifiers)) for s in sets
            for n in args.imgsz]  # a weights' rows with its first verifier, then its second ...
    machine = f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores"
    digests = ", ".join(f"{w} {sha256_12(SHIPPED if w == 'shipped' else Path(w))}" for w in args.weights)
    for name in (v for v in verifiers if v):
        digests += f"; verifier {name} {sha256_12(SHIPPED_VERIFIER if name == 'shipped' else Path(name))}"
    head = f"`bench_real.py` {dt.date.today().isoformat()}, {machine}; weights sha256: {digests}"
    lines = [head, "", *table(rows)] + (["", *sweep_table(rows)] if args.conf_sweep else [])
    if args.bootstrap:
        summarise_draws(rows, args.bootstrap, args.bootstrap_seed)
        lines += ["", *bootstrap_table(rows)]
    else:
        for r in rows:
            r.pop("draws")
    print("\n".join(lines))
    if args.json:
        print(json.dumps(rows))
    if not args.no_append:
        with open(ROOT / "BENCHMARKS.md", "a", encoding="utf-8") as f:
            f.write("\n" + "\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
