"""Reading bags record by record, so a truncated or corrupt file gives everything before the damage.

:class:`BagReader` streams MCAP records (decompressing chunks) and yields messages with their channel and
schema; when a record cannot be read it stops and keeps where and why in ``stopped``. :func:`summarize` is
``ros2 bag info``; :func:`recover` rewrites the intact part of a damaged bag as a complete, indexed one.
"""

from __future__ import annotations

import functools
import glob
import math
import os
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from mcap.data_stream import ReadDataStream
from mcap.exceptions import RecordLengthLimitExceeded
from mcap.opcode import Opcode
from mcap.records import (
    Attachment,
    AttachmentIndex,
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    McapRecord,
    Message,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)
from mcap.stream_reader import CRCValidationError, StreamReader, breakup_chunk, read_magic
from mcap.summary import Summary
from mcap.writer import Writer

from zebra_sim_ros.errors import ParameterError

# a camera's image: raw, or as image_transport's compressed transport sends it (up --bag-images jpeg records that)
CAMERA_IMAGES = ("image_raw", "image_raw/compressed")


def _stat(path: Path) -> tuple[int, ...]:
    """What tells that a file changed: its device and inode (a file made again at the path), size, and modification
    and change times (ns)."""
    st = os.stat(path)
    return st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns


@functools.cache
def _topic_pattern(kinds: tuple[str, ...]) -> re.Pattern[str]:
    alternatives = "|".join(re.escape(k) for k in kinds)
    return re.compile(rf"^(?P<owner>(?:/[^/]+)+)/(?P<kind>{alternatives})$")


def topic_owner(topic: str, kinds: tuple[str, ...]) -> tuple[str, str] | None:
    """``(owner, kind)`` of a recorded topic ``<owner>/<kind>`` with ``kind`` one of ``kinds`` and the owner one
    name or more (a camera under any namespace: ``/g1/drone_0/image_raw/compressed`` is ``("/g1/drone_0",
    "image_raw/compressed")`` for :data:`CAMERA_IMAGES`); None for any other topic. The owner's last name
    (:func:`last_name`) is the drone that bag scores and summaries group by."""
    match = _topic_pattern(kinds).match(topic)
    return (match.group("owner"), match.group("kind")) if match else None


def under_any_namespace(name: str) -> re.Pattern[str]:
    """A relative topic ``name`` under any graph's namespace (the root's included)."""
    return re.compile(rf"^(?:/[^/]+)*/{re.escape(name)}$")


def topic_filter(names: set[str] | frozenset[str], regex: re.Pattern[str] | None,
                 exclude: re.Pattern[str] | None) -> Callable[[str], bool]:
    """The rule that chooses topics to play or copy, as ``ros2 bag``'s ``--topics``, ``--regex`` and
    ``--exclude-regex``: one of ``names`` where it names any, found by ``regex`` (None: any) and not by
    ``exclude`` (None: none)."""
    def keep(topic: str) -> bool:
        return ((not names or topic in names) and (regex is None or bool(regex.search(topic)))
                and not (exclude is not None and exclude.search(topic)))
    return keep


def last_name(name: str) -> str:
    """The last name of a ROS name: ``/g1/drone_0`` is ``drone_0``."""
    return name.rsplit("/", 1)[-1]


@dataclass(frozen=True)
class BagMessage:
    """One message: topic, schema name (``pkg/msg/Type``), serialized data, times in ns, its channel's metadata."""

    topic: str
    type_name: str
    data: bytes
    log_time: int
    publish_time: int
    metadata: dict[str, str]
    # the records it was written under (what ``recover`` writes again); not part of the message's value
    channel: Channel | None = field(default=None, compare=False, repr=False)
    schema: Schema | None = field(default=None, compare=False, repr=False)


