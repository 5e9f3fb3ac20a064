"""``zebra-sim place``: scenes as JSON lines without ROS, the same as the node's, from the same YAML."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from cli_helpers import CliRun

REPO = Path(__file__).resolve().parents[1]


def test_scenes_and_summary(tmp_path: Path, cli: CliRun) -> None:
    proc = cli(["place", "--seed", "4", "--steps", "4", "--params-file", REPO / "config" / "placer.yaml",
                "--set", "count_max=30", "--strategy", "closeby", "--json"])
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.strip().splitlines()
    scenes = [json.loads(x) for x in lines[:-1]]
    summary = json.loads(lines[-1])
    assert [s["step"] for s in scenes] == [0, 1, 2, 3]
    assert all(s["seed"] == 4 and len(s["cameras"]) == 3 and s["requested"] <= 30 for s in scenes)
    assert all(c["strategy"] == "closeby" for s in scenes for c in s["cameras"])
    assert summary["steps"] == 4 and summary["zebras_placed"] == sum(s["placed"] for s in scenes)
    # Step 3 made alone is step 3 of the sequence.
    alone = cli(["place", "--seed", "4", "--steps", "1", "--start-step", "3", "--set", "count_max=30",
                 "--strategy", "closeby", "--out", tmp_path / "s.jsonl"])
    assert alone.returncode == 0, alone.stderr
    assert json.loads((tmp_path / "s.jsonl").read_text()) == scenes[3]


def test_bad_values_are_named(cli: CliRun) -> None:
    for args, needle in ((["--set", "scale_min=2.0"], "scale_min"), (["--set", "nonsense"], "--set"),
                         (["--steps", "0"], "--steps"), (["--world", "atlantis"], "world")):
        proc = cli(["place", *args])
        assert proc.returncode == 2, (args, proc.stdout, proc.stderr)
        assert needle in proc.stderr


def test_a_closed_pipe_ends_quietly_and_options_are_never_abbreviated(cli: CliRun) -> None:
    """``zebra-sim place --steps 20 | head -c 100``: the reader goes away, zebra-sim stops without a traceback;
    ``--frame`` is not taken for ``--frames`` (nor ``--step`` for ``--steps``)."""

    proc = subprocess.Popen([sys.executable, "-m", "zebra_sim_ros.cli", "place", "--steps", "20", "--seed", "3"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdout is not None and proc.stderr is not None
    assert len(proc.stdout.read(100)) == 100
    proc.stdout.close()  # 20 scenes are about 700 KB: far more than a pipe holds, so a write meets the closed pipe
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141 and "Traceback" not in err and "BrokenPipe" not in err, err
    bad = cli(["place", "--step", "2"])
    assert bad.returncode == 2 and "unrecognized arguments: --step 2" in bad.stderr, bad.stderr


def test_sigusr1_prints_the_stacks_and_the_command_goes_on() -> None:
    """``kill -USR1``: every thread's Python stack on stderr (where a run is), and the command carries on."""
    proc = subprocess.Popen([sys.executable, "-m", "zebra_sim_ros.cli", "place", "--seed", "1", "--steps", "100000"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        first = proc.stdout.readline()  # a scene written: the handler is in place, the loop is running
        assert json.loads(first)["step"] == 0
        proc.send_signal(signal.SIGUSR1)
        time.sleep(1.0)
        more = proc.stdout.readline()
        assert proc.poll() is None and json.loads(more)["step"] >= 1  # still going
    finally:
        proc.kill()
        _, err = proc.communicate(timeout=30)
    assert "most recent call first" in err and "zebra_sim_ros/cli/place.py" in err, err[-2000:]
    # a zebra-sim started with its stderr closed runs all the same
    closed = subprocess.run([sys.executable, "-m", "zebra_sim_ros.cli", "world", "list"], stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True, timeout=60, preexec_fn=lambda: os.close(2))
    assert closed.returncode == 0 and "savanna" in closed.stdout
