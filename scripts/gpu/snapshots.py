"""Snapshots of training runs on a lent GPU, named by the epoch they hold (a checkpoint counts its epochs from 0; the
names count from 1), not by the results rows seen, which a short epoch can outrun.

    python scripts/gpu/snapshots.py one RUN/snap/raw_123.pt RUN/snap        # train.sh: prints N of ep_N.pt
    python scripts/gpu/snapshots.py pair gpu_data/ab_a gpu_data/ab_b --out $OUT --want 5      # ab.sh
    python scripts/gpu/snapshots.py pick RUN $OUT                             # train.sh: the files to send back

``one``: a checkpoint (a hard link to a ``last.pt``: always a whole file) exported as an fp16 serving checkpoint
``FOLDER/ep_N.pt``; prints N. ``pair``: in each of an A/B's run folders, ``snap/raw_*.pt`` (the links ab.sh made
as each ``last.pt`` landed) become ``snap/full_ep_N.pt`` (the newest link of each epoch; the rest removed). With n
the highest epoch that every arm reached, epochs n-1 and n of each arm are exported to ``snap/ep_N.pt`` (what a next
call's INIT_A/INIT_B takes) and copied to ``OUT/<arm>/ep_N.pt``, ``<arm>`` being the folder's name after ``ab_``.
Prints one line per arm and the pairs sent; exit status 1 if no epoch was finished by every arm, or fewer than
``--want``. ``pick``: which of a run's ``snap/ep_N.pt`` and its ``best.pt`` to send back, one path a line.
"""

from __future__ import annotations

import argparse
import math
import shutil
from pathlib import Path

from zebra_sim_ros.errors import ZebraSimError  # no torch: `pick` runs as the call ends


def epoch_of(checkpoint: Path) -> int:
    """The epoch a checkpoint holds, counted from 1."""
    from zebra_sim_ros.detection.checkpoint import read_checkpoint  # torch, here and below: not for `pick`

    return int(read_checkpoint(checkpoint)["epoch"]) + 1


def export_by_epoch(checkpoint: Path, folder: Path) -> int:
    """``checkpoint`` exported as ``folder/ep_N.pt`` (fp16, no optimizer; the run's record kept), N the epoch it
    holds; returns N. The export is written under a hidden name first, then renamed: a reader never sees half."""
    from zebra_sim_ros.detection.export import export_checkpoint

    out = export_checkpoint(checkpoint, folder / ".export.pt")
    n = epoch_of(out)  # read from the small fp16 export, not the full checkpoint again
    out.replace(folder / f"ep_{n}.pt")
    return n


def name_links(run: Path) -> dict[int, Path]:
    """Rename ``run/snap/raw_*.pt`` by the epoch each holds (1-based; of two links to one epoch the newer file
    stays); returns {epoch: path}."""
    for raw in sorted((run / "snap").glob("raw_*.pt"), key=lambda p: p.stat().st_mtime):
        try:
            epoch = epoch_of(raw)
        except (ZebraSimError, KeyError, TypeError, ValueError) as exc:  # not one of our checkpoints: say so
            print(f"snapshots: {raw}: not a readable checkpoint ({exc}); left out")
            continue
        target = run / "snap" / f"full_ep_{epoch}.pt"
        if target.exists() and raw.samefile(target):  # a second link to one file (ab.sh's raw_last.pt): renaming
            raw.unlink()  # it onto the other would leave both
        else:
            raw.replace(target)
    return dict(sorted((int(p.stem.removeprefix("full_ep_")), p) for p in (run / "snap").glob("full_ep_*.pt")))


def pair(runs: list[Path], out: Path, want: int) -> int:
    """Name each arm's links, export the last two epochs every arm reached into ``out/<arm>/``; the exit status."""
    from zebra_sim_ros.detection.export import export_checkpoint

    epochs = {run: name_links(run) for run in runs}
    for run, got in epochs.items():
        print(f"snapshots: {run.name}: epochs {', '.join(map(str, got)) or 'none'}")
    n = min(max(got, default=0) for got in epochs.values())
    print(f"snapshots: both arms finished {n} epochs")
    if n < 1:
        print("snapshots: nothing to pair")
        return 1
    for run, got in epochs.items():
        arm = run.name.removeprefix("ab_")
        (out / arm).mkdir(parents=True, exist_ok=True)
        for e in (n - 1, n):
            if e < 1:
                continue
            if e not in got:
                print(f"snapshots: {run.name} has no snapshot of epoch {e}: that pair is incomplete")
                continue
            ep = export_checkpoint(got[e], run / "snap" / f"ep_{e}.pt")
            shutil.copy(ep, out / arm / ep.name)
    print(f"snapshots: paired epochs {max(n - 1, 1)}-{n} in {out}")
    return 1 if n < want else 0


# what one call sends back: 8 files and 60 MiB at most, a file over 15 MiB counted as its 15 MiB parts
PART, FILES, BYTES = 15 * 2**20, 8, 60 * 2**20


def pick(run: Path, out: Path) -> list[Path]:
    """The snapshots worth sending back from ``run`` (one from the middle of the run and the two before the last,
    newest first; the last one is already sent as last_snap.pt) and ``run/best.pt``, in that order, while they fit
    beside what ``out`` already holds (train.log counted whether or not it is there yet)."""
    held = {p for p in out.rglob("*") if p.is_file()} | {out / "train.log"}
    files, size = len(held), sum(p.stat().st_size for p in held if p.exists())
    snaps = sorted((run / "snap").glob("ep_*.pt"), key=lambda p: int(p.stem.removeprefix("ep_")))
    older = snaps[:-3]
    keep = ([older[len(older) // 2]] if older else []) + snaps[-3:-1][::-1]
    chosen = []
    for p in keep + ([run / "best.pt"] if (run / "best.pt").exists() else []):
        n = max(1, math.ceil(p.stat().st_size / PART))
        if files + n <= FILES and size + p.stat().st_size <= BYTES:
            files, size = files + n, size + p.stat().st_size
            chosen.append(p)
    return chosen


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    one = sub.add_parser("one", help="export one checkpoint as FOLDER/ep_N.pt; prints N")
    one.add_argument("checkpoint", type=Path)
    one.add_argument("folder", type=Path)
    pr = sub.add_parser("pair", help="name an A/B's links by epoch and export the last two epochs both arms reached")
    pr.add_argument("runs", type=Path, nargs=2, help="the two arms' run folders (ab_a, ab_b)")
    pr.add_argument("--out", type=Path, required=True, help="where OUT/<arm>/ep_N.pt go")
    pr.add_argument("--want", type=int, default=1, help="exit status 1 unless every arm reached this many epochs")
    pk = sub.add_parser("pick", help="the snapshots and best.pt of a run that fit what one call sends back")
    pk.add_argument("run", type=Path)
    pk.add_argument("out", type=Path, help="the folder sent back (what it holds already is counted)")
    a = ap.parse_args()
    if a.cmd == "one":
        print(export_by_epoch(a.checkpoint, a.folder))
        return
    if a.cmd == "pick":
        for p in pick(a.run, a.out):
            print(p)
        return
    raise SystemExit(pair(a.runs, a.out, a.want))


if __name__ == "__main__":
    main()
