"""The recorder core: a bounded queue between the subscription callbacks and one writer thread.

Callbacks never touch the disk: :meth:`RecorderCore.offer` puts the serialized message in the queue or, if it
is full, counts a drop for that topic (never silent: drops are in the statistics and the logs); while ``paused``
it counts the message as ``paused`` instead, neither written nor dropped. The writer thread writes in arrival
order; :meth:`RecorderCore.split` queues a split in that order too. A full disk or the size cap ends the
recording: the thread finalises what it can and keeps the error for the node to report.
"""

from __future__ import annotations

import queue
import threading
import time
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from zebra_sim_ros.recording.writer import BagFullError, BagWriter

_STOP = object()
_SPLIT = object()  # in the queue: what came before it goes into the open file, what comes after into the next


@dataclass
class TopicStats:
    """Per-topic counters."""

    received: int = 0
    written: int = 0
    dropped: int = 0
    paused: int = 0  # received while the recording was paused: not written, not a drop
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

    def __post_init__(self) -> None:
        self._q: queue.Queue[Any] = queue.Queue(maxsize=self.queue_size)
        self._lock = threading.Lock()
        self._closed = False  # close() has begun: no split is taken
        self._thread = threading.Thread(target=self._run, name="bag-writer", daemon=True)
        self._thread.start()
        self.started = time.monotonic()

    def offer(self, topic: str, data: bytes, log_time_ns: int, publish_time_ns: int | None = None) -> bool:
        """Queue one message without blocking; False (and a counted drop) when the queue is full or stopped, False
        (counted as paused) while paused. ``publish_time_ns``: when it arrived (wall clock; None = the log time)."""
        with self._lock:
            s = self.stats[topic]
            s.received += 1
            if self.error is not None:
                s.dropped += 1
                return False
            if self.paused:
                s.paused += 1
                return False
            try:
                self._q.put_nowait((topic, data, log_time_ns, publish_time_ns))
            except queue.Full:
                s.dropped += 1
                return False
            return True

    def split(self, timeout: float = 2.0) -> tuple[bool, str]:
        """Split the bag after what is queued now (as ``ros2 bag record``'s split_bagfile); waits up to ``timeout``
        for the writer thread to make it. (True, the new file) once made; (True, how far behind) if still queued;
        (False, why) when the recording has ended or the queue stays full."""
        if self.error is not None or self._closed:
            return False, f"the recording has ended: {self.error or 'the bag is closed'}"
        made = threading.Event()
        into: list[Path] = []
        try:
            self._q.put((_SPLIT, made, into), timeout=timeout)
        except queue.Full:
            return False, f"the writer's queue stayed full for {timeout:g} s: not split"
        if not made.wait(timeout):
            return True, f"split queued behind {self._q.qsize()} messages"
        if not into:
            return False, f"the recording has ended: {self.error}"
        return True, f"now writing {into[0]}"

    def _run(self) -> None:
        while True:
            item = self._q.get()
            if item is _STOP:
                return
            if item[0] is _SPLIT:
                _, made, into = item
                if self.error is None:
                    try:
                        into.append(self.writer.split())
                    except (BagFullError, OSError) as exc:
                        self.error = str(exc)
                made.set()
                continue
            topic, data, t, pt = item
            if self.error is not None:  # the recording has ended: what is still queued is dropped, and counted
                with self._lock:
                    self.stats[topic].dropped += 1
                continue
            t0 = time.perf_counter()
            try:
                self.writer.write(topic, data, t, pt)
                self.write_seconds += time.perf_counter() - t0
            except (BagFullError, OSError) as exc:
                self.error = str(exc)
                with self._lock:
                    self.stats[topic].dropped += 1
                continue
            with self._lock:
                s = self.stats[topic]
                s.written += 1
                s.bytes += len(data)

    def close(self, timeout: float = 60.0) -> list[str]:
        """Drain the queue, stop the thread, finalise the bag; returns its files."""
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
        elapsed = max(time.monotonic() - self.started, 1e-9)
        written = sum(s["bytes"] for s in per.values())
        return {"topics": per, "messages": sum(s["written"] for s in per.values()),
                "dropped": sum(s["dropped"] for s in per.values()), "paused": sum(s["paused"] for s in per.values()),
                "mb_per_s": round(written / elapsed / 1e6, 2),
                "queue": self._q.qsize(), "error": self.error,
                "write_mb_per_s": round(written / max(self.write_seconds, 1e-9) / 1e6, 1)}