@dataclass
class BagReader:
    """Messages of one or more bag files, in file order (each file in its write order; the files of a split
    recording, ``<name>_<n>.mcap``, in the order of ``n``)."""

    paths: list[Path]
    stopped: list[str] = field(default_factory=list)
    passed_chunks: int = 0  # chunks not opened: every message in them logged before ``pass_before_ns``
    pass_before_ns: int | None = None  # messages()'s ``from_ns``; may be moved on while it reads (a seek forward)
    known_to: dict[int, int] = field(default_factory=dict)  # file index -> bytes read from its start (by this reader
    # or one it took them from, :meth:`carry_from`): the channels and schemas defined there are known
    stats: dict[int, tuple[int, ...]] = field(default_factory=dict)  # file index -> its _stat when opened
    schemas: dict[tuple[int, int], Schema] = field(default_factory=dict)  # (file index, schema id)
    channels: dict[tuple[int, int], Channel] = field(default_factory=dict)

    @classmethod
    def open(cls, paths: list[str | Path] | str | Path, name: str = "bag") -> BagReader:
        """Check the files exist (a folder means every .mcap in it, by :func:`file_order`: ``run_2`` before
        ``run_10``); errors name the parameter ``name``."""
        items = [paths] if isinstance(paths, str | Path) else list(paths)
        files: list[Path] = []
        for item in items:
            p = Path(item)
            if p.is_dir():
                files += sorted(p.glob("*.mcap"), key=file_order)
            elif p.is_file():
                files.append(p)
            else:
                raise ParameterError(name, str(p), "an existing .mcap file or a folder of them")
        if not files:
            raise ParameterError(name, [str(i) for i in items], "at least one .mcap file")
        return cls(files, stats={k: _stat(f) for k, f in enumerate(files)})

    def carry_from(self, older: BagReader) -> BagReader:
        """Take what ``older`` (a reader of the same bags, opened before) has learnt of each file that is still here
        and unchanged (the same :func:`_stat`): its channels, schemas and how far it was read, so that
        :meth:`messages` may pass over chunks read before even in a file without a summary (cut short). A file
        that grew or changed since (a recording still being written) starts from nothing. Returns self."""
        index = {p: j for j, p in enumerate(older.paths)}
        for k, path in enumerate(self.paths):
            j = index.get(path)
            if j is None or older.stats.get(j) != self.stats.get(k):
                continue
            self.channels.update({(k, cid): ch for (i, cid), ch in older.channels.items() if i == j})
            self.schemas.update({(k, sid): sc for (i, sid), sc in older.schemas.items() if i == j})
            if j in older.known_to:
                self.known_to[k] = older.known_to[j]
        return self

    def channel_list(self) -> list[tuple[str, str, dict[str, str]]]:
        """(topic, ``pkg/msg/Type``, channel metadata) of every channel in the files' summaries, without reading
        the messages; files without a readable summary (cut, still being written) contribute nothing."""
        out: dict[str, tuple[str, str, dict[str, str]]] = {}
        for path in self.paths:
            summary = file_summary(path)
            if summary is None:
                continue
            for ch in summary.channels.values():
                sc = summary.schemas.get(ch.schema_id)
                out.setdefault(ch.topic, (ch.topic, sc.name if sc else "", dict(ch.metadata)))
        return list(out.values())

    def messages(self, topics: set[str] | None = None, from_ns: int | None = None) -> Iterator[BagMessage]:
        """Every readable message; with ``from_ns``, a chunk whose messages were all logged before it is passed over
        unread (a seek's shortcut: the file seeks past it, so no read, decompression or CRC of it; counted in
        :attr:`passed_chunks`; the data section's CRC is then not checked in that file), so what
        comes is every message at or after ``from_ns`` and some before it (those sharing a chunk with later ones, and
        any not in a chunk). It is kept in :attr:`pass_before_ns`, which may be changed while reading (a seek forward:
        the chunks from there on before it are passed over). A chunk is passed over only where the channels it may
        define are known: the file has a readable summary that repeats every channel and schema, or this reader (or the
        one it took them from, :meth:`carry_from`) has read past it. A chunk that fails its CRC or does not decompress
        is skipped and noted in :attr:`stopped`, and reading goes on with the next one; damage that breaks the record
        stream itself (a cut file, a bad record length) ends that file's stream, also noted. The channels and schemas
        come from the records as they are read and, where the file has a readable summary, from it first: a damaged
        chunk that held a topic's first definition loses only its own messages. Messages whose channel was never read
        are counted in a note."""
        self.pass_before_ns = from_ns
        for k, path in enumerate(self.paths):
            schemas = {sid: sc for (i, sid), sc in self.schemas.items() if i == k}  # read before
            summary = file_summary(path)
            if summary is not None:
                schemas.update(summary.schemas)
                self.channels.update({(k, cid): ch for cid, ch in summary.channels.items()})
            orphans = 0
            with open(path, "rb") as f:
                try:
                    for rec in self._records(f, k, _defines_all(summary)):
                        if isinstance(rec, Schema):
                            schemas[rec.id] = rec
                            self.schemas[(k, rec.id)] = rec
                        elif isinstance(rec, Channel):
                            self.channels[(k, rec.id)] = rec
                        elif isinstance(rec, Message):
                            ch = self.channels.get((k, rec.channel_id))
                            if ch is None:
                                orphans += 1
                                continue
                            if topics is not None and ch.topic not in topics:
                                continue
                            sc = schemas.get(ch.schema_id)
                            yield BagMessage(ch.topic, sc.name if sc else "", rec.data, rec.log_time, rec.publish_time,
                                             dict(ch.metadata), ch, sc)
                except Exception as exc:  # truncation or corruption: the mcap reader raises several types
                    self.stopped.append(f"{path}: stopped at byte {f.tell()} of {path.stat().st_size} "
                                        f"({type(exc).__name__}: {exc})")
            if orphans:
                self.stopped.append(f"{path}: skipped {orphans} messages of channels whose definition was not read "
                                    f"(it was in a damaged part, and the file has no readable summary)")
            self.schemas.update({(k, sid): sc for sid, sc in schemas.items()})

    def _records(self, f: IO[bytes], k: int, summarised: bool) -> Iterator[McapRecord]:
        """The records of file ``k`` (open as ``f``), as mcap's ``StreamReader`` gives them with ``validate_crcs``,
        every chunk opened in place, less the message indexes (read, not parsed: :meth:`messages` has no use for
        them); but a chunk :meth:`messages` passes over (all its messages before :attr:`pass_before_ns`;
        ``summarised``: the file's summary gave every channel and schema, or this reader knows the file past it) is
        not read, nor the message indexes after it: its header's two times are, and the file seeks past it. The data
        section's CRC covers those bytes, so in a file where a chunk was passed it is not checked (each chunk read
        still checks its own). A damaged chunk is skipped with a note; a record that does not fit in its length is
        damage that ends the stream. Counts the bytes read in :attr:`known_to` as it goes."""
        path = self.paths[k]
        stream = ReadDataStream(f, calculate_crc=True)
        read_magic(stream)
        whole = True  # every byte of the data section so far went through the stream's CRC
        passing = False  # the record before was a chunk passed over (or one of its message indexes)
        while True:
            crc = stream.checksum()  # of everything before this record (what DataEnd's CRC covers)
            opcode, length = stream.read1(), stream.read8()
            if length > _RECORD_LIMIT:
                raise RecordLengthLimitExceeded(opcode, length, _RECORD_LIMIT)
            start, known, until = f.tell(), self.known_to.get(k, 0), self.pass_before_ns
            if passing and opcode == Opcode.MESSAGE_INDEX and start + length <= os.fstat(f.fileno()).st_size:
                f.seek(start + length)
                self.known_to[k] = max(known, start + length)
                continue
            passing = False
            count = stream.count
            if opcode == Opcode.CHUNK and length >= 16:
                first, last = stream.read8(), stream.read8()  # message_start_time, message_end_time
                if (until is not None and last < until and (summarised or start + length <= known)
                        and start + length <= os.fstat(f.fileno()).st_size):
                    f.seek(start + length)
                    self.passed_chunks += 1
                    self.known_to[k] = max(known, start + length)
                    whole, passing = False, True
                    continue
                rec: McapRecord | None = _chunk_after_times(stream, first, last)
            elif opcode == Opcode.MESSAGE:
                if length < _MESSAGE_FIELDS:
                    raise ValueError(f"a message record at byte {start - 9} of {length} bytes, fewer than its "
                                     f"fields' {_MESSAGE_FIELDS}")
                rec = Message.read(stream, length)
            elif opcode == Opcode.MESSAGE_INDEX:
                stream.read(length)
                rec = None
            else:
                rec = read(stream) if (read := _READERS.get(opcode)) else None
            if stream.count - count > length:
                raise ValueError(f"a record (opcode {opcode:#04x}) at byte {start - 9} of {length} bytes whose "
                                 f"fields take {stream.count - count}")
            if length > stream.count - count:  # fields this reader does not know (a later MCAP version), or unknown
                stream.read(length - (stream.count - count))
            if isinstance(rec, DataEnd) and whole and rec.data_section_crc not in (0, crc):
                raise CRCValidationError(expected=rec.data_section_crc, actual=crc, record=rec)
            end = f.tell()  # where the record just read ends
            if isinstance(rec, Chunk):
                try:
                    inner = breakup_chunk(rec, validate_crc=True)
                except Exception as exc:  # noqa: BLE001 - CRC mismatch or a broken compressed payload
                    self.stopped.append(f"{path}: skipped a damaged chunk ending at byte {end} "
                                        f"({rec.message_start_time}..{rec.message_end_time} ns; "
                                        f"{type(exc).__name__}: {exc})")
                    self.known_to[k] = max(known, end)
                    continue
                yield from inner
                self.known_to[k] = max(known, end)  # read to its end (a reader closed within it has not: not counted)
            else:
                self.known_to[k] = max(known, end)
                if rec is not None:
                    yield rec
            if isinstance(rec, Footer):
                read_magic(stream)
                return


