"""Writing MCAP bags the way rosbag2 does: profile ``ros2``, ``ros2msg`` schemas with every dependency,
``cdr`` messages, ``offered_qos_profiles`` channel metadata, chunk compression, message indexes and summary.

A bag may be split by size or duration into ``<stem>_<k>.mcap`` files (k from 0), each complete on its own, or
on demand (:meth:`BagWriter.split`: a bag not split by size or duration then goes on in ``<stem>_1.mcap``, ...),
and may be capped in total size (``max_bytes``): the write that would pass the cap raises
:class:`BagFullError` and the files written so far stay finalised. The disk is watched the same way: a write that
would leave less free space than the reserve (``reserve_bytes``; by default what the open chunk holds so far, 256 KB
and 1% of what is written: room for that chunk, the indexes and the summary) raises :class:`BagFullError` before
the disk is full, so closing still writes every message accepted so far and the summary.

With ``defer_open`` no file is made until the first message, and :meth:`BagWriter.finish_file` finishes the open
file without starting the next: the next message starts it. That is the recorder's snapshot mode, a complete file
per snapshot and none before the first.
"""

from __future__ import annotations

import errno
import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from mcap.writer import CompressionType, Writer

from zebra_sim_ros.errors import ParameterError, ZebraSimError
from zebra_sim_ros.recording.config import least_cap
from zebra_sim_ros.recording.qos import to_yaml
from zebra_sim_ros.recording.schemas import schema_text

COMPRESSIONS = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}


def compression_type(name: str) -> CompressionType:
    """The chunk compression named ``name`` (zstd, lz4 or none); a ParameterError naming ``compression`` else."""
    if name not in COMPRESSIONS:
        raise ParameterError("compression", name, f"one of {sorted(COMPRESSIONS)}")
    return COMPRESSIONS[name]


class BagFullError(ZebraSimError):
    """The bag reached its size cap, or the disk is full."""


@dataclass
class _Channel:
    topic: str
    type_name: str
    qos_yaml: str
    ids: dict[int, int] = field(default_factory=dict)  # file index -> channel id in that file


