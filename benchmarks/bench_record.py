"""Benchmark: record three drones at 1280x720 (rgb8 + 32FC1 depth + mono16 mask) at 10 Hz over DDS.

Starts three publisher processes (one per drone, each publishing its three image topics at 10 Hz with
stamps and sequence numbers) and the recorder node as separate processes on a private ROS domain, for
``--seconds``; then counts messages published against messages in the bag per topic (drops), the MB/s written,
and the write speed of the recorder's path as a ratio of a plain mcap writer on the same messages in the same
run. Like for like: both write the recorded messages from memory to a file on the same disk, one after the other,
three times, on an otherwise idle machine (median of each): the recorder's path is its core (bounded queue, writer
thread, rosbag2-style BagWriter with schemas and QoS metadata), fed as the node feeds it; the plain writer is the
mcap library's ``Writer`` with one channel per topic. The live recorder's own writer-thread speed while the
publishers ran beside it is reported too.

Every process uses the project's Fast DDS profile (config/fastdds.xml: 100 ms heartbeat), as ``zebra-sim up``
and the launch file do; ``--stock`` runs with Fast DDS's defaults (3 s heartbeat) instead.

    python benchmarks/bench_record.py [--seconds 60] [--compression none] [--stock] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

PUBLISHER = r'''
import sys, time, numpy as np, rclpy
from sensor_msgs.msg import Image
from std_msgs.msg import Header
drone, seconds = sys.argv[1], float(sys.argv[2])
rclpy.init()
node = rclpy.create_node(f"bench_pub_{drone}")
pubs = {k: node.create_publisher(Image, f"/{drone}/{k}", 10) for k in ("image_raw", "depth", "instances")}
rng = np.random.default_rng(0)
arrays = {"image_raw": (rng.integers(0, 255, (720, 1280, 3), dtype=np.uint8), "rgb8", 3),
          "depth": (rng.uniform(1, 100, (720, 1280)).astype("<f4"), "32FC1", 4),
          "instances": (rng.integers(0, 300, (720, 1280)).astype("<u2"), "mono16", 2)}
msgs = {k: Image(height=720, width=1280, encoding=e, is_bigendian=0, step=1280 * b, data=a.tobytes())
        for k, (a, e, b) in arrays.items()}
while any(node.count_subscribers(f"/{drone}/{k}") == 0 for k in pubs):  # all three matched before timing
    time.sleep(0.05)
time.sleep(1.0)
start, n = time.monotonic(), 0
while time.monotonic() - start < seconds:
    now = node.get_clock().now().to_msg()
    for k, m in msgs.items():
        m.header = Header(stamp=now, frame_id=f"{drone}_camera_optical")
        pubs[k].publish(m)
    n += 1
    time.sleep(max(0.0, start + n / 10.0 - time.monotonic()))
print(f"PUBLISHED {drone} {n * 3}", flush=True)
time.sleep(2.0)
node.destroy_node(); rclpy.shutdown()
'''


def _dds_env(stock: bool) -> dict[str, str]:
    """The processes' environment: a private ROS domain on this host, the project's Fast DDS profile unless stock."""
    env = dict(os.environ, ROS_DOMAIN_ID=str(150 + os.getpid() % 50), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
               PYTHONUNBUFFERED="1")
    for var in ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE"):
        env.pop(var, None)
    if not stock:
        env["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(Path(__file__).resolve().parents[1] / "config" / "fastdds.xml")
    return env


def _record_live(tmp: Path, bag: Path, args: argparse.Namespace) -> tuple[int, str]:
    """Run the recorder and three publishers for ``args.seconds``: messages published, the recorder's output."""
    env = _dds_env(args.stock)
    rec = subprocess.Popen([sys.executable, "-m", "zebra_sim_ros.nodes.recorder", "--ros-args", "-p",
                            f"output:={bag}", "-p", f"compression:={args.compression}", "-p", "topic_regex:=^/drone_",
                            "-p", "discovery_period_s:=0.2", "-p", "stats_period_s:=0.0"], env=env,
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)
    (tmp / "pub.py").write_text(PUBLISHER)
    pubs = [subprocess.Popen([sys.executable, str(tmp / "pub.py"), f"drone_{i}", str(args.seconds)], env=env,
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True) for i in range(3)]
    published = 0
    for p in pubs:
        out, _ = p.communicate(timeout=args.seconds + 120)
        m = re.search(r"PUBLISHED \S+ (\d+)", out)
        published += int(m.group(1)) if m else 0
    time.sleep(2.0)
    os.killpg(rec.pid, signal.SIGINT)
    rec_out, _ = rec.communicate(timeout=120)
    return published, rec_out


