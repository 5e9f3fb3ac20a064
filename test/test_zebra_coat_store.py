"""The coat store: coats baked once between processes, and every failure of the folder still gives the coat."""

from __future__ import annotations

import errno
import hashlib
import multiprocessing
import os
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from zebra_sim_ros.zebra import coat
from zebra_sim_ros.zebra.coat_store import CoatStore
from zebra_sim_ros.zebra.skeleton import MORPHS


def _baked(name: str, seed: int, size: int) -> np.ndarray:
    return coat.bake_coat(MORPHS[name], coat.random_coat(seed, MORPHS[name]), size)


def _share_coats(root: str, keys: list[tuple[str, int]], barrier: Any, out: Any) -> None:
    """A process of the sharing test: wait for the others, then ask the store for every coat; errors go back too."""
    try:
        store = CoatStore(Path(root))
        barrier.wait(timeout=60)
        texs = store.coats(keys, 128)
        out.put((store.baked, store.read, [hashlib.md5(t.tobytes()).hexdigest() for t in texs]))
    except BaseException as exc:  # noqa: BLE001 - the test reports it, whatever it is
        out.put(("error", repr(exc), []))


def test_three_processes_share_the_coat_store_and_each_coat_is_baked_once(tmp_path: Path) -> None:
    """Three processes that ask for the same 24 coats at the same moment (the three cameras of a graph) bake each of
    them once between them and all get the coats that bake_coat bakes; a later store reads them all."""
    keys = [(name, seed) for name in ("plains", "grevy", "buffalo") for seed in range(8)]
    ctx = multiprocessing.get_context("spawn")
    barrier, out = ctx.Barrier(3), ctx.Queue()
    procs = [ctx.Process(target=_share_coats, args=(str(tmp_path), keys, barrier, out)) for _ in range(3)]
    for p in procs:
        p.start()
    try:
        got = [out.get(timeout=120) for _ in procs]
    finally:
        for p in procs:
            p.join(timeout=30)
            if p.is_alive():
                p.kill()
    assert not [g for g in got if g[0] == "error"], got
    want = [hashlib.md5(_baked(n, s, 128).tobytes()).hexdigest() for n, s in keys]
    assert all(md5s == want for _, _, md5s in got)
    assert sum(baked for baked, _, _ in got) == len(keys), got  # not 3 x 24
    assert sum(read for _, read, _ in got) == 2 * len(keys)
    later = CoatStore(tmp_path)
    assert [hashlib.md5(t.tobytes()).hexdigest() for t in later.coats(keys, 128)] == want
    assert (later.baked, later.read) == (0, len(keys))
    assert not list(later.dir.glob("*.claim")) and not list(later.dir.glob("*.tmp"))


def test_a_broken_file_and_a_dead_claim_still_give_the_coat(tmp_path: Path) -> None:
    """A coat file cut short is baked again and rewritten whole; a claim left by a process that died (older than
    ``stale_s``) is taken over at once, not waited for."""
    want = _baked("plains", 3, 64)
    store = CoatStore(tmp_path, stale_s=0.5)
    store.path("plains", 3, 64).write_bytes(b"x\x9c\x03")  # a truncated zlib stream
    assert np.array_equal(store.coats([("plains", 3)], 64)[0], want) and store.baked == 1
    again = CoatStore(tmp_path)
    assert np.array_equal(again.coats([("plains", 3)], 64)[0], want) and (again.baked, again.read) == (0, 1)
    claim = store.path("plains", 4, 64).with_suffix(".claim")
    claim.touch()
    os.utime(claim, (time.time() - 5, time.time() - 5))  # its process is gone
    t0 = time.monotonic()
    four = store.coats([("plains", 4), ("plains", 3)], 64)
    assert time.monotonic() - t0 < 5 and not claim.exists()
    assert np.array_equal(four[0], _baked("plains", 4, 64)) and np.array_equal(four[1], want)


def test_an_interrupted_bake_lets_its_claim_go(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A bake stopped by Ctrl-C leaves neither its claim nor a temporary file, so the next process bakes the coat
    at once instead of waiting ``stale_s`` for the claim to go stale."""
    store = CoatStore(tmp_path, stale_s=30.0, wait_s=30.0)

    def interrupted(*args: object, **kwargs: object) -> np.ndarray:
        raise KeyboardInterrupt

    with monkeypatch.context() as m:
        m.setattr(coat, "bake_coat", interrupted)
        with pytest.raises(KeyboardInterrupt):
            store.coats([("grevy", 5)], 64)
    assert not list(store.dir.iterdir())  # no claim, no temporary file, no coat
    t0 = time.monotonic()
    assert np.array_equal(CoatStore(tmp_path, stale_s=30.0).coats([("grevy", 5)], 64)[0], _baked("grevy", 5, 64))
    assert time.monotonic() - t0 < 10


def test_a_store_that_cannot_be_made_or_written_bakes_in_memory_and_says_why(tmp_path: Path,
                                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    """A folder that cannot be made turns the store off; a full disk or a read-only folder stops the writing but
    not the reading of the coats already there; a folder deleted while in use stops both. Each names the folder,
    and every coat still comes back as bake_coat bakes it."""
    (tmp_path / "file").write_text("not a folder")
    off = CoatStore(tmp_path / "file")
    assert not off.on and off.error is not None and str(tmp_path / "file") in off.error
    assert np.array_equal(off.coats([("plains", 3)], 64)[0], _baked("plains", 3, 64)) and off.baked == 1

    CoatStore(tmp_path / "full").coats([("plains", 1)], 64)  # one coat already there
    full = CoatStore(tmp_path / "full")

    def no_space(self: Path, data: bytes) -> int:
        raise OSError(errno.ENOSPC, "No space left on device", str(self))

    with monkeypatch.context() as m:
        m.setattr(Path, "write_bytes", no_space)
        texs = full.coats([("plains", 1), ("rhino", 2), ("rhino", 3)], 64)
    assert full.on and not full.writable and full.error is not None and "No space left" in full.error
    assert (full.read, full.baked) == (1, 2) and np.array_equal(texs[1], _baked("rhino", 2, 64))
    assert [f.name for f in full.dir.iterdir()] == [full.path("plains", 1, 64).name]  # nothing half-written

    CoatStore(tmp_path / "ro").coats([("plains", 1)], 64)
    ro = CoatStore(tmp_path / "ro")
    real_open = os.open

    def read_only(path: Any, flags: int, *args: Any) -> int:
        if flags & os.O_CREAT:
            raise PermissionError(errno.EACCES, "Permission denied", str(path))
        return real_open(path, flags, *args)

    with monkeypatch.context() as m:
        m.setattr(os, "open", read_only)
        texs = ro.coats([("plains", 1), ("grevy", 7)], 64)
    assert ro.on and not ro.writable and "Permission denied" in str(ro.error) and (ro.read, ro.baked) == (1, 1)
    assert np.array_equal(texs[1], _baked("grevy", 7, 64)) and not ro.path("grevy", 7, 64).exists()

    gone = CoatStore(tmp_path / "gone")
    for f in gone.dir.iterdir():
        f.unlink()
    gone.dir.rmdir()  # deleted while in use ("safe to delete")
    assert np.array_equal(gone.coats([("foal", 2)], 64)[0], _baked("foal", 2, 64))
    assert not gone.on and "gone" in str(gone.error)
