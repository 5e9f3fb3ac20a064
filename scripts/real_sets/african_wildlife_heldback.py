"""Rebuild the HELD-BACK real set ``real_heldback/african_wildlife_heldback/`` (measuring only, and rarely).

Source: github:EricJakovac/Animals, commit 676be7122cb9b9fa8f86367621da2a5e1c8d692c, the TEST and VALID splits of
``datasets/african-wildlife`` (the ultralytics "African Wildlife" set; classes 0 buffalo, 1 elephant, 2 rhino,
3 zebra). License: AGPL-3.0 (the ultralytics dataset's).
Why held back: ``african_wildlife_dev`` (400 photos of the same set's train split) is the set weights and rules have
been weighed on; these 452 photos have not been. They say whether the dev set's figures hold on photographs nobody
tuned on. They live outside ``real/`` so that ``bench_real.py`` never scores them unless named with ``--sets``;
score them seldom (a checkpoint or a rule is never chosen on them) and say so when you do.
Every image of both splits is written, files byte for byte.

Layout written: ``images/<split>_<name>.jpg`` (the source name with every character but letters and digits turned
into ``_``), ``labels/*.txt`` (class 0 = zebra), ``other_species/*.txt`` (the other animals' boxes in the source
classes 0-2), ``data.yaml``, ``SOURCE.txt``.

    python scripts/real_sets/african_wildlife_heldback.py GIT_DIR [--out real_heldback/african_wildlife_heldback]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from african_wildlife_dev import COMMIT, write_set  # noqa: E402  (the same source, pinned to the same commit)
from common import export_images, local_name  # noqa: E402

ROOT = "datasets/african-wildlife"
SPLITS = ("test", "valid")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    ap.add_argument("git_dir", type=Path)
    ap.add_argument("--out", type=Path, default=HERE.parents[1] / "real_heldback" / "african_wildlife_heldback")
    args = ap.parse_args()
    sources = export_images(args.git_dir, COMMIT, ROOT, SPLITS)
    write_set(args.git_dir, [(src, local_name(src.split("/")[2], src)) for src in sources], args.out,
              "# real photographs, HELD BACK: for measuring only, seldom",
              f"{ROOT}/{{test,valid}} (AGPL-3.0); see scripts/real_sets/african_wildlife_heldback.py")


if __name__ == "__main__":
    main()