def _plain_write(msgs: list[Any], path: Path, compression: str) -> float:
    """Seconds the mcap library's plain ``Writer`` takes to write ``msgs`` (one channel per topic) to ``path``."""
    from mcap.writer import Writer

    from zebra_sim_ros.recording.writer import COMPRESSIONS

    t0 = time.perf_counter()
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=4 << 20, compression=COMPRESSIONS[compression])
        w.start(profile="ros2", library="bench")
        sid = w.register_schema("sensor_msgs/msg/Image", "ros2msg", b"")
        chans = {t: w.register_channel(t, "cdr", sid) for t in {msg.topic for msg in msgs}}
        for msg in msgs:
            w.add_message(chans[msg.topic], msg.log_time, msg.data, msg.publish_time)
        w.finish()
    return time.perf_counter() - t0


def _recorder_write(msgs: list[Any], path: Path, compression: str) -> float:
    """Seconds the recorder's core (queue, writer thread, BagWriter) takes to write ``msgs``, fed as the node does."""
    from zebra_sim_ros.recording.qos import profile_dict
    from zebra_sim_ros.recording.recorder import RecorderCore
    from zebra_sim_ros.recording.writer import BagWriter

    t0 = time.perf_counter()
    writer = BagWriter(path, compression, 4 << 20)
    for t in sorted({msg.topic for msg in msgs}):
        writer.add_channel(t, "sensor_msgs/msg/Image", [profile_dict("keep_last", 10, "reliable", "volatile")])
    core = RecorderCore(writer, 2000)
    for msg in msgs:
        while not core.offer(msg.topic, msg.data, msg.log_time):  # a live recorder would count a drop; here: wait
            time.sleep(0.001)
    core.close()
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--compression", default="none")
    ap.add_argument("--stock", action="store_true", help="Fast DDS defaults instead of config/fastdds.xml")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    from zebra_sim_ros.recording.reader import BagReader, summarize

    tmp = Path(tempfile.mkdtemp(prefix="bench_record_"))
    bag = tmp / "bench.mcap"
    published, rec_out = _record_live(tmp, bag, args)
    s = summarize(bag)
    recorded = s["messages"]
    wm = re.search(r"writer ([\d.]+) MB/s", rec_out)
    rec_write = float(wm.group(1)) if wm else 0.0
    msgs = list(BagReader.open(bag).messages())
    per_topic = {t: v["count"] for t, v in s["topics"].items()}
    total_bytes = sum(len(msg.data) for msg in msgs)
    plain_times, core_times = [], []
    for _ in range(3):  # interleaved: the same page cache and disk state for both
        plain_times.append(_plain_write(msgs, tmp / "plain.mcap", args.compression))
        (tmp / "plain.mcap").unlink()
        core_times.append(_recorder_write(msgs, tmp / "core.mcap", args.compression))
        (tmp / "core.mcap").unlink()
    plain = total_bytes / statistics.median(plain_times) / 1e6
    core_speed = total_bytes / statistics.median(core_times) / 1e6
    result = {"benchmark": "record_3_drones", "seconds": args.seconds, "compression": args.compression,
              "dds": "stock" if args.stock else "config/fastdds.xml",
              "published": published, "recorded": recorded, "dropped": published - recorded,
              "mb_per_s_written": round(total_bytes / 1e6 / max(s["duration_s"], 1e-9), 1),
              "per_topic_recorded": per_topic, "live_recorder_writer_mb_per_s": rec_write,
              "recorder_path_mb_per_s": round(core_speed, 1), "plain_writer_mb_per_s": round(plain, 1),
              "ratio_recorder_over_plain": round(core_speed / plain, 2) if plain else None,
              "machine": f"{platform.machine()} cpus={os.cpu_count()}"}
    print(rec_out.strip().splitlines()[-1][:400])
    print(f"published {published}, recorded {recorded}, {result['mb_per_s_written']} MB/s; per topic {per_topic}")
    print(f"live recorder's writer thread: {rec_write} MB/s; same messages from memory, median of 3: recorder path "
          f"{core_speed:.1f} MB/s, plain mcap writer {plain:.1f} MB/s (ratio {result['ratio_recorder_over_plain']})")
    if args.json:
        print(json.dumps(result))
    bag.unlink(missing_ok=True)


if __name__ == "__main__":
    main()
