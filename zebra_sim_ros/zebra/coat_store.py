"""Baked coats shared between processes: the coat store beside the zebra cache.

The three cameras of a graph render the same animals at the same moment, and each used to bake every coat itself.
Through a :class:`CoatStore` a coat is baked by the first process to claim it, written to disk, and read by the
others and by later runs of the same experiment. ``generate`` does not use it: its placer streams bring new
animals to every worker, so nothing would be read.
"""

from __future__ import annotations

import errno
import os
import time
import zlib
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.zebra import coat, skeleton
from zebra_sim_ros.zebra.asset import coat_store_dir

Key = tuple[str, int]  # (morph name, coat seed)


class CoatStore:
    """Coats on disk for every process on this machine: ``<cache root>/coats-<appearance digest>-np<numpy>/``, one
    zlib-compressed file per individual and texture size (50-120 kB at 256 texels: zebras the least, giraffes the
    most).

    A process that needs a coat reads it if it is there; otherwise it claims it (a ``.claim`` file made with
    ``O_EXCL``), bakes it and writes it (a temporary file, then a rename), and lets the claim go, also when the bake
    is interrupted. A process that finds a coat claimed bakes its unclaimed ones first, then waits for the rest: a
    claim let go without a coat becomes its own, and one older than ``stale_s`` (its process died) or a wait past
    ``wait_s`` is baked anyway. The bytes are the baked ones, so a coat read is the coat baked, texel for texel; the
    folder is keyed by :func:`~zebra_sim_ros.zebra.asset.appearance_digest` and the numpy version (``sin``
    differs between numpy builds), so other code starts another folder (``zebra-sim asset prune`` removes the old
    ones). A folder that cannot be made turns the store off; one that cannot be written (read-only, full) is still
    read. Either way ``error`` says why and the coats it lacks are baked in memory.
    """

    def __init__(self, root: Path | None = None, wait_s: float = 30.0, stale_s: float = 10.0,
                 enabled: bool = True) -> None:
        self.dir = coat_store_dir(root)
        self.wait_s, self.stale_s = wait_s, stale_s
        self.baked = self.read = 0  # coats this store baked, and coats it read from disk
        self.on = enabled  # read and write the folder; False: every coat baked in memory
        self.writable = enabled  # False: the folder is read, coats it lacks are baked in memory
        self.error: str | None = None
        if enabled:
            try:
                self.dir.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                self.on = self.writable = False
                self.error = f"coat store {self.dir} unusable ({exc}); coats are baked in memory"

    def path(self, morph: str, seed: int, size: int) -> Path:
        """The file of one individual's coat at ``size`` texels."""
        return self.dir / f"{morph}-{seed}-{size}.z"

    def usage(self) -> tuple[int, int]:
        """Coats in the store's folder and their bytes on disk (0, 0 when there is none)."""
        sizes = [f.stat().st_size for f in self.dir.glob("*.z")] if self.dir.is_dir() else []
        return len(sizes), sum(sizes)

    def coats(self, wanted: list[Key], size: int) -> list[NDArray[np.uint8]]:
        """The coats (size, size, 3) uint8 RGB of ``wanted`` (morph name, coat seed) individuals, in order. Blocks
        while other processes bake coats they claimed, ``wait_s`` at most."""
        got: dict[Key, NDArray[np.uint8]] = {}
        waiting = []
        for key in dict.fromkeys(wanted):
            tex = self._load(key, size)
            if tex is None:
                if not self._claim(key, size):
                    waiting.append(key)
                    continue
                tex = self._load_claimed(key, size)
            got[key] = tex
        deadline = time.monotonic() + self.wait_s
        for key in waiting:
            while (tex := self._load(key, size)) is None:
                if time.monotonic() > deadline or self._stale(key, size):
                    tex = self._bake(key, size)  # the claim may be another's: at worst a coat baked twice
                    break
                if self._claim(key, size):  # let go without a coat (its bake failed): ours now
                    tex = self._load_claimed(key, size)
                    break
                time.sleep(0.005)
            got[key] = tex
        return [got[k] for k in wanted]

    def _load(self, key: Key, size: int) -> NDArray[np.uint8] | None:
        if not self.on:
            return None
        try:
            raw = zlib.decompress(self.path(*key, size).read_bytes())
        except (OSError, zlib.error):  # not there yet, or cut short: baked again
            return None
        if len(raw) != size * size * 3:
            return None
        self.read += 1
        return np.frombuffer(raw, dtype=np.uint8).reshape(size, size, 3).copy()

    def _load_claimed(self, key: Key, size: int) -> NDArray[np.uint8]:
        """A coat this process claimed: read if it was written between the look and the claim, else baked."""
        tex = self._load(key, size)
        if tex is None:
            return self._bake(key, size)
        _drop(self._claim_path(key, size))
        return tex

    def _claim(self, key: Key, size: int) -> bool:
        if not self.writable:
            return True  # nothing to share: every coat the folder lacks is this process's to bake
        try:
            os.close(os.open(self._claim_path(key, size), os.O_CREAT | os.O_EXCL | os.O_WRONLY))
            return True
        except FileExistsError:
            return False
        except OSError as exc:
            self._cannot_write(exc)
            return True

    def _cannot_write(self, exc: OSError) -> None:
        self.writable = False
        gone = exc.errno == errno.ENOENT  # the folder was deleted while in use
        self.on = self.on and not gone
        self.error = (f"coat store {self.dir} cannot be written ({exc}); coats it lacks are baked in memory"
                      + (" (the folder is gone: not read either)" if gone else ""))

    def _claim_path(self, key: Key, size: int) -> Path:
        return self.path(*key, size).with_suffix(".claim")

    def _stale(self, key: Key, size: int) -> bool:
        try:
            return time.time() - self._claim_path(key, size).stat().st_mtime > self.stale_s
        except OSError:  # the claim is gone: its coat is written, or the next claim is ours
            return False

    def _bake(self, key: Key, size: int) -> NDArray[np.uint8]:
        """Bake one coat and, where the folder can be written, write it; the claim on it is let go either way."""
        dest = self.path(*key, size)
        tmp = dest.with_suffix(f".{os.getpid()}.tmp")
        try:
            morph = skeleton.MORPHS[key[0]]
            tex = np.ascontiguousarray(coat.bake_coat(morph, coat.random_coat(key[1], morph), size))
            self.baked += 1
            if self.writable:
                try:
                    tmp.write_bytes(zlib.compress(tex.tobytes(), 1))
                    os.replace(tmp, dest)
                except OSError as exc:
                    self._cannot_write(exc)
            return tex
        finally:
            if self.on:
                _drop(tmp)
                _drop(self._claim_path(key, size))


def _drop(path: Path) -> None:
    """Remove a claim or a temporary file if it is there (a folder that cannot be written keeps it: no matter)."""
    try:
        path.unlink(missing_ok=True)
    except OSError:
        pass
