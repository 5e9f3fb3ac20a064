"""The recorder core: a bounded queue between the subscription callbacks and one writer thread.

Callbacks never touch the disk: :meth:`RecorderCore.offer` puts the serialized message in the queue or, if it
is full, counts a drop for that topic (never silent: drops are in the statistics and the logs); while ``paused``
it counts the message as ``paused`` instead, neither written nor dropped. The writer thread writes in arrival
order; :meth:`RecorderCore.split` queues a split in that order too. A full disk or the size cap ends the
recording: the thread finalises what it can and keeps the error for the node to report.

In snapshot mode (``snapshot_bytes`` > 0, as ``ros2 bag record --snapshot-mode``) offered messages go into a cache
in memory instead, the oldest let go (counted as ``expired``) past ``snapshot_bytes`` or, with ``snapshot_ns``, once
older than that much log time before the newest; :meth:`RecorderCore.snapshot` hands the whole cache to the writer
thread in one piece and empties it, and the thread writes it into a file of its own, finished at once (as rosbag2
does since it writes each snapshot to a new file): the bag's first file, then ``<stem>_1.mcap``, ... (with a size or
duration split, ``<stem>_0.mcap``, ..., and a large snapshot may fill several); a split on demand has no meaning
there and is refused.
"""

from __future__ import annotations

import queue
import threading
import time
from collections import defaultdict, deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from zebra_sim_ros.errors import ZebraSimError
from zebra_sim_ros.recording.config import MB
from zebra_sim_ros.recording.writer import BagWriter

_STOP = object()
_SPLIT = object()  # in the queue: what came before it goes into the open file, what comes after into the next
_SNAPSHOT = object()  # in the queue with the cache's messages: written in one piece, into a file of its own


@dataclass
class TopicStats:
    """Per-topic counters."""

    received: int = 0
    written: int = 0
    dropped: int = 0
    paused: int = 0  # received while the recording was paused: not written, not a drop
    taken: int = 0  # snapshot mode: put into the cache (received, not paused, before any error)
    expired: int = 0  # snapshot mode: let go from the cache before a snapshot took it (too old, or no room)
    bytes: int = 0


