"""The in-process runner behind the ``cli`` fixture: statuses as the interpreter makes them, output captured at the
file descriptors, and a timeout that fails the test even through code that catches every Exception."""

from __future__ import annotations

import os
import signal
import sys
import time
from pathlib import Path

import pytest
from cli_helpers import CliTimeout, run_cli, script_main


def test_a_run_past_its_timeout_raises_through_a_catch_all(
        capfd: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    caught: list[BaseException] = []

    def stubborn(argv: list[str]) -> int:
        try:
            time.sleep(10)
        except Exception as exc:  # what generate's `except OSError` or a broad handler would do
            caught.append(exc)
        return 0

    before = signal.getsignal(signal.SIGALRM)
    t0 = time.monotonic()
    with pytest.raises(CliTimeout, match="timeout of 0.3 s"):
        run_cli(stubborn, [], capfd, monkeypatch, timeout=0.3)
    assert time.monotonic() - t0 < 5
    assert caught == []
    # a run that ends before its timeout leaves no timer running, and either way the old handler is back
    assert signal.getsignal(signal.SIGALRM) is before
    assert run_cli(lambda argv: 0, [], capfd, monkeypatch, timeout=30).returncode == 0
    assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)
    assert signal.getsignal(signal.SIGALRM) is before


def test_statuses_and_output_come_back_as_a_finished_process(
        capfd: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    def noisy(argv: list[str]) -> int:
        print("out:", *argv)
        os.write(2, b"err at the fd\n")
        raise SystemExit("bad value 'x' for --frames")

    done = run_cli(noisy, ["a", 3], capfd, monkeypatch, env={"ZEBRA_T": "1"})
    assert done.args == ["a", "3"]
    assert done.returncode == 1
    assert done.stdout == "out: a 3\n"
    assert "err at the fd" in done.stderr and "bad value 'x' for --frames" in done.stderr
    assert run_cli(lambda argv: 3, [], capfd, monkeypatch).returncode == 3
    assert run_cli(lambda argv: (_ for _ in ()).throw(SystemExit(0)), [], capfd, monkeypatch).returncode == 0
    seen: list[str | None] = []
    run_cli(lambda argv: seen.append(os.environ.get("ZEBRA_T")) or 0, [], capfd, monkeypatch, env={"ZEBRA_T": "7"})
    assert seen == ["7"] and "ZEBRA_T" not in os.environ


@pytest.mark.parametrize("timeout", [0, -1.0, float("nan"), float("inf")])
def test_a_timeout_that_is_not_positive_and_finite_is_refused(
        timeout: float, capfd: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    with pytest.raises(ValueError, match="timeout must be a positive, finite number"):
        run_cli(lambda argv: 0, [], capfd, monkeypatch, timeout=timeout)


def test_a_script_runs_as_main_with_its_argv_which_is_put_back(
        tmp_path: Path, capfd: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    script = tmp_path / "tool.py"
    script.write_text("import sys\nif __name__ == '__main__':\n    print(sys.argv)\n"
                      "    sys.exit(4 if sys.argv[1:] == ['--n', '2'] else 'wrong argv')\n")
    before = list(sys.argv)
    done = run_cli(script_main(script), ["--n", 2], capfd, monkeypatch)
    assert done.returncode == 4, done.stderr
    assert done.stdout == f"{[str(script), '--n', '2']}\n"
    assert sys.argv == before
    script.write_text("raise RuntimeError('broken tool')\n")
    with pytest.raises(RuntimeError, match="broken tool"):
        run_cli(script_main(script), [], capfd, monkeypatch)
    assert sys.argv == before