class BagWriter:
    """An MCAP bag (possibly split); thread-compatible but not thread-safe: one writer thread."""

    def __init__(self, path: str | Path, compression: str = "zstd", chunk_size: int = 4 << 20,
                 split_bytes: int = 0, split_seconds: float = 0.0, max_bytes: int = 0, reserve_bytes: int = -1,
                 defer_open: bool = False) -> None:
        compression_type(compression)
        if chunk_size < 1024:
            raise ParameterError("chunk_size", chunk_size, ">= 1024 bytes")
        if 0 < max_bytes < least_cap(chunk_size):  # the room write() keeps under the cap (the recorder checks too)
            raise ParameterError("max_bytes", max_bytes, f"0 or at least two chunks and 16 KiB for the summary "
                                 f"({least_cap(chunk_size)} bytes with chunks of {chunk_size})")
        self.path = Path(path)
        if self.path.suffix != ".mcap":  # "run.1" -> "run.1.mcap": another name than "run.2" gets, never the same
            self.path = self.path.with_name(self.path.name + ".mcap")
        self.compression, self.chunk_size = compression, chunk_size
        self.split_bytes, self.split_ns, self.max_bytes = split_bytes, int(split_seconds * 1e9), max_bytes
        self.reserve_bytes = reserve_bytes  # -1: automatic (see the module's docstring); 0: none
        self._unflushed = 0  # bytes in the open chunk (not on disk yet), with a record's overhead each
        self.files: list[Path] = []
        self.channels: dict[str, _Channel] = {}
        self._schemas: dict[str, int] = {}
        self._stream: IO[bytes] | None = None
        self._writer: Writer | None = None
        self._file_start_ns: int | None = None
        self._closed_bytes = 0
        self.messages = 0
        self._idle = defer_open  # no file open, and the next message starts one (False once closed)
        if not defer_open:
            self._open()  # the file exists from the start, as with rosbag2: an empty recording is an empty, valid bag
            return
        try:  # no file yet: its folder is made, and checked, now rather than at the first message
            self.path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ParameterError("output", str(self.path), f"a bag file that can be written ({exc.strerror or exc})") \
                from exc
        if not os.access(self.path.parent, os.W_OK | os.X_OK) or self.path.is_dir():
            raise ParameterError("output", str(self.path), "a bag file that can be written (a writable folder, "
                                 "not a folder itself)")

    def _file_path(self, k: int) -> Path:
        """The bag's ``k``-th file (from 0): ``<stem>_<k>.mcap`` when split by size or duration, else the path given
        for the first and ``<stem>_<k>.mcap`` for those a :meth:`split` starts."""
        split = self.split_bytes > 0 or self.split_ns > 0
        return self.path.with_name(f"{self.path.stem}_{k}.mcap") if split or k > 0 else self.path

    def _open(self) -> None:
        k = len(self.files)
        p = self._file_path(k)
        try:
            p.parent.mkdir(parents=True, exist_ok=True)
            self._stream = open(p, "wb")  # noqa: SIM115 - closed in _close_file
        except OSError as exc:
            if exc.errno == errno.ENOSPC:
                raise BagFullError(f"disk full while opening {p}: {exc}") from exc
            raise ParameterError("output", str(p), f"a bag file that can be written ({exc.strerror or exc})") from exc
        self._writer = Writer(self._stream, chunk_size=self.chunk_size, compression=COMPRESSIONS[self.compression])
        self._writer.start(profile="ros2", library="zebra_sim_ros")
        self._schemas = {}
        self.files.append(p)
        self._file_start_ns = None

    def _close_file(self) -> None:
        """Finish the open file; whatever happens (a full disk), the writer and stream are let go, so a later
        close() does not touch a closed stream."""
        writer, stream = self._writer, self._stream
        self._writer, self._stream = None, None
        if writer is None or stream is None:
            return
        error: OSError | None = None
        try:
            writer.finish()
        except OSError as exc:
            error = exc
        try:
            self._closed_bytes += stream.tell()
            stream.close()  # flushes: a full disk may say so here too
        except OSError as exc:
            error = error or exc
        if error is not None:
            if error.errno == errno.ENOSPC:
                raise BagFullError(f"disk full while finishing {self.files[-1]}: {error}") from error
            raise error

    def add_channel(self, topic: str, type_name: str, qos_profiles: list[dict[str, Any]]) -> None:
        """Declare a topic (``type_name`` like ``sensor_msgs/msg/Image``); its schema text is looked up now."""
        schema_text(type_name)  # fail early for an unknown type
        self.channels[topic] = _Channel(topic, type_name, to_yaml(qos_profiles))

    def _channel_id(self, ch: _Channel) -> int:
        k = len(self.files) - 1
        if k not in ch.ids:
            assert self._writer is not None
            sid = self._schemas.get(ch.type_name)
            if sid is None:
                sid = self._writer.register_schema(name=ch.type_name, encoding="ros2msg",
                                                   data=schema_text(ch.type_name).encode())
                self._schemas[ch.type_name] = sid
            ch.ids[k] = self._writer.register_channel(topic=ch.topic, message_encoding="cdr", schema_id=sid,
                                                      metadata={"offered_qos_profiles": ch.qos_yaml})
        return ch.ids[k]

    @property
    def open_file(self) -> Path | None:
        """The file messages go into now; None before the first (deferred), after :meth:`finish_file` or close."""
        return self.files[-1] if self._writer is not None else None

    @property
    def bytes_written(self) -> int:
        """Bytes on disk so far (closed files plus the open one, up to its last completed chunk)."""
        return self._closed_bytes + (self._stream.tell() if self._stream is not None else 0)

    def write(self, topic: str, data: bytes, log_time_ns: int, publish_time_ns: int | None = None) -> None:
        """Append one serialized (CDR) message of a declared topic."""
        ch = self.channels[topic]
        if self._writer is None and not self._idle:  # closed: reopening would truncate the finished file
            raise RuntimeError(f"write to {self.path} after close()")
        if self.max_bytes:
            # Room kept for the open chunk, the summary and the indexes, so the finished bag stays under the cap.
            written = self.bytes_written
            margin = least_cap(self.chunk_size) + written // 25
            if written + len(data) + margin > self.max_bytes:
                raise BagFullError(f"bag reached its size cap of {self.max_bytes} bytes ({written} written)")
        self._check_free_space(len(data))
        if self._writer is None:  # deferred, or after finish_file(): this message starts the next file
            self._open()
            self._idle = False
        if self._file_start_ns is not None and (
                (self.split_bytes and self._stream is not None and self._stream.tell() >= self.split_bytes)
                or (self.split_ns and log_time_ns - self._file_start_ns >= self.split_ns)):
            self._close_file()
            self._open()
        if self._file_start_ns is None:
            self._file_start_ns = log_time_ns
        assert self._writer is not None
        before = self.bytes_written
        try:
            self._writer.add_message(channel_id=self._channel_id(ch), log_time=log_time_ns, data=data,
                                     publish_time=publish_time_ns if publish_time_ns is not None else log_time_ns,
                                     sequence=self.messages)
        except OSError as exc:
            if exc.errno == errno.ENOSPC:
                raise BagFullError(f"disk full while writing {self.files[-1]}: {exc}") from exc
            raise
        self.messages += 1
        self._unflushed = 0 if self.bytes_written != before else self._unflushed + len(data) + 64

    def split(self) -> Path:
        """Finish the open file and go on in the next (as ``ros2 bag record``'s split_bagfile service); returns its
        path. A file split before any message is an empty, valid bag."""
        if self._writer is None:
            raise RuntimeError(f"split of {self.path} with no file open (" +
                               ("each message starts its next file itself)" if self._idle else "after close())"))
        self._close_file()
        self._open()
        return self.files[-1]

    def finish_file(self) -> Path | None:
        """Finish the open file (complete on disk from now on) without starting the next: the next message starts
        it. Returns the file finished, or None where none was open."""
        if self._writer is None:
            if not self._idle:
                raise RuntimeError(f"finish_file of {self.path} after close()")
            return None
        self._close_file()
        self._idle = True
        return self.files[-1]

    def _check_free_space(self, incoming: int) -> None:
        """BagFullError while there is still room to finish the bag, rather than ENOSPC in the middle of a chunk."""
        reserve = self.reserve_bytes if self.reserve_bytes >= 0 else \
            self._unflushed + (256 << 10) + self.bytes_written // 100
        if reserve == 0:
            return
        folder = self.files[-1].parent if self.files else self.path.parent
        free = shutil.disk_usage(folder).free
        if free < incoming + reserve:
            raise BagFullError(f"disk nearly full at {folder}: {free / 1e6:.2f} MB free, {reserve / 1e6:.2f} MB kept "
                               f"to finish the bag; stopped after {self.messages} messages, all of them kept")

    def close(self) -> list[Path]:
        """Finish the open file (summary, indexes, footer); returns every file of the bag (none where it was
        deferred and never written to)."""
        self._idle = False
        self._close_file()
        return list(self.files)