@dataclass
class RecorderCore:
    """Queue + writer thread around a :class:`BagWriter`."""

    writer: BagWriter
    queue_size: int = 2000
    stats: dict[str, TopicStats] = field(default_factory=lambda: defaultdict(TopicStats))
    error: str | None = None
    write_seconds: float = 0.0  # time the writer thread spent inside BagWriter.write
    paused: bool = False  # while true, offered messages are counted, not queued
    snapshot_bytes: int = 0  # > 0: snapshot mode, a cache of this many bytes of messages written only by snapshot()
    snapshot_ns: int = 0  # snapshot mode: the cache keeps only this much log time before its newest message (0: all)
    snapshots: int = 0  # snapshots written, each a file of its own

    def __post_init__(self) -> None:
        if self.snapshot_bytes < 0 or self.snapshot_ns < 0 or (self.snapshot_ns and not self.snapshot_bytes):
            raise ValueError(f"snapshot_bytes {self.snapshot_bytes} and snapshot_ns {self.snapshot_ns}: both 0 or "
                             "more, and a duration only with a size")
        self._cache: deque[tuple[str, bytes, int, int | None]] = deque()
        self._cache_bytes = 0
        self._cache_newest: int | None = None  # the latest log time the cache has held since the last snapshot
        # unbounded: offer() holds messages to queue_size itself, so a split, a snapshot or the stop never wait
        self._q: queue.Queue[Any] = queue.Queue()
        self._lock = threading.Lock()
        self._closed = False  # close() has begun: no split is taken
        self._thread = threading.Thread(target=self._run, name="bag-writer", daemon=True)
        self._thread.start()
        self.started = time.monotonic()

    def offer(self, topic: str, data: bytes, log_time_ns: int, publish_time_ns: int | None = None) -> bool:
        """Queue one message without blocking; False (and a counted drop) when the queue holds ``queue_size`` or the
        recording has ended, False (counted as paused) while paused. In snapshot mode it goes into the cache instead
        (True, even where the cache lets it go at once: it is counted as expired). ``publish_time_ns``: when it
        arrived (wall clock; None = the log time)."""
        with self._lock:
            s = self.stats[topic]
            s.received += 1
            if self.error is not None:
                s.dropped += 1
                return False
            if self.paused:
                s.paused += 1
                return False
            if self.snapshot_bytes:
                s.taken += 1
                self._cache_put((topic, data, log_time_ns, publish_time_ns))
                return True
            if self._q.qsize() >= self.queue_size:
                s.dropped += 1
                return False
            self._q.put_nowait((topic, data, log_time_ns, publish_time_ns))
            return True

    def _cache_put(self, item: tuple[str, bytes, int, int | None]) -> None:
        """Into the snapshot cache (under the lock); the oldest to arrive go while it holds more than
        ``snapshot_bytes`` or the first is more than ``snapshot_ns`` of log time before the latest it has held. A
        message larger than the whole cache goes at once: it is expired."""
        self._cache.append(item)
        self._cache_bytes += len(item[1])
        newest = self._cache_newest = item[2] if self._cache_newest is None else max(self._cache_newest, item[2])
        while self._cache and (self._cache_bytes > self.snapshot_bytes
                               or (self.snapshot_ns and newest - self._cache[0][2] > self.snapshot_ns)):
            old = self._cache.popleft()
            self._cache_bytes -= len(old[1])
            self.stats[old[0]].expired += 1

    def snapshot(self, timeout: float = 0.5) -> tuple[bool, str]:
        """Snapshot mode: hand the cache to the writer thread (written after what is queued, in one piece, into a file
        of its own that is finished at once) and empty it; waits up to ``timeout`` for the file, as :meth:`split`.
        (True, what was written and where); (True, what is being written) if not finished by then; (False, why)
        outside snapshot mode, once the recording has ended, or where the writing ended it (with what of it was
        written, and where)."""
        if not self.snapshot_bytes:
            return False, "not in snapshot mode"
        made = threading.Event()
        into: list[Path] = []
        done = [0]  # messages of this snapshot written
        with self._lock:  # close() takes the lock too: a snapshot queued is one the writer thread takes
            if (ended := self._ended()) is not None:
                return False, ended
            items, self._cache, size = self._cache, deque(), self._cache_bytes
            self._cache_bytes, self._cache_newest = 0, None
            if not items:
                return True, "the cache is empty: nothing to write"
            self._q.put((_SNAPSHOT, items, made, into, done))  # one item, whatever its size
        times = [t for _, _, t, _ in items]
        what = f"{len(items)} messages ({size / MB:.2f} MB, {(max(times) - min(times)) / 1e9:.2f} s of log time)"
        if not made.wait(timeout) and not made.is_set():
            return True, f"writing {what}"
        where = f" to {', '.join(str(f) for f in into)}" if into else ""
        if done[0] < len(items) or self.error is not None:
            return False, f"{done[0]} of {what} written{where}; the recording has ended: {self.error}"
        return True, f"wrote {what}{where}"

    def _ended(self) -> str | None:
        """Why no split or snapshot is taken any more, or None."""
        if self.error is None and not self._closed:
            return None
        return f"the recording has ended: {self.error or 'the bag is closed'}"

    def split(self, timeout: float = 0.5) -> tuple[bool, str]:
        """Split the bag after what is queued now (as ``ros2 bag record``'s split_bagfile); waits up to ``timeout``
        for the writer thread to make it (the caller's thread, an executor, waits with it). (True, the new file) once
        made; (True, how far behind) if still queued; (False, why) when the recording has ended."""
        if self.snapshot_bytes:
            return False, "snapshot mode writes each snapshot into a file of its own: nothing to split"
        made = threading.Event()
        into: list[Path] = []
        with self._lock:  # as snapshot(): queued only while close() has not queued its stop
            if (ended := self._ended()) is not None:
                return False, ended
            self._q.put((_SPLIT, made, into))
        if not made.wait(timeout) and not made.is_set():
            return True, f"split queued: the writer's queue holds {self._q.qsize()} messages"
        if not into:
            return False, self._ended() or "the recording has ended"
        return True, f"now writing {into[0]}"

    def _run(self) -> None:
        while True:
            item = self._q.get()
            if item is _STOP:
                return
            if item[0] is _SPLIT:
                _, made, into = item
                try:
                    if self.error is None:
                        into.append(self.writer.split())
                except Exception as exc:  # noqa: BLE001 - the recording ends, and the node reports why
                    self._fail(exc)
                finally:
                    made.set()
                continue
            if item[0] is _SNAPSHOT:
                self._write_snapshot(*item[1:])
                continue
            self._write(*item)

    def _write_snapshot(self, items: deque[tuple[str, bytes, int, int | None]], made: threading.Event,
                        into: list[Path], done: list[int]) -> None:
        """A snapshot's messages, into the file(s) they start, finished even where a write ended the recording on
        the way (``into``: those it wrote to; ``done[0]``: the messages written)."""
        first = len(self.writer.files) - (self.writer.open_file is not None)  # the file open now takes it first
        try:
            for message in items:
                done[0] += self._write(*message)
            self.writer.finish_file()  # complete on disk now, whatever came on the way
            if self.error is None:
                self.snapshots += 1
        except Exception as exc:  # noqa: BLE001 - the file could not be finished: the recording ends, and says why
            ended = self.error
            self._fail(exc)
            why = self.error if ended is None else f"{ended}; finishing its file failed too ({exc})"
            self.error = f"{why}; the file is unfinished: use 'zebra-sim bag recover' on it"
        finally:
            into += self.writer.files[first:]
            made.set()

    def _write(self, topic: str, data: bytes, t: int, pt: int | None) -> bool:
        """Write one message; False (a counted drop) once the recording has ended, or where this write ends it."""
        if self.error is not None:  # the recording has ended: what is still queued is dropped, and counted
            with self._lock:
                self.stats[topic].dropped += 1
            return False
        t0 = time.perf_counter()
        try:
            self.writer.write(topic, data, t, pt)
            self.write_seconds += time.perf_counter() - t0
        except Exception as exc:  # noqa: BLE001 - a full disk, the cap, a next file that cannot be opened: it ends
            self._fail(exc)
            with self._lock:
                self.stats[topic].dropped += 1
            return False
        with self._lock:
            s = self.stats[topic]
            s.written += 1
            s.bytes += len(data)
        return True

    def _fail(self, exc: Exception) -> None:
        """End the recording with ``exc``: the thread goes on draining (and counting) what is queued."""
        known = isinstance(exc, (ZebraSimError, OSError))  # their messages say what and where (a full disk, a path)
        self.error = str(exc) if known else f"{type(exc).__name__}: {exc}"

    def close(self, timeout: float = 60.0) -> list[str]:
        """Drain the queue, stop the thread, finalise the bag; returns its files."""
        with self._lock:  # a split or snapshot queued before this is taken; none is queued after it
            self._closed = True
            self._q.put(_STOP)
        self._thread.join(timeout)
        if self._thread.is_alive():  # still draining: drop the rest rather than write while the file is finished
            self.error = self.error or f"the writer did not drain its queue in {timeout:.0f} s; the rest was dropped"
            self._thread.join()
        try:
            files = self.writer.close()
        except OSError as exc:  # the disk is full even for the summary: the chunks on disk stay recoverable
            self.error = (self.error or "") + f"; finalising failed ({exc}); use 'zebra-sim bag recover'"
            files = self.writer.files
        return [str(f) for f in files]

    def totals(self) -> dict[str, Any]:
        """Summary counters over all topics, and the rate written so far."""
        with self._lock:
            per = {t: dict(vars(s)) for t, s in self.stats.items()}
            cached, cached_bytes = len(self._cache), self._cache_bytes
        elapsed = max(time.monotonic() - self.started, 1e-9)
        written = sum(s["bytes"] for s in per.values())
        return {"topics": per, "messages": sum(s["written"] for s in per.values()),
                "dropped": sum(s["dropped"] for s in per.values()), "paused": sum(s["paused"] for s in per.values()),
                "expired": sum(s["expired"] for s in per.values()), "cached": cached,
                "received": sum(s["received"] for s in per.values()), "taken": sum(s["taken"] for s in per.values()),
                "snapshots": self.snapshots,
                "cached_mb": round(cached_bytes / MB, 2),
                "mb_per_s": round(written / elapsed / 1e6, 2),
                "queue": self._q.qsize(), "error": self.error,
                "write_mb_per_s": round(written / max(self.write_seconds, 1e-9) / 1e6, 1)}
