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
import os
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
    ap.add_argument("--max-mib", type=float, default=62.0,
                    help="refuse a pack that would make the tree that travels larger than this: the repository's "
                         "files that git does not ignore, the pack and anything else in --out, as allocated on disk "
                         "(the GPU machine takes 64 MiB in all; the default leaves 2 MiB for carried checkpoints)")
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
    mib = total / 2**20
    written = [p for p in a.out.rglob("*") if p.is_file()]
    in_pack = [p.relative_to(a.out).parts[0] in ("train", "val") for p in written]
    pack = _disk_bytes(p for p, ours in zip(written, in_pack, strict=True) if ours) / 2**20
    rest = _disk_bytes(p for p, ours in zip(written, in_pack, strict=True) if not ours) / 2**20
    repo = _repository_files()
    here = _disk_bytes(repo or []) / 2**20
    tree = pack + rest + here
    print(f"pack: {len(frames)} training and {len(val)} validation frames, {mib:.1f} MiB in {a.out}; the tree that "
          f"travels with it, on disk: {tree:.1f} MiB (the pack {pack:.1f}, other files in {a.out} {rest:.1f}, "
          + (f"the repository {here:.1f})" if repo is not None else "the repository not counted: git could not list "
             "its files)"))
    if tree > a.max_mib:
        raise SystemExit(f"pack: the tree with the pack is {tree:.1f} MiB on disk, over --max-mib {a.max_mib}: it "
                         "would not travel (a lower --quality, --thin or --keep-every makes the pack smaller; "
                         f"other files in {a.out} travel too)")


def _repository_files() -> list[Path] | None:
    """The repository's files that travel with the pack (tracked, and untracked ones git does not ignore); None where
    git cannot list them."""
    root = Path(__file__).resolve().parents[2]
    try:
        r = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=root,
                           capture_output=True, check=False, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return None
    return [root / os.fsdecode(f) for f in r.stdout.split(b"\0") if f] if r.returncode == 0 else None


def _disk_bytes(paths: Iterable[Path]) -> int:
    """What files take on disk, as allocated (st_blocks counts 512-byte units), which is what the GPU machine's limit
    was seen to count: a pack of 48.0 MiB (53.7 MiB on disk) beside 13.2 MiB of tracked files (13.7 on disk) was
    refused on 2026-11-28, 61.2 MiB in bytes but 67.4 MiB on disk."""
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