def _chunk_after_times(stream: ReadDataStream, first: int, last: int) -> Chunk:
    """The rest of a chunk record whose two times were read (as mcap's ``Chunk.read``, which reads them first)."""
    uncompressed_size, uncompressed_crc = stream.read8(), stream.read4()
    compression = str(stream.read(stream.read4()), "utf-8")
    data = stream.read(stream.read8())
    return Chunk(compression=compression, data=data, message_end_time=last, message_start_time=first,
                 uncompressed_crc=uncompressed_crc, uncompressed_size=uncompressed_size)


_MESSAGE_FIELDS = 22  # channel id, sequence, log and publish times: the bytes of a message record before its data
_RECORD_LIMIT = 4 * 2**30  # as mcap's StreamReader: a longer record is taken as damage, not allocated
_READERS: dict[int, Callable[[ReadDataStream], McapRecord]] = {
    Opcode.ATTACHMENT: Attachment.read, Opcode.ATTACHMENT_INDEX: AttachmentIndex.read, Opcode.CHANNEL: Channel.read,
    Opcode.CHUNK: Chunk.read, Opcode.CHUNK_INDEX: ChunkIndex.read, Opcode.DATA_END: DataEnd.read,
    Opcode.FOOTER: Footer.read, Opcode.HEADER: Header.read, Opcode.METADATA: Metadata.read,
    Opcode.METADATA_INDEX: MetadataIndex.read, Opcode.SCHEMA: Schema.read, Opcode.STATISTICS: Statistics.read,
    Opcode.SUMMARY_OFFSET: SummaryOffset.read,
}  # opcode -> record reader (a chunk, a message and a message index are read in _records)


