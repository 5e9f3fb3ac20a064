"""Bags for the recording tests: read back by rosbags (an independent reader), or cut short as a kill leaves them."""

from __future__ import annotations

from pathlib import Path

from mcap.reader import make_reader
from rosbags.highlevel import AnyReader


def texts(path: Path) -> list[str]:
    """The data of every std_msgs/String in the bag file ``path``, as rosbags reads them."""
    with AnyReader([path]) as r:
        return [r.deserialize(raw, c.msgtype).data for c, _, raw in r.messages()]


def cut_after_last_chunk(src: Path, dst: Path, data: bytes | None = None) -> None:
    """Write ``src`` (or ``data``, its bytes altered) to ``dst`` up to the end of its last chunk: every chunk, no
    message index, summary or footer (a recording killed just after a chunk)."""
    with open(src, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    last = max(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    dst.write_bytes((src.read_bytes() if data is None else data)[:last.chunk_start_offset + last.chunk_length])
