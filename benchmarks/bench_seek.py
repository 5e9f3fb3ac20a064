"""Benchmark: the replay's seek back, reading the bag again from its start against passing over the chunks before
the time sought (``BagReader.messages(from_ns=...)``).

Writes a zstd bag like a recorded run's (``bench_bag_info``'s: three drones, 1280x720 rgb8 images, labels, 10 Hz)
of about ``--mb`` MB, then times how long each way takes to reach the first message at ``--at`` of the bag's
duration (a seek there), ``--repeat`` times each, alternating, and reports the medians and their ratio; the same
for the bag cut short after its last chunk (no summary), where a reader that takes what a first pass learnt
(``carry_from``) passes over the chunks it read. Every way must give the same messages from there on. Last, what a
seek asks of the summaries (the bags' first and last log times: is the time sought in them?), parsed afresh
against parsed once per version of the file (``file_summary``'s cache, which the timings above also use).

    python benchmarks/bench_seek.py [--mb 300] [--at 0.9] [--repeat 5] [--json]
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from bench_bag_info import write_bag
from mcap.reader import make_reader

from zebra_sim_ros.recording import reader as bag_reader
from zebra_sim_ros.recording.reader import BagReader


def reach(reader: BagReader, at_ns: int, pass_over: bool) -> tuple[float, list[int]]:
    """Seconds until the first message at or after ``at_ns`` comes; and the log times of the ten from there."""
    t0 = time.perf_counter()
    stream = reader.messages(from_ns=at_ns if pass_over else None)
    first = next(m for m in stream if m.log_time >= at_ns)
    took = time.perf_counter() - t0
    times = [first.log_time] + [m.log_time for _, m in zip(range(9), stream, strict=False)]
    return took, times


def span_check(paths: list[Path], fresh: bool) -> tuple[float, list[int]]:
    """Seconds to learn the bags' first and last log times from their summaries, as a seek does (``fresh``: every
    summary parsed again, as before the cache); and the two times."""
    if fresh:
        bag_reader._parsed_summary.cache_clear()
    t0 = time.perf_counter()
    first, last = bag_reader.first_log_time(paths), bag_reader.last_log_time(paths)
    took = time.perf_counter() - t0
    return took, [first or 0, last or 0]


def median_pair(a: Callable[[], tuple[float, list[int]]], b: Callable[[], tuple[float, list[int]]],
                repeat: int) -> tuple[float, float]:
    """Medians of ``a`` and ``b`` timed in turn; both must give the same messages."""
    ta, tb = [], []
    for _ in range(repeat):
        sa, ma = a()
        sb, mb = b()
        if ma != mb:
            raise SystemExit(f"the two ways disagree: {ma} against {mb}")
        ta.append(sa)
        tb.append(sb)
    return statistics.median(ta), statistics.median(tb)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mb", type=float, default=300.0)
    ap.add_argument("--at", type=float, default=0.9, help="where to seek, as a fraction of the bag's duration")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path, cut = Path(tmp) / "run.mcap", Path(tmp) / "cut.mcap"
        steps = write_bag(path, args.mb)
        with open(path, "rb") as f:
            summary = make_reader(f).get_summary()
        assert summary is not None and summary.statistics is not None
        st = summary.statistics
        at_ns = st.message_start_time + int(args.at * (st.message_end_time - st.message_start_time))
        last = max(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
        with open(path, "rb") as src, open(cut, "wb") as dst:
            dst.write(src.read(last.chunk_start_offset + last.chunk_length))
        whole, passing = median_pair(lambda: reach(BagReader.open(path), at_ns, False),
                                     lambda: reach(BagReader.open(path), at_ns, True), args.repeat)
        first_pass = BagReader.open(cut)
        list(first_pass.messages())  # what the replay's first pass leaves: every chunk read
        cut_whole, cut_passing = median_pair(lambda: reach(BagReader.open(cut), at_ns, False),
                                             lambda: reach(BagReader.open(cut).carry_from(first_pass), at_ns, True),
                                             args.repeat)
        fresh, cached = median_pair(lambda: span_check([path], True), lambda: span_check([path], False),
                                    args.repeat)
        result = {"machine": f"{platform.machine()} {platform.processor() or ''}".strip(), "steps": steps,
                  "chunks": len(summary.chunk_indexes), "bag_mb": round(path.stat().st_size / 1e6, 1),
                  "at": args.at, "reread_s": round(whole, 3), "pass_over_s": round(passing, 3),
                  "speedup": round(whole / passing, 1), "cut_reread_s": round(cut_whole, 3),
                  "cut_pass_over_s": round(cut_passing, 3), "cut_speedup": round(cut_whole / cut_passing, 1),
                  "span_fresh_ms": round(fresh * 1e3, 3), "span_cached_ms": round(cached * 1e3, 3),
                  "span_speedup": round(fresh / cached, 1)}
    print(f"bag {result['bag_mb']} MB, {result['chunks']} chunks, seek to {args.at:.0%}: reading again from the "
          f"start {result['reread_s']} s, passing over the chunks before {result['pass_over_s']} s "
          f"({result['speedup']}x); cut short (no summary), after a first pass: {result['cut_reread_s']} s against "
          f"{result['cut_pass_over_s']} s ({result['cut_speedup']}x); a seek's look at the summaries: "
          f"parsed again {result['span_fresh_ms']} ms, parsed once {result['span_cached_ms']} ms "
          f"({result['span_speedup']}x); medians of {args.repeat}")
    if args.json:
        print(json.dumps(result))


if __name__ == "__main__":
    main()
