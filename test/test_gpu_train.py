"""scripts/gpu/train.sh: a fine-tune fitted to a time budget, run here on the CPU with a tiny pack (on a lent GPU it
is the same script): two epochs timed, the run resumed with the epoch count that fits, fp16 snapshots sent back."""

from __future__ import annotations

import os
import re
import subprocess
import time
from pathlib import Path

import torch
from cli_helpers import CliRun
from gpu_helpers import ROOT, assert_refused, run_script, tiny_pack

from zebra_sim_ros.detection.checkpoint import read_checkpoint

TRAIN = ROOT / "scripts" / "gpu" / "train.sh"


def test_train_sh_refuses_settings_that_name_the_bad_value(tmp_path: Path, pack: CliRun) -> None:
    data, out = tiny_pack(tmp_path, pack), tmp_path / "out"
    base = {"DATA": str(data), "OUT": str(out), "DEVICE": "cpu"}
    assert_refused(TRAIN, base, [({"MODEL": "x"}, "MODEL=x"), ({"P2": "2"}, "P2=2"), ({"E0": "0"}, "E0=0"),
                                 ({"BUDGET": "700"}, "BUDGET=700"), ({"INIT": str(tmp_path / "no.pt")}, "INIT="),
                                 ({"DATA": str(tmp_path / "empty")}, "DATA=")], out)


def test_train_sh_fits_the_epochs_to_its_budget_and_sends_the_last_snapshot(tmp_path: Path,
                                                                            pack: CliRun) -> None:
    data, out = tiny_pack(tmp_path, pack), tmp_path / "out"
    r = run_script(TRAIN, {"DATA": str(data), "OUT": str(out), "DEVICE": "cpu", "K": "4", "E0": "3", "BATCH": "2",
                "WORKERS": "1", "IMGSZ": "320", "CROP": "160", "BUDGET": "70"})
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    log = (out / "train.log").read_text()
    fit = re.search(r"\[run\] epoch 2 took (\d+) s; (\d+) s gone; (\d+) epochs fit", log)
    assert fit, log[-3000:]
    ended = re.search(r"\[run\] training ended at \d+ s, rows (\d+)", log)
    assert ended, log[-3000:]
    rows = int(ended.group(1))
    assert 3 <= rows <= int(fit.group(3))  # at least E0's minimum of 3; no more than it planned
    results = (out / "results.csv").read_text().strip().splitlines()
    assert len(results) == rows + 1  # the header and one row per epoch, the resumed run's included
    assert [int(line.split(",")[0]) for line in results[1:]] == list(range(1, rows + 1))
    snap = read_checkpoint(out / "last_snap.pt")  # the last epoch's EMA weights in fp16, the run's record kept
    last = read_checkpoint(data / "run_out" / "last.pt")["epoch"] + 1  # checkpoints count epochs from 0
    # the last epoch saved: the trainer writes an epoch's row before its last.pt, so a trainer the budget's timeout
    # stops between the two leaves one row more
    assert snap["epoch"] == last - 1 and rows - 1 <= last <= rows, (snap["epoch"], last, rows)
    assert all(t.dtype == torch.float16 for t in snap["model"].values() if t.is_floating_point())
    assert snap["train_args"]["crop"] == 160 and snap["config"]["p2"] is False
    # every epoch has a snapshot, named by the epoch it holds, but those a backlog left at the end (counted in the
    # log): CPU epochs of a second or two outrun an export, and the watch (polling every 0.2 s) links each last.pt
    # while the exports run behind it
    kept = {int(p.stem.removeprefix("ep_")): read_checkpoint(p)["epoch"]
            for p in (data / "run_out" / "snap").glob("ep_*.pt")}
    assert all(held == n - 1 for n, held in kept.items()), kept
    dropped = re.search(r"\[run\] (\d+) older links not exported", log)
    assert dropped, log[-3000:]
    assert {last - 2, last - 1, last} <= set(kept) and len(kept) + int(dropped.group(1)) == last, (kept, log[-2000:])
    assert not list((data / "run_out" / "snap").glob("raw_*.pt")), "a link left unexported"
    # sent back besides last_snap.pt: one snapshot from the middle of the run and the two before the last, and best.pt
    epochs = sorted(kept)
    older = epochs[:-3]
    assert sorted(p.name for p in (out / "snap").glob("*.pt")) == sorted(
        f"ep_{n}.pt" for n in ([older[len(older) // 2]] if older else []) + epochs[-3:-1]), log[-1000:]
    assert (out / "best.pt").is_file() == (data / "run_out" / "best.pt").is_file()  # none if the timeout cut the run


def _export_links(run: Path, links: dict[str, float], watch_s: float, late: str = "") -> list[str]:
    """lib.sh's export_links on RUN/snap/raw_*.pt links made with these modification times (seconds ago), the
    watch a `sleep watch_s` (0: already gone), a link named ``late`` added 0.5 s in; the links snap_one got, in
    order (this snap_one records the name and takes the link away, as train.sh's does)."""
    (run / "snap").mkdir(parents=True)
    now = time.time()
    for name, ago in sorted(links.items()):  # made in name order, so that neither name nor making order is time order
        (run / "snap" / name).write_bytes(b"x")
        os.utime(run / "snap" / name, (now - ago, now - ago))
    script = f"""source scripts/gpu/lib.sh
snap_one() {{ echo "${{1##*/}}" >> "{run}/order"; rm -f "$1"; }}
sleep {watch_s} & W=$!
if [ {watch_s} = 0 ]; then wait $W; fi
if [ -n "{late}" ]; then (sleep 0.5; touch "{run}/snap/{late}") & fi
export_links "{run}" "$W" "{run}/log"
"""
    r = subprocess.run(["bash", "-c", script], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert not list((run / "snap").glob("raw_*.pt")), "a link left behind"
    return (run / "order").read_text().split() if (run / "order").exists() else []


def test_export_links_sends_oldest_first_and_drops_all_but_three_once_the_watch_is_gone(tmp_path: Path) -> None:
    # names out of time order: the order must come from the links' times
    links = {"raw_50.pt": 60, "raw_7.pt": 50, "raw_300.pt": 40, "raw_12.pt": 30, "raw_9.pt": 20, "raw_88.pt": 10}
    got = _export_links(tmp_path / "gone", links, 0)
    assert got == ["raw_12.pt", "raw_9.pt", "raw_88.pt"]  # the newest three, oldest first
    assert (tmp_path / "gone" / "log").read_text() == "[run] 3 older links not exported\n"
    # while the watch runs nothing is dropped, and a link that lands later is sent after the earlier ones
    got = _export_links(tmp_path / "alive", links, 3, late="raw_1.pt")
    assert got == ["raw_50.pt", "raw_7.pt", "raw_300.pt", "raw_12.pt", "raw_9.pt", "raw_88.pt", "raw_1.pt"]
    assert (tmp_path / "alive" / "log").read_text() == "[run] 0 older links not exported\n"