def _defines_all(summary: Summary | None) -> bool:
    """Whether a file's summary repeats every channel and schema the file defines (a writer may leave them out:
    rosbag2's presets without repeated channels or schemas), as its statistics count them."""
    st = summary.statistics if summary is not None else None
    return (summary is not None and st is not None and len(summary.channels) >= st.channel_count
            and len(summary.schemas) >= st.schema_count)


_PIECE = re.compile(r"(.*)_(\d+)")  # a split recording's file stem: <name>_<n>


def file_order(path: Path) -> tuple[str, int, str]:
    """Sort key of bag files: a split recording's ``<name>_<n>.mcap`` by name, then by the number ``n`` (``run_2``
    before ``run_10``); other names by name."""
    m = _PIECE.fullmatch(path.stem)
    return (m.group(1), int(m.group(2)), path.name) if m else (path.stem, -1, path.name)


def recording_files(path: Path) -> list[Path]:
    """The files of a recording written to ``path``, in the order written: ``path`` itself where it exists and the
    pieces a split made of it (``<stem>_<n>.mcap`` beside it: by size, duration or ``~/split_bagfile``)."""
    pieces = [p for p in path.parent.glob(f"{glob.escape(path.stem)}_*.mcap")
              if (m := _PIECE.fullmatch(p.stem)) is not None and m.group(1) == path.stem]
    return sorted([path] * path.is_file() + pieces, key=file_order)


def file_summary(path: Path) -> Summary | None:
    """The summary section of one MCAP file, or None when it has none that reads (cut short, being written, gone).

    Parsed once per version of the file (kept by path and :func:`_stat`), so that every pass of a looping replay,
    every seek and every report asking again parse nothing, while a file that changed (a recording still being
    written, a file rewritten in place) is read again. Callers must not change what it returns."""
    try:
        version = _stat(path)
    except OSError:
        return None
    return _parsed_summary(os.fspath(path), version)


