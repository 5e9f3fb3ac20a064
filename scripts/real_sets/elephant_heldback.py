"""Rebuild the HELD-BACK real set ``real_heldback/elephant_heldback/`` (photos of elephants only; measuring only).

Source: github:ThevinduSK/Elephants-Intrusion-Detection, commit d86b9e9f2305a2dfa2fbe123df9fd8b0fa6a9bfc, the VALID
and TEST folders of ``data/`` (``valid_reduced``, 150 photos, and ``test_reduced``, 85: the repository owner's
subsets of a Roboflow Universe export, "Elephant intrusion detection system" v1,
school-ihmbv/elephant-intrusion-detection-system-xjwvm, 2023-07-03, 4,609 images; one class, 0 = elephant; every
image stretched to 640x640). The export's augmentations (flips, crops, rotation, shear, salt-and-pepper noise) are,
as Roboflow makes them, in its train split, which is left out here; the photos here look unaugmented. License: the
photos are Open Images photos (the file names are their ids; Open Images photos are CC BY 2.0); the export is
labelled Public Domain (its ``README.dataset.txt`` and ``data.yaml``).
Why: photos of another species and no zebra, to count false detections on photographs nobody has tuned on (the
african_wildlife photos of other species have been weighed on many times). Held back: it lives outside ``real/``
so that ``bench_real.py`` scores it only when named with ``--sets``; score it seldom, never to choose anything, and
say so when you do. They are Open Images photos tagged elephant, not only field photos: zoos, circuses, people
beside elephants, statues, toys, drawings and posters, so they measure false detections on elephants and on
everything else a photo of one holds. Every photo's elephant boxes go to ``other_species/`` as class 1 (elephant, as
in the african_wildlife sets); ``labels/`` are empty. One photo shows a zebra (a poster of African animals) and is
left out (``WITH_ZEBRAS``); no other zebra was seen on a contact sheet of all 235 photos at 128 px, so a photo a
detector finds a zebra on is worth a look before it is counted as false.
Every other image of both splits is written, files byte for byte.

Layout written: ``images/<split>_<name>.jpg`` (the source name with every character but letters and digits turned
into ``_``), ``labels/*.txt`` (empty), ``other_species/*.txt`` (class 1 = elephant), ``data.yaml``, ``SOURCE.txt``.

    python scripts/real_sets/elephant_heldback.py GIT_DIR [--out real_heldback/elephant_heldback]

``GIT_DIR``: a clone or bare mirror of the repository holding that commit.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from common import export_images, fresh_set, git, label_rows, local_name  # noqa: E402  (shared by these scripts)

COMMIT = "d86b9e9f2305a2dfa2fbe123df9fd8b0fa6a9bfc"
ROOT = "data"
SPLITS = ("valid_reduced", "test_reduced")
ELEPHANT_SOURCE, ELEPHANT_OURS = "0", "1"
# photos that show a zebra (a poster of African animals), left out
WITH_ZEBRAS = frozenset({"16ebbed435f259aa_jpg.rf.f143e84d97d32f6dfaaa60a5dde0f0e9.jpg"})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    ap.add_argument("git_dir", type=Path)
    ap.add_argument("--out", type=Path, default=HERE.parents[1] / "real_heldback" / "elephant_heldback")
    args = ap.parse_args()
    sources = export_images(args.git_dir, COMMIT, ROOT, SPLITS, skip=WITH_ZEBRAS)
    fresh_set(args.out)
    boxes = 0
    for src in sources:
        split = src.split("/")[1].removesuffix("_reduced")
        name = local_name(split, src)
        rows = label_rows(args.git_dir, COMMIT, src, only_class=ELEPHANT_SOURCE)
        (args.out / "images" / f"{name}{Path(src).suffix.lower()}").write_bytes(
            git(args.git_dir, "show", f"{COMMIT}:{src}"))
        (args.out / "labels" / f"{name}.txt").write_text("")
        (args.out / "other_species" / f"{name}.txt").write_text(
            "".join(" ".join([ELEPHANT_OURS, *r[1:]]) + "\n" for r in rows))
        boxes += len(rows)
    (args.out / "data.yaml").write_text("# real photographs of elephants, HELD BACK: for measuring only, seldom\n"
                                        "path: .\ntrain: images\nval: images\nnames:\n  0: zebra\n")
    (args.out / "SOURCE.txt").write_text(f"github:ThevinduSK/Elephants-Intrusion-Detection@{COMMIT} "
                                         f"{ROOT}/{{valid_reduced,test_reduced}} (Roboflow school-ihmbv/"
                                         "elephant-intrusion-detection-system-xjwvm v1, Public Domain); see "
                                         "scripts/real_sets/elephant_heldback.py\n")
    print(f"wrote {args.out}: {len(sources)} photos, none with zebras, {boxes} elephant boxes")


if __name__ == "__main__":
    main()
