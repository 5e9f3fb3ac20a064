"""What the real-set scripts share: reading a pinned file of a fetched repository, the set's fresh layout, the
photos of a YOLO export's splits, their label rows and their names in a rebuilt set."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path


def git(git_dir: Path, *args: str) -> bytes:
    """Standard output of ``git -C git_dir args...`` (the one way these scripts read a pinned file)."""
    return subprocess.run(["git", "-C", str(git_dir), *args], check=True, capture_output=True).stdout


def fresh_set(out: Path) -> None:
    """``out`` emptied, with the layout's three folders: ``images/``, ``labels/``, ``other_species/``."""
    if out.exists():
        shutil.rmtree(out)
    for sub in ("images", "labels", "other_species"):
        (out / sub).mkdir(parents=True)


def export_images(git_dir: Path, commit: str, root: str, splits: tuple[str, ...],
                  skip: frozenset[str] = frozenset()) -> list[str]:
    """The photos of a YOLO export's ``<root>/<split>/images/`` at ``commit`` (``root`` may have several parts),
    sorted, less those whose file names are in ``skip``. Stops, naming the folders, if there is none, and naming the
    name if one of ``skip`` is not there (the pin and the list would have drifted apart)."""
    files = git(git_dir, "ls-tree", "-r", "--name-only", commit, root).decode().splitlines()
    found = [f for f in files if len(parts := f.removeprefix(root + "/").split("/")) == 3 and parts[0] in splits
             and parts[1] == "images" and f.lower().endswith((".jpg", ".jpeg", ".png"))]
    absent = sorted(skip - {Path(f).name for f in found})
    if absent:
        raise SystemExit(f"{git_dir}: {absent[0]!r}, to be left out, is not under {root}/{{{','.join(splits)}}}/images "
                         f"at {commit}")
    sources = sorted(f for f in found if Path(f).name not in skip)
    if not sources:
        raise SystemExit(f"{git_dir}: no images under {root}/{{{','.join(splits)}}}/images at {commit}")
    return sources


def label_rows(git_dir: Path, commit: str, image: str, only_class: str | None = None) -> list[list[str]]:
    """The rows, split into fields, of the YOLO label file of the export's photo ``image`` (its path in the
    repository; the labels at ``.../labels/<stem>.txt``), blank lines left out. ``only_class``: the export holds
    boxes of this one class only, and a row of another class or shape stops the script, naming the file (the source
    would not be what was pinned). A missing file raises ``CalledProcessError``."""
    label = image.replace("/images/", "/labels/").rsplit(".", 1)[0] + ".txt"
    rows = [ln.split() for ln in git(git_dir, "show", f"{commit}:{label}").decode().splitlines() if ln.strip()]
    bad = [r for r in rows if only_class is not None and (len(r) != 5 or r[0] != only_class)]
    if bad:
        raise SystemExit(f"{label} at {commit}: row {' '.join(bad[0])!r} is not a class-{only_class} box (5 fields)")
    return rows


def local_name(prefix: str, image: str) -> str:
    """A photo's file stem in a rebuilt set: ``<prefix>_<source stem>``, every character but letters and digits
    turned into ``_``."""
    return f"{prefix}_{re.sub(r'[^A-Za-z0-9]', '_', Path(image).stem)}"
