"""Benchmark: `zebra-sim bag info` from the files' summaries against reading every message (`--full`).

Writes a zstd bag like a recorded run's (three drones, 1280x720 rgb8 images of smooth shading with sensor noise,
labels as JSON strings, 10 Hz) of about ``--mb`` MB compressed, then times :func:`summarize` both ways,
``--repeat`` times each, alternating, and reports the medians and their ratio; both must agree on messages,
duration and counts.

    python benchmarks/bench_bag_info.py [--mb 500] [--repeat 3] [--json]
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Image
from std_msgs.msg import Header, String

from zebra_sim_ros.recording.qos import profile_dict
from zebra_sim_ros.recording.reader import summarize
from zebra_sim_ros.recording.writer import BagWriter


def write_bag(path: Path, mb: float) -> int:
    """A bag of roughly ``mb`` MB; returns the number of steps written."""
    rng = np.random.default_rng(0)
    w = BagWriter(path)
    drones = ("drone_0", "drone_1", "drone_2")
    for d in drones:
        w.add_channel(f"/{d}/image_raw", "sensor_msgs/msg/Image", [profile_dict()])
        w.add_channel(f"/{d}/labels", "std_msgs/msg/String", [profile_dict()])
    # Smooth shading plus a little sensor noise, so zstd compresses it about as much as a rendered frame.
    yy, xx = np.mgrid[0:720, 0:1280]
    shade = (np.stack([xx / 5, yy / 3, (xx + yy) / 8], -1) % 256).astype(np.int16)
    base = np.clip(shade + rng.integers(-6, 7, shade.shape), 0, 255).astype(np.uint8)
    step = 0
    while w.bytes_written < mb * 1e6:
        t = 1_000_000_000 + step * 100_000_000
        for k, d in enumerate(drones):
            pixels = np.roll(base, step * 7 + k * 101, axis=1)
            img = Image(header=Header(frame_id=f"{d}_camera_optical"), height=720, width=1280, encoding="rgb8",
                        step=3840, data=pixels.tobytes())
            img.header.stamp.sec, img.header.stamp.nanosec = divmod(t, 1_000_000_000)
            w.write(f"/{d}/image_raw", serialize_message(img), t)
            w.write(f"/{d}/labels", serialize_message(String(data=json.dumps({"stamp": t, "zebras": []}))), t)
        step += 1
    w.close()
    return step


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mb", type=float, default=500.0)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "run.mcap"
        steps = write_bag(path, args.mb)
        fast_s, full_s = [], []
        fast = full = None
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            fast = summarize(path)
            fast_s.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            full = summarize(path, full=True)
            full_s.append(time.perf_counter() - t0)
        assert fast is not None and full is not None
        same = all(fast[k] == full[k] for k in ("messages", "start_ns", "end_ns", "duration_s"))
        same &= {t: v["count"] for t, v in fast["topics"].items()} == {t: v["count"] for t, v in full["topics"].items()}
        if not same or fast["read"]:
            raise SystemExit("the summary path and the full read disagree")
        result = {"machine": f"{platform.machine()} {platform.processor() or ''}".strip(), "steps": steps,
                  "messages": fast["messages"], "bag_mb": round(path.stat().st_size / 1e6, 1),
                  "summary_ms": round(statistics.median(fast_s) * 1e3, 2),
                  "full_s": round(statistics.median(full_s), 3),
                  "speedup": round(statistics.median(full_s) / statistics.median(fast_s), 1)}
    print(f"bag {result['bag_mb']} MB, {result['messages']} messages: info from the summary "
          f"{result['summary_ms']} ms, reading everything {result['full_s']} s ({result['speedup']}x), "
          f"median of {args.repeat}")
    if args.json:
        print(json.dumps(result))


if __name__ == "__main__":
    main()