@functools.lru_cache(maxsize=1024)  # a folder of many split files stays parsed from pass to pass
def _parsed_summary(path: str, version: tuple[int, ...]) -> Summary | None:
    """:func:`file_summary`'s parse, for one version of the file (``version``: its :func:`_stat`)."""
    from mcap.reader import make_reader

    try:
        with open(path, "rb") as f:
            return make_reader(f).get_summary()
    except Exception:  # noqa: BLE001 - a damaged file simply has no usable summary
        return None


def first_log_time(paths: list[Path]) -> int | None:
    """The earliest log time in the files: from their summaries' statistics, and in a file without one (cut short)
    from its chunks' headers (their bytes read, none decompressed) and any message outside a chunk; None for none."""
    times: list[int] = []
    for path in paths:
        summary = file_summary(path)
        if summary is not None and summary.statistics is not None:
            if summary.statistics.message_count:
                times.append(summary.statistics.message_start_time)
            continue
        with open(path, "rb") as f:
            try:
                for rec in StreamReader(f, emit_chunks=True, validate_crcs=False).records:
                    if isinstance(rec, Chunk) and (rec.message_start_time or rec.message_end_time):  # 0, 0: empty
                        times.append(rec.message_start_time)
                    elif isinstance(rec, Message):
                        times.append(rec.log_time)
            except Exception:  # noqa: BLE001 - the cut ends the file: what was read counts
                pass
    return min(times) if times else None


def last_log_time(paths: list[Path]) -> int | None:
    """The latest log time in the files, from their summaries' statistics alone (no chunk read); None where a file
    has none (cut short, still written: its end is not known without reading it all) or no file has a message."""
    ends: list[int] = []
    for path in paths:
        summary = file_summary(path)
        if summary is None or summary.statistics is None:
            return None
        if summary.statistics.message_count:
            ends.append(summary.statistics.message_end_time)
    return max(ends) if ends else None


def summarize(paths: list[str | Path] | str | Path, full: bool = False) -> dict[str, Any]:
    """``ros2 bag info``: files, size, duration, start and end, message count and type per topic.

    Like ``ros2 bag info`` it reads each file's summary section (its statistics), without decompressing a
    single chunk. A file without a readable summary (cut short, still being written) is read message by message
    instead, and so is every file with ``full``: that also checks every chunk's CRC (damage goes to ``damaged``)
    and adds the bytes per topic (``bytes`` is None otherwise). ``read`` lists the files that were read."""
    reader = BagReader.open(paths)
    topics: dict[str, dict[str, Any]] = {}
    times: list[int] = []
    n = 0
    scan: list[Path] = []
    for path in reader.paths:
        summary = None if full else file_summary(path)
        if summary is None or summary.statistics is None:
            scan.append(path)
            continue
        st = summary.statistics
        for channel_id, count in sorted(st.channel_message_counts.items()):
            ch = summary.channels.get(channel_id)
            if ch is None or count == 0:
                continue
            sc = summary.schemas.get(ch.schema_id)
            topics.setdefault(ch.topic, {"type": sc.name if sc else "", "count": 0, "bytes": None})["count"] += count
        if st.message_count:
            times += [st.message_start_time, st.message_end_time]
        n += st.message_count
    stream = BagReader(scan)
    for m in stream.messages():
        t = topics.setdefault(m.topic, {"type": m.type_name, "count": 0, "bytes": 0 if full else None})
        t["count"] += 1
        if full:
            t["bytes"] += len(m.data)
        times.append(m.log_time)
        n += 1
    start, end = (min(times), max(times)) if times else (None, None)
    return {"files": [str(p) for p in reader.paths], "size_bytes": sum(p.stat().st_size for p in reader.paths),
            "messages": n, "start_ns": start, "end_ns": end,
            "duration_s": round((end - start) / 1e9, 3) if start is not None and end is not None else 0.0,
            "topics": dict(sorted(topics.items())), "damaged": stream.stopped, "read": [str(p) for p in scan]}


def recover(src: str | Path, dst: str | Path, compression: str = "zstd") -> dict[str, Any]:
    """Write every intact message of ``src`` (a bag cut short, e.g. by SIGKILL; a file or a folder of split files)
    into a complete bag ``dst``, each under the channel and schema it was written with; ``dst`` appears only once it
    is complete (written beside it, then renamed)."""
    return rewrite(src, dst, compression=compression, library="zebra_sim_ros recover")


