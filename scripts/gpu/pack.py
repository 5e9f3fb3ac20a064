"""Pack generated frames into ``gpu_data/`` (git-ignored), small enough to travel to a lent GPU machine with the
repository (its working tree may hold 64 MiB in all): each training frame re-encoded as JPEG at ``--quality``,
with its labels and don't-care boxes, a few validation frames for the run's last-epoch check, and the generated
sets' settings (``generate.json``: one set's copied, several sets' gathered) so that checkpoints record them.
``scripts/gpu/train.sh`` then trains on it there.

Stage 12 (README, "Shipped weights")::

    python scripts/gpu/pack.py --train datasets/sav_6001/images/train datasets/sav_6001/images/val \\
        datasets/sav_6000/images/train --drop-every datasets/sav_6000/images/train=4 \\
        --val datasets/sav_6000/images/val --val-frames 8      # 504 frames, 50.0 MiB (run a)
    python scripts/gpu/pack.py ... --thin 8                    # the same less every 8th: 441 frames (run b)
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
from collections.abc import Iterable
from pathlib import Path

import cv2

from zebra_sim_ros.detection.data import generate_config, label_path


def _copy_frame(image: Path, out: Path, split: str, quality: int) -> int:
    """Re-encode one frame into ``out/images/<split>/`` with its label files; returns the JPEG's bytes."""
    img = cv2.imread(str(image), cv2.IMREAD_COLOR)
    if img is None:
        raise SystemExit(f"pack: {image} is not a readable image")
    ok, data = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise SystemExit(f"pack: {image} could not be encoded as JPEG at quality {quality}")
    dst = out / "images" / split / (image.stem + ".jpg")
    dst.parent.mkdir(parents=True, exist_ok=True)
    dst.write_bytes(data.tobytes())
    for folder in ("labels", "ignore"):
        src = label_path(image, folder)
        if src.exists():
            d = out / folder / split / src.name
            d.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy(src, d)
    return len(data)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--train", type=Path, nargs="+", required=True, help="image folders of generated sets")
    ap.add_argument("--drop-every", action="append", default=[], metavar="FOLDER=N",
                    help="leave out every N-th frame (the 1st, N+1-th, ...) of this --train folder, sorted by name")
    ap.add_argument("--keep-every", action="append", default=[], metavar="FOLDER=N",
                    help="keep only every N-th frame (the 1st, N+1-th, ...) of this --train folder, sorted by name")
    ap.add_argument("--thin", type=int, default=0, help="then leave out every N-th of all training frames (0: none)")
    ap.add_argument("--val", type=Path, required=True, help="image folder of the validation frames")
    ap.add_argument("--val-frames", type=int, default=8, help="the first N of --val, by name")
    ap.add_argument("--quality", type=int, default=77, help="JPEG quality of the training frames")
    ap.add_argument("--val-quality", type=int, default=80, help="JPEG quality of the validation frames")
    ap.add_argument("--out", type=Path, default=Path("gpu_data"))
    ap.add_argument("--max-mib", type=float, default=64.0,
                    help="refuse a pack that would make the tree that travels (the repository's tracked files and the "
                         "pack, as they lie on disk: whole 4 KiB blocks) larger than this")
    a = ap.parse_args()
    if a.thin == 1 or a.thin < 0:
        raise SystemExit(f"pack: --thin {a.thin}: want 0 (none) or N >= 2")
    for name, q in (("--quality", a.quality), ("--val-quality", a.val_quality)):
        if not 1 <= q <= 100:
            raise SystemExit(f"pack: {name} {q}: want a JPEG quality of 1..100")
    drop = _every("--drop-every", a.drop_every)
    keep = _every("--keep-every", a.keep_every)
    if both := sorted(map(str, set(drop) & set(keep))):
        raise SystemExit(f"pack: {', '.join(both)}: given both --drop-every and --keep-every; want one")
    frames: list[Path] = []
    for folder in a.train:
        found = sorted(folder.glob("*.jpg")) + sorted(folder.glob("*.png"))
        if not found:
            raise SystemExit(f"pack: --train {folder} holds no .jpg or .png frames")
        n = drop.get(folder, 0)
        m = keep.get(folder, 1)
        frames += [f for k, f in enumerate(found) if (not n or k % n) and k % m == 0]
    frames.sort(key=lambda p: p.name)
    if a.thin:
        frames = [f for k, f in enumerate(frames) if k % a.thin]
    val = sorted(a.val.glob("*.jpg"))[: a.val_frames]
    for sub in ("train", "val"):
        shutil.rmtree(a.out / sub, ignore_errors=True)
    total = sum(_copy_frame(f, a.out / "train", "train", a.quality) for f in frames)
    total += sum(_copy_frame(f, a.out / "val", "val", a.val_quality) for f in val)
    _record_generators(a.train, a.out / "train" / "generate.json")
    mib, tree = total / 2**20, (_disk_bytes(a.out.rglob("*")) + _disk_bytes(_tracked())) / 2**20
    print(f"pack: {len(frames)} training and {len(val)} validation frames, {mib:.1f} MiB in {a.out}; "
          f"the tree that travels with it: {tree:.1f} MiB on disk")
    if tree > a.max_mib:
        raise SystemExit(f"pack: the tree with the pack is {tree:.1f} MiB on disk, over --max-mib {a.max_mib}: it "
                         "would not travel (a lower --quality, --thin or --keep-every makes it smaller)")


def _tracked() -> list[Path]:
    """The repository's tracked files (they travel with the pack); none where git cannot list them."""
    root = Path(__file__).resolve().parents[2]
    r = subprocess.run(["git", "ls-files", "-z"], cwd=root, capture_output=True, check=False)
    return [root / f for f in r.stdout.decode().split("\0") if f] if r.returncode == 0 else []


def _disk_bytes(paths: Iterable[Path]) -> int:
    """What files take on disk, in whole blocks: a 64 MiB tree of 48 MiB of frames and 13 MiB of tracked files was
    refused on 2026-11-28, when its blocks came to 67 MiB."""
    return sum(p.stat().st_blocks * 512 for p in paths if p.is_file())


def _every(option: str, items: list[str]) -> dict[Path, int]:
    """``FOLDER=N`` items of a per-folder option as {folder: N}, N a whole number >= 2."""
    out = {}
    for item in items:
        folder, _, n = item.partition("=")
        if not n.isdigit() or int(n) < 2:
            raise SystemExit(f"pack: {option} {item!r}: want FOLDER=N with N >= 2")
        out[Path(folder)] = int(n)
    return out


def _record_generators(folders: list[Path], out: Path) -> None:
    """What the packed frames were generated with, for the checkpoints trained on them: one set's
    ``generate.json`` as it is; several sets' settings as ``{"config": {"sets": {root: settings}}}``, the shape a
    checkpoint records for a dataset.yaml listing several sets. Folders without a ``generate.json`` add nothing."""
    found: dict[str, dict[str, object]] = {}
    for folder in folders:
        root = folder.parent.parent
        cfg = generate_config(root)
        if cfg:
            found.setdefault(str(root), cfg)
    if len(found) == 1:
        shutil.copy(Path(next(iter(found))) / "generate.json", out)
    elif found:
        out.write_text(json.dumps({"config": {"sets": found}, "packed_by": "scripts/gpu/pack.py"}, indent=1))


if __name__ == "__main__":
    main()
