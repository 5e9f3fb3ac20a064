"""Rebuild the real set ``real/african_wildlife_dev/`` (measuring only: never training data, never in git).

Source: github:EricJakovac/Animals, commit 676be7122cb9b9fa8f86367621da2a5e1c8d692c, the TRAIN split of
``datasets/african-wildlife`` (a copy of the "African Wildlife" detection set published with ultralytics; classes
0 buffalo, 1 elephant, 2 rhino, 3 zebra). License: AGPL-3.0 (the ultralytics dataset's). The test and valid
splits of that repository are held back, unused, to check that figures generalise to images nobody tuned on.
What it holds: 400 ground-level photographs listed in ``african_wildlife_dev.txt`` beside this script, 200 that
show zebras (436 zebra boxes) and 200 that show only buffalo, elephant or rhino, spread through the split's file
names. Files are copied byte for byte.

Layout written: ``images/train_<name>.jpg`` (the source name with every character but letters and digits turned
into ``_``), ``labels/*.txt`` (class 0 = zebra), ``other_species/*.txt`` (the other animals' boxes in the source
classes 0-2), ``data.yaml``, ``SOURCE.txt``.

    python scripts/real_sets/african_wildlife_dev.py GIT_DIR [--out real/african_wildlife_dev]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from common import fresh_set, git, label_rows, local_name  # scripts/real_sets/common.py

COMMIT = "676be7122cb9b9fa8f86367621da2a5e1c8d692c"
ZEBRA = "3"
HERE = Path(__file__).resolve().parent


def copy_photo(git_dir: Path, src: str, out: Path, name: str) -> int:
    """Copy the photo ``src`` (a path in the repository at COMMIT) to ``out/images/<name>``, its zebra boxes to
    ``labels/`` (class 0) and the other animals' to ``other_species/``; returns its number of zebras."""
    (out / "images" / f"{name}{Path(src).suffix.lower()}").write_bytes(git(git_dir, "show", f"{COMMIT}:{src}"))
    rows = label_rows(git_dir, COMMIT, src)
    zebra = [" ".join(["0", *r[1:5]]) for r in rows if r[0] == ZEBRA]
    other = [" ".join(r[:5]) for r in rows if r[0] != ZEBRA]
    (out / "labels" / f"{name}.txt").write_text("".join(z + "\n" for z in zebra))
    (out / "other_species" / f"{name}.txt").write_text("".join(o + "\n" for o in other))
    return len(zebra)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    ap.add_argument("git_dir", type=Path)
    ap.add_argument("--out", type=Path, default=HERE.parents[1] / "real" / "african_wildlife_dev")
    args = ap.parse_args()
    sources = [s for s in (HERE / "african_wildlife_dev.txt").read_text().splitlines() if s.strip()]
    write_set(args.git_dir, [(src, local_name("train", src)) for src in sources], args.out,
              "# real photographs for measuring only (never training)",
              "datasets/african-wildlife/train (AGPL-3.0); see scripts/real_sets/african_wildlife_dev.py")


def write_set(git_dir: Path, photos: list[tuple[str, str]], out: Path, yaml_comment: str, source: str) -> None:
    """``out`` written anew: each (repository path, local name) of ``photos`` by :func:`copy_photo`, a data.yaml
    headed by ``yaml_comment`` and a SOURCE.txt naming the repository, the commit and ``source``."""
    fresh_set(out)
    zebra_images = zebra_boxes = 0
    for src, name in photos:
        n = copy_photo(git_dir, src, out, name)
        zebra_images += bool(n)
        zebra_boxes += n
    (out / "data.yaml").write_text(f"{yaml_comment}\npath: .\ntrain: images\nval: images\nnames:\n  0: zebra\n")
    (out / "SOURCE.txt").write_text(f"github:EricJakovac/Animals@{COMMIT} {source}\n")
    print(f"wrote {out}: {len(photos)} images, {zebra_images} with zebras, {zebra_boxes} zebra boxes")


if __name__ == "__main__":
    main()
