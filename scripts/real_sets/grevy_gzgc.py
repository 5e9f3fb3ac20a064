"""Rebuild the real set ``real/grevy_gzgc/`` (measuring only: never training data, never in git).

Source: github:aj19081/grevy-zebra-identification-with-keypoints, commit
bd0c3f1884a9ed54a89c140f96eb405df7e50e54 (2024-05-07), folder ``data/zebra`` (YOLO labels: 0 grevy-zebra,
1 great-zebra, i.e. plains zebra, 2 giraffe).
License: the repository states none. Its photographs appear to come from the Great Zebra and Giraffe Count
(GZGC, on LILA, CDLA-Permissive-1.0; file names 0000000000NN.jpg) and from Wild Me's Grevy's zebra
identification photos (uuid names). We use them only to measure, do not redistribute them, and keep them out of
git (``real/`` is ignored).
What it holds: ground-level field photographs, 3000-4608 px wide. The train and val folders repeat some files;
each file name is kept once. Images are resized to a long side of 1280 px (INTER_AREA; YOLO labels are
normalised and unchanged) so that serving sizes are those of our cameras.

Layout written: ``images/*.jpg``, ``labels/*.txt`` (class 0 = zebra: both zebra species), ``other_species/*.txt``
(giraffes, class 0 = giraffe), ``SOURCE.txt``.

    python scripts/real_sets/grevy_gzgc.py GIT_DIR [--out real/grevy_gzgc]

``GIT_DIR``: a clone or bare mirror of the repository holding that commit.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import fresh_set, git, label_rows  # noqa: E402  (shared by these scripts)

COMMIT = "bd0c3f1884a9ed54a89c140f96eb405df7e50e54"
ZEBRA_CLASSES = {0, 1}
OTHER = {2: 0}  # giraffe
LONG_SIDE = 1280


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    ap.add_argument("git_dir", type=Path)
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[2] / "real" / "grevy_gzgc")
    args = ap.parse_args()
    names = git(args.git_dir, "ls-tree", "-r", "--name-only", COMMIT, "data/zebra/images").decode().split("\n")
    images = sorted({Path(n).name: n for n in names if n.lower().endswith((".jpg", ".jpeg", ".png"))}.items())
    fresh_set(args.out)
    kept = boxes = others = missing = 0
    for name, path in images:
        try:
            rows = label_rows(args.git_dir, COMMIT, path)
        except subprocess.CalledProcessError:
            continue  # an image without a label file is not annotated: left out
        try:
            data = git(args.git_dir, "show", f"{COMMIT}:{path}")
        except subprocess.CalledProcessError:
            missing += 1  # a partial mirror may lack its largest files
            continue
        img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
        if img is None:
            raise SystemExit(f"{path} at {COMMIT} is not a readable image")
        r = LONG_SIDE / max(img.shape[:2])
        if r < 1:
            img = cv2.resize(img, (round(img.shape[1] * r), round(img.shape[0] * r)), interpolation=cv2.INTER_AREA)
        stem = Path(name).stem
        cv2.imwrite(str(args.out / "images" / f"{stem}.jpg"), img, [cv2.IMWRITE_JPEG_QUALITY, 95])
        zebra = [" ".join(["0", *r_[1:5]]) for r_ in rows if int(r_[0]) in ZEBRA_CLASSES]
        other = [" ".join([str(OTHER[int(r_[0])]), *r_[1:5]]) for r_ in rows if int(r_[0]) in OTHER]
        (args.out / "labels" / f"{stem}.txt").write_text("".join(z + "\n" for z in zebra))
        (args.out / "other_species" / f"{stem}.txt").write_text("".join(o + "\n" for o in other))
        kept += 1
        boxes += len(zebra)
        others += len(other)
    (args.out / "SOURCE.txt").write_text(f"github:aj19081/grevy-zebra-identification-with-keypoints@{COMMIT} "
                                         "data/zebra; no license stated (see scripts/real_sets/grevy_gzgc.py)\n")
    print(f"wrote {args.out}: {kept} images, {boxes} zebra boxes, {others} giraffe boxes"
          + (f"; {missing} images absent from {args.git_dir} were left out" if missing else ""))


if __name__ == "__main__":
    main()