def rewrite(src: list[str | Path] | str | Path, dst: str | Path, *, keep: Callable[[str], bool] | None = None,
            start_s: float | None = None, end_s: float | None = None, compression: str = "zstd",
            library: str = "zebra_sim_ros rewrite", names: tuple[str, str, str] = ("start", "end", "OUT")
            ) -> dict[str, Any]:
    """Write the intact messages of the bags ``src`` (files, or folders of split files, in order) whose topic
    ``keep`` takes (all where None) and whose log time lies in [``start_s``, ``end_s``] seconds after the bags'
    first message (either end open where None), into one complete bag ``dst``, each under the channel and schema it
    was written with (per topic and type: the first file's), in the order read (as ``ros2 bag convert`` with a topic
    and time filter). The chunks before ``start_s`` are passed over undecompressed in files whose summary repeats
    their channels. ``dst`` appears only once it is complete (written beside it, then renamed); it may not be one of
    the files read, nor in a folder read (it would join the recording), nor a folder. Errors name ``names`` (the
    start, the end, the output: the caller's words for them). Returns the inputs, ``out``, the messages written in
    all and per topic, the window written (ns; None where nothing was), the chunks passed over and the damage met."""
    from zebra_sim_ros.recording.writer import compression_type

    kind = compression_type(compression)
    for name, v in zip(names[:2], (start_s, end_s), strict=True):
        if v is not None and not (math.isfinite(v) and v >= 0):
            raise ParameterError(name, v, "seconds after the first message: 0 or more")
    if start_s is not None and end_s is not None and end_s < start_s:
        raise ParameterError(names[1], end_s, f"not before {names[0]} ({start_s:g} s)")
    reader = BagReader.open(src)
    out = Path(dst)
    inputs = [src] if isinstance(src, str | Path) else list(src)
    folders = [Path(i).resolve() for i in inputs if Path(i).is_dir()]
    if out.is_dir() or any(out.resolve() == p.resolve() for p in reader.paths) or \
            (out.suffix == ".mcap" and out.resolve().parent in folders):
        raise ParameterError(names[2], str(dst), "a new bag file: not a folder, not one of the bags read, nor in a "
                             "folder read (it would join that recording)")
    from_ns = to_ns = None
    if start_s is not None or end_s is not None:  # the window counts from the first message of them all
        first = first_log_time(reader.paths)
        if first is not None:
            from_ns = first + int(round((start_s or 0.0) * 1e9))
            to_ns = None if end_s is None else first + int(round(end_s * 1e9))
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.{os.getpid()}.tmp")
    n = 0
    topics: dict[str, int] = {}
    lo: int | None = None
    hi: int | None = None
    try:
        with open(tmp, "wb") as f:
            w = Writer(f, compression=kind)
            w.start(profile="ros2", library=library)
            ids: dict[tuple[str, str], int] = {}
            schema_ids: dict[tuple[str, str, bytes], int] = {}
            for m in reader.messages(from_ns=from_ns):
                if (keep is not None and not keep(m.topic)) or (from_ns is not None and m.log_time < from_ns) \
                        or (to_ns is not None and m.log_time > to_ns):
                    continue
                key = (m.topic, m.type_name)
                if key not in ids:
                    sc, ch = m.schema, m.channel
                    assert ch is not None  # every message the reader yields has its channel
                    skey = (sc.name, sc.encoding, sc.data) if sc is not None else ("", "", b"")
                    if skey not in schema_ids:
                        schema_ids[skey] = w.register_schema(*skey) if sc is not None else 0  # 0: no schema
                    ids[key] = w.register_channel(m.topic, ch.message_encoding, schema_ids[skey], m.metadata)
                w.add_message(ids[key], m.log_time, m.data, m.publish_time, sequence=n)
                n += 1
                topics[m.topic] = topics.get(m.topic, 0) + 1
                lo = m.log_time if lo is None else min(lo, m.log_time)
                hi = m.log_time if hi is None else max(hi, m.log_time)
            w.finish()
        tmp.replace(out)
    finally:
        tmp.unlink(missing_ok=True)
    return {"in": str(src) if isinstance(src, str | Path) else [str(p) for p in inputs], "out": str(out),
            "messages": n, "topics": dict(sorted(topics.items())), "start_ns": lo, "end_ns": hi,
            "passed_chunks": reader.passed_chunks, "damage": reader.stopped}
