"""Workers for ``generate``'s parallel runner that misbehave on purpose, each the way a real one could: spawned
processes import them from here (the test folder is on their ``sys.path`` as on the parent's)."""

from __future__ import annotations

import time
from typing import Any


def reports_then_returns(cfg: Any, jobs: list[Any], conn: Any) -> None:
    """Reports its start and one frame, then ends with exit code 0 without saying it was done (as a library that
    calls ``sys.exit(0)`` would make it)."""
    conn.send(("started", None))
    conn.send(("frames", 1))
    conn.close()


def closes_its_pipe_and_stays(cfg: Any, jobs: list[Any], conn: Any) -> None:
    """Closes its pipe at once and goes on running (the parent must end it)."""
    conn.close()
    time.sleep(120)


def reports_then_waits(cfg: Any, jobs: list[Any], conn: Any) -> None:
    """Reports its start, then waits, as a worker busy with a long frame does."""
    conn.send(("started", None))
    time.sleep(120)
