"""The snapshots of an A/B's arms (``scripts/gpu/ab.sh``): each arm's hard links to its successive ``last.pt`` named
by the epoch they hold, and the last two epochs that every arm finished exported as fp16 serving checkpoints.

    python scripts/gpu/snapshots.py gpu_data/ab_a gpu_data/ab_b --out $OUT

In each run folder, ``snap/raw_*.pt`` (links ab.sh made as each ``last.pt`` landed; a checkpoint counts its epochs
from 0) become ``snap/full_ep_N.pt`` (the newest link of each epoch; the rest removed). With n the highest epoch that
every arm reached, epochs n-1 and n of each arm are exported to ``snap/ep_N.pt`` (what a next call's INIT_A/INIT_B
takes) and copied to ``OUT/<arm>/ep_N.pt``, ``<arm>`` being the folder's name after ``ab_``. Prints one line per arm
and the pairs sent; exit status 1 if no epoch was finished by every arm, or fewer than ``--want``.
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

from zebra_sim_ros.detection.checkpoint import read_checkpoint
from zebra_sim_ros.detection.export import export_checkpoint
from zebra_sim_ros.errors import ZebraSimError


def name_links(run: Path) -> dict[int, Path]:
    """Rename ``run/snap/raw_*.pt`` by the epoch each holds (1-based; of two links to one epoch the newer file
    stays); returns {epoch: path}."""
    for raw in sorted((run / "snap").glob("raw_*.pt"), key=lambda p: p.stat().st_mtime):
        try:
            epoch = int(read_checkpoint(raw)["epoch"]) + 1
        except (ZebraSimError, KeyError, TypeError, ValueError) as exc:  # not one of our checkpoints: say so
            print(f"snapshots: {raw}: not a readable checkpoint ({exc}); left out")
            continue
        raw.replace(run / "snap" / f"full_ep_{epoch}.pt")
    return dict(sorted((int(p.stem.removeprefix("full_ep_")), p) for p in (run / "snap").glob("full_ep_*.pt")))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", type=Path, nargs=2, help="the two arms' run folders (ab_a, ab_b)")
    ap.add_argument("--out", type=Path, required=True, help="where OUT/<arm>/ep_N.pt go")
    ap.add_argument("--want", type=int, default=1, help="exit status 1 unless every arm reached this many epochs")
    a = ap.parse_args()
    epochs = {run: name_links(run) for run in a.runs}
    for run, got in epochs.items():
        print(f"snapshots: {run.name}: epochs {', '.join(map(str, got)) or 'none'}")
    n = min(max(got, default=0) for got in epochs.values())
    print(f"snapshots: both arms finished {n} epochs")
    if n < 1:
        print("snapshots: nothing to pair")
        raise SystemExit(1)
    for run, got in epochs.items():
        arm = run.name.removeprefix("ab_")
        (a.out / arm).mkdir(parents=True, exist_ok=True)
        for e in (n - 1, n):
            if e < 1:
                continue
            if e not in got:
                print(f"snapshots: {run.name} has no snapshot of epoch {e}: that pair is incomplete")
                continue
            ep = export_checkpoint(got[e], run / "snap" / f"ep_{e}.pt")
            shutil.copy(ep, a.out / arm / ep.name)
    print(f"snapshots: paired epochs {max(n - 1, 1)}-{n} in {a.out}")
    if n < a.want:
        raise SystemExit(1)


if __name__ == "__main__":
    main()
