"""Rebuild the HELD-BACK real set ``real_heldback/zebra_detection/`` (measuring only, and rarely).

Source: github:Insohamdas/Zebra_detection, commit 435de4fad6eb16a260d19f1038d63df5d269c067 (2025), folder
``datasets/{train,valid,test}``: the Roboflow Universe export "Zebra v1" (sushanth-raj/zebra-3cn5k, 2024-10-05;
one class, 0 = zebra; every image fitted within 640x640, no augmentation). License: CC BY 4.0, as its
``Zebra.v1i.yolov8/README.dataset.txt`` states; credit: the Roboflow user sushanth-raj.
Why held back: the issue keeps this repository out of everything that chooses weights or rules, to check that the
figures generalise to images nobody tuned on. It lives outside ``real/`` so that ``bench_real.py`` never scores it
unless named with ``--sets``; score it seldom and say so when you do. It holds zebras only: no photo of another
species, so it measures finding zebras, not false detections on other animals (``other_species/`` is empty).
Every image of the three splits is written, files byte for byte.

Layout written: ``images/<split>_<name>.jpg`` (the source name with every character but letters and digits turned
into ``_``), ``labels/*.txt`` (class 0 = zebra), ``other_species/`` (empty), ``data.yaml``, ``SOURCE.txt``.

    python scripts/real_sets/zebra_detection_heldback.py GIT_DIR [--out real_heldback/zebra_detection]

``GIT_DIR``: a clone or bare mirror of the repository holding that commit.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import export_images, fresh_set, git, label_rows, local_name  # noqa: E402  (shared by these scripts)

COMMIT = "435de4fad6eb16a260d19f1038d63df5d269c067"
ROOT = "datasets"
SPLITS = ("train", "valid", "test")
ZEBRA = "0"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    ap.add_argument("git_dir", type=Path)
    ap.add_argument("--out", type=Path,
                    default=Path(__file__).resolve().parents[2] / "real_heldback" / "zebra_detection")
    args = ap.parse_args()
    sources = export_images(args.git_dir, COMMIT, ROOT, SPLITS)
    fresh_set(args.out)
    zebra_images = boxes = 0
    for src in sources:
        split = src.split("/")[1]
        name = local_name(split, src)
        rows = label_rows(args.git_dir, COMMIT, src, only_class=ZEBRA)
        (args.out / "images" / f"{name}{Path(src).suffix.lower()}").write_bytes(
            git(args.git_dir, "show", f"{COMMIT}:{src}"))
        (args.out / "labels" / f"{name}.txt").write_text("".join(" ".join(r) + "\n" for r in rows))
        (args.out / "other_species" / f"{name}.txt").write_text("")
        zebra_images += bool(rows)
        boxes += len(rows)
    (args.out / "data.yaml").write_text("# real photographs, HELD BACK: for measuring only, seldom\n"
                                        "path: .\ntrain: images\nval: images\nnames:\n  0: zebra\n")
    (args.out / "SOURCE.txt").write_text(f"github:Insohamdas/Zebra_detection@{COMMIT} {ROOT}/{{train,valid,test}} "
                                         "(Roboflow sushanth-raj/zebra-3cn5k v1, CC BY 4.0); see "
                                         "scripts/real_sets/zebra_detection_heldback.py\n")
    print(f"wrote {args.out}: {len(sources)} images, {zebra_images} with zebras, {boxes} zebra boxes")


if __name__ == "__main__":
    main()
