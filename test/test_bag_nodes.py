"""recorder and replay as real processes over DDS: round trip, timing, SIGKILL + recover, cut bags, full bags."""

from __future__ import annotations

import os
import re
import signal
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bag_helpers import cut_after_last_chunk, texts
from cli_helpers import CliRun
from mcap.reader import make_reader
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from ros_helpers import Peer, collect_diagnostics, fresh_domain_id, node_process, set_parameter
from rosbag2_interfaces.srv import (
    Burst,
    GetRate,
    IsPaused,
    Pause,
    PlayNext,
    Resume,
    Seek,
    SetRate,
    Snapshot,
    SplitBagfile,
    Stop,
    TogglePaused,
)
from rosbags.highlevel import AnyReader
from sensor_msgs.msg import Image
from std_msgs.msg import Header, String

from zebra_sim_ros.nodes.ros_adapter import stamp
from zebra_sim_ros.recording.qos import profile_dict
from zebra_sim_ros.recording.stamps import stamp_text
from zebra_sim_ros.recording.writer import BagWriter

pytestmark = pytest.mark.integration


@pytest.fixture
def peer():  # type: ignore[no-untyped-def]
    p = Peer(fresh_domain_id())
    yield p
    p.close()


# the recorder's own /diagnostics left out where a test counts what it recorded
ONLY_DATA = {"exclude_regex": "^/(rosout|parameter_events|diagnostics)$"}


def _domain(peer: Peer) -> int:
    return peer.ctx.get_domain_id()


def _image(k: int) -> Image:
    img = Image(header=Header(frame_id="drone_0/camera_optical"), height=48, width=64, encoding="rgb8", step=192,
                data=bytes([k % 256]) * (48 * 192))
    img.header.stamp.sec = 100 + k
    return img


def test_record_a_live_graph_and_read_it_back(peer: Peer, tmp_path: Path) -> None:
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    pub_s = peer.node.create_publisher(String, "/zebra_sim/scene", latched)
    pub_i = peer.node.create_publisher(Image, "/drone_0/image_raw", 10)
    bag = tmp_path / "live.mcap"
    with node_process("recorder", {"output": str(bag), "discovery_period_s": 0.1, **ONLY_DATA}, _domain(peer),
                      tmp_path / "rec.log") as rec:
        subscribed = lambda: all(peer.node.count_subscribers(t) > 0  # noqa: E731
                                 for t in ("/drone_0/image_raw", "/zebra_sim/scene"))
        assert peer.spin(subscribed, 30), (tmp_path / "rec.log").read_text()
        for k in range(20):
            pub_i.publish(_image(k))
            if k % 5 == 0:
                pub_s.publish(String(data=f"scene {k}"))
            peer.spin(lambda: False, 0.05)
        peer.spin(lambda: False, 0.5)
        rec.send_signal(signal.SIGINT)
        assert rec.wait(timeout=30) == 0, (tmp_path / "rec.log").read_text()
    log = (tmp_path / "rec.log").read_text()
    assert "24 messages, 0 dropped" in log  # the statistics printed at exit
    with open(bag, "rb") as f:
        summary = make_reader(f, validate_crcs=True).get_summary()
    assert summary is not None and summary.statistics.message_count == 24
    meta = {c.topic: c.metadata["offered_qos_profiles"] for c in summary.channels.values()}
    assert "transient_local" in meta["/zebra_sim/scene"] and "reliable" in meta["/drone_0/image_raw"]
    with AnyReader([bag]) as r:
        msgs = [(c.topic, r.deserialize(raw, c.msgtype)) for c, _, raw in r.messages()]
    images = [m for t, m in msgs if t == "/drone_0/image_raw"]
    assert [m.header.stamp.sec for m in images] == list(range(100, 120))
    assert all(m.data[0] == k for k, m in enumerate(images))
    assert [m.data for t, m in msgs if t == "/zebra_sim/scene"] == [f"scene {k}" for k in (0, 5, 10, 15)]


def test_sigterm_finalises_the_bag(peer: Peer, tmp_path: Path) -> None:
    # transient local: the recorder subscribes with the offered durability, so messages published before its reader
    # has matched (seen the subscription, not yet the match, on a loaded machine: 6 of 10 recorded) still reach it
    pub = peer.node.create_publisher(String, "/chatter",
                                     QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    bag = tmp_path / "term.mcap"
    with node_process("recorder", {"output": str(bag), "discovery_period_s": 0.1, **ONLY_DATA}, _domain(peer),
                      tmp_path / "rec.log") as rec:
        assert peer.spin(lambda: peer.node.count_subscribers("/chatter") > 0, 30)
        assert bag.exists()  # created at start: an empty recording is an empty, valid bag
        for k in range(10):
            pub.publish(String(data=str(k)))
            peer.spin(lambda: False, 0.02)
        peer.spin(lambda: False, 0.5)
        rec.send_signal(signal.SIGTERM)
        assert rec.wait(timeout=30) == 0
    with open(bag, "rb") as f:
        summary = make_reader(f, validate_crcs=True).get_summary()
    assert summary is not None and summary.statistics.message_count == 10
    assert all("transient_local" in c.metadata["offered_qos_profiles"] for c in summary.channels.values())


def test_sigkill_then_recover(peer: Peer, tmp_path: Path, cli: CliRun) -> None:
    pub = peer.node.create_publisher(Image, "/drone_0/image_raw", 100)
    bag = tmp_path / "killed.mcap"
    with node_process("recorder", {"output": str(bag), "discovery_period_s": 0.1, "chunk_size_mb": 0.05, **ONLY_DATA},
                      _domain(peer), tmp_path / "rec.log") as rec:
        assert peer.spin(lambda: peer.node.count_subscribers("/drone_0/image_raw") > 0, 30)
        for k in range(150):
            pub.publish(_image(k))
            peer.spin(lambda: False, 0.01)
        peer.spin(lambda: False, 1.0)
        os.kill(rec.pid, signal.SIGKILL)
        rec.wait(timeout=10)
    with open(bag, "rb") as f:
        with pytest.raises(Exception):  # noqa: B017 - no summary, no footer: the file is cut
            make_reader(f).get_summary()
    out = cli(["bag", "recover", bag, tmp_path / "ok.mcap", "--json"])
    assert out.returncode == 0, out.stderr
    with open(tmp_path / "ok.mcap", "rb") as f:
        survived = make_reader(f, validate_crcs=True).get_summary().statistics.message_count
    assert 100 <= survived <= 150  # every complete chunk survives; at most the last chunk is lost


def _timed_bag(path: Path, gaps: list[float], pad: int = 0) -> list[int]:
    """Ticks ``tick k`` (``pad`` spaces after: 4096 or more, a chunk each) at the gaps given (s); their log times."""
    w = BagWriter(path, chunk_size=4096)
    w.add_channel("/tick", "std_msgs/msg/String", [profile_dict()])
    t, times = 5_000_000_000, []
    for k, g in enumerate(gaps):
        t += int(g * 1e9)
        w.write("/tick", serialize_message(String(data=f"tick {k}" + " " * pad)), t)
        times.append(t)
    w.close()
    return times


def test_ctrl_c_while_replay_waits_ends_it_at_once_and_cleanly(peer: Peer, tmp_path: Path) -> None:
    """SIGINT while the play thread waits 30 s for the next message: the node ends within seconds, exit status 0,
    without the play thread publishing through a destroyed node ("replay failed")."""
    import time

    _timed_bag(tmp_path / "t.mcap", [0.0, 30.0])
    got: list[str] = []
    peer.node.create_subscription(String, "/tick", lambda m: got.append(m.data), 10)
    log = tmp_path / "replay.log"
    with node_process("replay", {"bags": [str(tmp_path / "t.mcap")], "wait_for_subscribers_s": 20.0, "clock": True,
                                 "clock_rate_hz": 1000.0}, _domain(peer),
                      log) as proc:
        assert peer.spin(lambda: got == ["tick 0"], 60), log.read_text()
        t0 = time.monotonic()
        os.killpg(proc.pid, signal.SIGINT)
        assert proc.wait(timeout=10) == 0, log.read_text()
        assert time.monotonic() - t0 < 8  # not the 30 s it would have waited for the next message
    assert "replay failed" not in log.read_text() and got == ["tick 0"], log.read_text()


@pytest.mark.parametrize("rate", [1.0, 2.0])
def test_replay_keeps_order_and_spacing(peer: Peer, tmp_path: Path, rate: float) -> None:
    gaps = [0.0] + [0.05, 0.15, 0.1, 0.02, 0.2] * 5
    times = _timed_bag(tmp_path / "t.mcap", gaps)
    got: list[tuple[str, float]] = []
    # the time each message reached this process's DDS reader (rmw's reception stamp), not when this test's Python
    # executor got round to it: a test process slowed by load does not move it
    peer.node.create_subscription(
        String, "/tick", lambda m, info: got.append((m.data, info["received_timestamp"] / 1e9)), 100)
    params = {"bags": [str(tmp_path / "t.mcap")], "rate": rate, "wait_for_subscribers_s": 20.0}
    with node_process("replay", params, _domain(peer), tmp_path / "replay.log") as proc:
        assert peer.spin(lambda: len(got) == len(times), 60), (tmp_path / "replay.log").read_text()
        assert proc.wait(timeout=20) == 0
    assert [d for d, _ in got] == [f"tick {k}" for k in range(len(times))]
    assert all(t > 0 for _, t in got)  # the middleware stamps receptions
    # On the timeline: each arrival against its recorded time over the rate, less the run's median offset. A player
    # that falls behind (stalled under load) sends the backlog at once and is back on time, so a stall spoils the few
    # messages inside it, not every gap after it; a wrong rate drifts and a player that ignores the spacing is off by
    # up to the whole bag's length, so both still fail. At most 5 of the 26 may be off by more than 50 ms (one stall
    # of about 0.25 s at rate 2); a burst of the first half second (a clock started before the subscriber wait)
    # would pass where it is shorter than that.
    recorded = (np.array(times) - times[0]) / 1e9 / rate
    arrived = np.array([t for _, t in got]) - got[0][1]
    off = np.abs((arrived - recorded) - np.median(arrived - recorded))
    assert np.median(off) < 0.010 and np.percentile(off, 75) < 0.02, (recorded.round(3), arrived.round(3))
    assert (off > 0.05).sum() <= 5, (recorded.round(3), arrived.round(3))


def test_a_cut_bag_replays_its_first_half_and_says_so(peer: Peer, tmp_path: Path) -> None:
    gaps = [0.0] + [0.002] * 400
    _timed_bag(tmp_path / "full.mcap", gaps)
    data = (tmp_path / "full.mcap").read_bytes()
    (tmp_path / "cut.mcap").write_bytes(data[: len(data) // 2])
    got: list[str] = []
    peer.node.create_subscription(String, "/tick", lambda m: got.append(m.data), 1000)
    params = {"bags": [str(tmp_path / "cut.mcap")], "wait_for_subscribers_s": 20.0}
    with node_process("replay", params, _domain(peer), tmp_path / "replay.log") as proc:
        assert proc.wait(timeout=60) == 0
    log = (tmp_path / "replay.log").read_text()
    played = re.search(r"played (\d+) messages", log)
    assert played and "stopped at byte" in log, log
    # every one of them acknowledged by this side's reader before the node said so; taken here within seconds
    # (a fixed second of spinning once missed the last one on a loaded machine)
    assert peer.spin(lambda: len(got) >= int(played.group(1)), 10), (len(got), log)
    assert len(got) == int(played.group(1))
    assert 50 < len(got) < 401 and got == [f"tick {k}" for k in range(len(got))]


def test_a_looping_cut_bag_counts_its_damage_per_pass_and_keeps_recorded_diagnostics_off_the_live_topic(
        peer: Peer, tmp_path: Path) -> None:
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus

    w = BagWriter(tmp_path / "full.mcap", chunk_size=4096)
    w.add_channel("/tick", "std_msgs/msg/String", [profile_dict()])
    w.add_channel("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray", [profile_dict()])
    for k in range(200):
        t = 1_000_000_000 + k * 2_000_000
        w.write("/tick", serialize_message(String(data=f"tick {k}")), t)
        if k % 20 == 0:  # a recorded node's health, as a recorder writes it
            old = DiagnosticStatus(level=b"\x01", name="recorded: detector", message="from the bag")
            w.write("/diagnostics", serialize_message(DiagnosticArray(status=[old])), t)
    w.close()
    data = (tmp_path / "full.mcap").read_bytes()
    (tmp_path / "cut.mcap").write_bytes(data[: len(data) // 2])
    recorded = collect_diagnostics(peer.node, "recorded: detector")
    live = collect_diagnostics(peer.node, "replay: replay")
    ticks: list[str] = []
    peer.node.create_subscription(String, "/tick", lambda m: ticks.append(m.data), 1000)
    params = {"bags": [str(tmp_path / "cut.mcap")], "loop": True, "rate": 4.0, "diagnostics_period_s": 0.1,
              "wait_for_subscribers_s": 20.0}
    with node_process("replay", params, _domain(peer), tmp_path / "replay.log"):
        # three passes or more: each skips the cut part once, and the count of damage keeps rising across them
        assert peer.spin(lambda: bool(live) and int(live[-1]["values"]["damaged"]) >= 3, 60), \
            (live[-3:], (tmp_path / "replay.log").read_text()[-2000:])
    damaged = [int(s["values"]["damaged"]) for s in live]
    assert damaged == sorted(damaged), damaged  # a total: it never goes down when a pass starts again
    assert any(s["level"] == 1 and "damaged" in s["message"] for s in live), live
    assert ticks and recorded == []  # the bag's ticks played; its /diagnostics kept off the live topic
    assert "not playing the recorded /diagnostics" in (tmp_path / "replay.log").read_text()


def test_a_full_bag_ends_with_a_finalised_file_and_an_error(peer: Peer, tmp_path: Path) -> None:
    pub = peer.node.create_publisher(Image, "/drone_0/image_raw", 100)
    status = collect_diagnostics(peer.node, "recorder: recorder")
    bag = tmp_path / "capped.mcap"
    with node_process("recorder", {"output": str(bag), "discovery_period_s": 0.1, "max_size_mb": 0.3,
                                   "chunk_size_mb": 0.02, "compression": "none", "diagnostics_period_s": 0.2},
                      _domain(peer), tmp_path / "rec.log") as rec:
        assert peer.spin(lambda: peer.node.count_subscribers("/drone_0/image_raw") > 0, 30)
        assert peer.spin(lambda: len(status) > 0, 30), (tmp_path / "rec.log").read_text()  # before it records
        for k in range(200):
            pub.publish(_image(k))
            peer.spin(lambda: False, 0.01)
        assert rec.wait(timeout=30) == 1
    log = (tmp_path / "rec.log").read_text()
    assert "recording ended" in log and "size cap" in log
    # /diagnostics: OK while it recorded, then, before the node exits, one last status that says why it ended
    assert peer.spin(lambda: any(s["level"] == 2 for s in status), 5), status
    assert status[0]["level"] == 0 and status[0]["values"]["output"] == str(bag)
    assert status[-1]["level"] == 2 and "recording ended" in status[-1]["message"] and \
        "size cap" in status[-1]["message"], status[-1]
    levels = [s["level"] for s in status]
    assert all(x == 2 for x in levels[levels.index(2):]), levels  # once ended, it stays an error to the last
    # its own reports, stamped on its wall clock, are logged at the latest image stamp once images came (one time
    # base in the bag: the images' 100..300 s), at its clock only before
    with open(bag, "rb") as f:
        order = [(ch.topic, m.log_time) for _, ch, m in make_reader(f).iter_messages(log_time_order=False)]
    first = next(i for i, (topic, _) in enumerate(order) if topic == "/drone_0/image_raw")
    later = [t for topic, t in order[first:] if topic == "/diagnostics"]
    assert later and all(100 * 10**9 <= t < 300 * 10**9 for t in later), later
    assert 5 < int(status[-1]["values"]["messages"]) < 200
    with open(bag, "rb") as f:
        n = make_reader(f, validate_crcs=True).get_summary().statistics.message_count
    assert 5 < n < 200 and bag.stat().st_size <= 0.3 * (1 << 20)


def test_replay_remap_offset_loop_and_clock(peer: Peer, tmp_path: Path) -> None:
    """The offset skips the first half, looping plays the second again and again under the prefix, with /clock. Started
    paused, a ``~/burst`` of 0 plays one pass (to its end, not on into the next) and the next burst the next pass.
    ``~/stop`` (rosbag2_interfaces/Stop) ends the looping replay, which exits cleanly."""
    import time

    from rosgraph_msgs.msg import Clock

    times = _timed_bag(tmp_path / "t.mcap", [0.0] + [0.05] * 19)  # 20 ticks over 0.95 s
    got: list[str] = []
    clock: list[int] = []
    peer.node.create_subscription(String, "/replayed/tick", lambda m: got.append(m.data), 100)
    peer.node.create_subscription(Clock, "/clock", lambda m: clock.append(m.clock.sec * 10**9 + m.clock.nanosec), 100)
    status = collect_diagnostics(peer.node, "replay: replay")
    burst, resume = _caller(peer, "/replay/burst", Burst), _caller(peer, "/replay/resume", Resume)
    stop = _caller(peer, "/replay/stop", Stop)
    params = {"bags": [str(tmp_path / "t.mcap")], "remap_prefix": "/replayed", "start_offset_s": 0.5, "paused": True,
              "loop": True, "clock": True, "wait_for_subscribers_s": 20.0, "diagnostics_period_s": 0.2}
    log = tmp_path / "replay.log"
    with node_process("replay", params, _domain(peer), log) as proc:
        assert peer.spin(lambda: burst.ready() and bool(status) and status[-1]["message"] == "paused", 30), \
            (status[-1:], log.read_text())
        for passes in (1, 2):
            deadline = time.monotonic() + 10
            while (played := burst(num_messages=0).actually_burst) == 0:  # refused while the pass reads on to its
                assert time.monotonic() < deadline, log.read_text()   # offset
                peer.spin(lambda: False, 0.1)
            assert played == 10, log.read_text()
            assert peer.spin(lambda passes=passes: len(got) == 10 * passes, 10), got
        peer.spin(lambda: False, 0.3)
        assert len(got) == 20  # held at the end of the second pass
        resume()
        assert _says(peer, log, "~/resume", ["resumed"]), log.read_text()
        assert peer.spin(lambda: len(got) >= 35, 30), log.read_text()
        stop()
        assert proc.wait(timeout=10) == 0, log.read_text()  # looping, it would play on
        peer.spin(lambda: False, 0.5)  # what the replay published (flushed before it logged the count) is all in
        assert _said(log, "~/stop") == [f"playback stopped after {len(got)} messages"], (len(got), log.read_text())
    # The offset skips ticks 0..9 (before 0.5 s); looping plays 10..19 again and again.
    assert got[:10] == [f"tick {k}" for k in range(10, 20)] and got[10:20] == got[:10] and got[20:30] == got[:10]
    assert clock and min(clock) >= times[0] and max(clock) <= times[-1]
    assert all(b >= a for a, b in zip(clock[:5], clock[1:6], strict=True))


@pytest.mark.parametrize(("node", "params", "named"), [
    ("recorder", {"max_size_mb": 5.0}, "'max_size_mb'"),  # below two 4 MB chunks: it would end at once
    ("recorder", {"exclude_regex": "(unclosed"}, "'exclude_regex'"),
    ("recorder", {"qos_overrides_path": "/no/such/qos.yaml"}, "'qos_overrides_path'"),
    ("replay", {"bags": ["/no/such.mcap"]}, "'bags'"),
    ("replay", {"bags": ["x.mcap"], "remap_prefix": "/replay/"}, "'remap_prefix'"),
    ("replay", {"bags": ["x.mcap"], "exclude_regex": "[a-"}, "'exclude_regex'"),
    # ticks 0.5 s apart, the last 1.5 s after the first: a window from 2 s holds none
    ("replay", {"bags": ["ticks.mcap"], "start_offset_s": 2.0}, "'start_offset_s' = 2.0 is invalid: allowed a bag "
     "time the bags reach (past the bags' last message at 1970-01-01T00:00:06.500Z (6.500000000), 1.5 s after their "
     "first message)"),
])
def test_a_bad_parameter_stops_the_node_naming_it(tmp_path: Path, node: str, params: dict[str, object],
                                                   named: str) -> None:
    params = {"output": str(tmp_path / "bag.mcap"), **params} if node == "recorder" else params
    if params.get("bags") == ["ticks.mcap"]:  # a real bag, for a check that reads it
        _timed_bag(tmp_path / "ticks.mcap", [0.0, 0.5, 0.5, 0.5])
        params = {**params, "bags": [str(tmp_path / "ticks.mcap")]}
    with node_process(node, params, fresh_domain_id(), tmp_path / "log") as proc:
        assert proc.wait(timeout=60) == 2
    assert named in (tmp_path / "log").read_text()
    assert not (tmp_path / "bag.mcap").exists()  # stopped before creating anything


def test_replay_skips_a_topic_it_cannot_play_and_plays_the_rest(peer: Peer, tmp_path: Path) -> None:
    from mcap.writer import Writer

    bag = tmp_path / "mixed.mcap"
    with open(bag, "wb") as f:
        w = Writer(f)
        w.start(profile="ros2", library="test")
        ok = w.register_channel("/tick", "cdr", w.register_schema("std_msgs/msg/String", "ros2msg", b"string data"))
        odd = w.register_channel("/odd", "cdr", w.register_schema("nope_msgs/msg/Thing", "ros2msg", b"int32 x"))
        left_out = w.register_channel("/tock", "cdr", w.register_schema("std_msgs/msg/String", "ros2msg",
                                                                         b"string data"))
        for k in range(20):
            t = 10**9 + k * 10**7
            w.add_message(odd, t, b"\x00\x01\x00\x00\x07\x00\x00\x00", t)
            w.add_message(ok, t, serialize_message(String(data=f"tick {k}")), t)
            w.add_message(left_out, t, serialize_message(String(data=f"tock {k}")), t)
        w.finish()
    got: list[str] = []
    tocks: list[str] = []
    peer.node.create_subscription(String, "/tick", lambda m: got.append(m.data), 100)
    peer.node.create_subscription(String, "/tock", lambda m: tocks.append(m.data), 100)
    with node_process("replay", {"bags": [str(bag)], "wait_for_subscribers_s": 20.0, "exclude_regex": "^/to"},
                      _domain(peer), tmp_path / "replay.log") as proc:
        assert peer.spin(lambda: peer.node.count_publishers("/tick") > 0, 30)
        assert peer.node.count_publishers("/tock") == 0  # excluded: no publisher, nothing played
        assert proc.wait(timeout=60) == 0
        peer.spin(lambda: len(got) == 20, 10)
    assert got == [f"tick {k}" for k in range(20)] and tocks == []
    assert "cannot play /odd (nope_msgs/msg/Thing)" in (tmp_path / "replay.log").read_text()


def _caller(peer: Peer, name: str, srv: Any) -> Any:
    """A caller of the service ``name`` of type ``srv``: ready() once it answers, call(**fields) its answer to a
    request with those fields."""
    client = peer.node.create_client(srv, name)

    def call(**fields: Any) -> Any:
        future = client.call_async(srv.Request(**fields))
        assert peer.spin(future.done, 30), f"no answer from {name}"
        return future.result()
    call.ready = client.service_is_ready  # type: ignore[attr-defined]
    call.send = lambda **fields: client.call_async(srv.Request(**fields))  # type: ignore[attr-defined]
    return call


def _said(log: Path, service: str) -> list[str]:
    """What the node's log says of each call of ``service`` so far, in order: ``[replay]: ~/pause: paused`` gives
    ``paused``, ``[replay]: ~/play_next refused: not paused: ...`` gives ``refused: not paused: ...`` (rosbag2's
    answers to most of these services are empty or a bare success)."""
    return [f"refused: {why}" if refused else why for refused, why in
            re.findall(rf"\]: {re.escape(service)}( refused)?: (.*)$", log.read_text(), re.MULTILINE)]


def _says(peer: Peer, log: Path, service: str, want: list[str], timeout: float = 10.0) -> bool:
    """Spin until the log's outcomes of ``service`` are ``want``."""
    return peer.spin(lambda: _said(log, service) == want, timeout)


def _send(peer: Peer, pub: Any, numbers: range) -> None:
    """Publish each number as a String, 20 ms apart, spinning the peer between."""
    for k in numbers:
        pub.publish(String(data=str(k)))
        peer.spin(lambda: False, 0.02)


def test_the_recorder_pauses_and_resumes_on_its_services(peer: Peer, tmp_path: Path) -> None:
    """``paused:=true`` and ``~/pause`` / ``~/resume`` / ``~/is_paused`` (rosbag2_interfaces' types, as ros2 bag
    record's) and ``~/toggle_paused``: what arrives while paused is counted (``paused`` on /diagnostics, and at exit),
    not written; what arrives after ~/resume is; the log says whether each call changed the state (a toggle names the
    state it leaves); rosbags reads back exactly the messages sent while it recorded."""
    pub = peer.node.create_publisher(String, "/chatter",
                                     QoSProfile(depth=50, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    status = collect_diagnostics(peer.node, "recorder: recorder")
    pause, resume = _caller(peer, "/recorder/pause", Pause), _caller(peer, "/recorder/resume", Resume)
    toggle = _caller(peer, "/recorder/toggle_paused", TogglePaused)
    is_paused = _caller(peer, "/recorder/is_paused", IsPaused)
    bag, log = tmp_path / "paused.mcap", tmp_path / "rec.log"

    def send(numbers: range) -> None:
        _send(peer, pub, numbers)
        peer.spin(lambda: False, 0.5)
    params = {"output": str(bag), "discovery_period_s": 0.1, "paused": True, "diagnostics_period_s": 0.2, **ONLY_DATA}
    with node_process("recorder", params, _domain(peer), log) as rec:
        assert peer.spin(lambda: peer.node.count_subscribers("/chatter") > 0 and pause.ready() and resume.ready(),
                         30), log.read_text()
        peer.spin(lambda: False, 0.5)
        send(range(0, 5))  # paused from the start
        assert peer.spin(lambda: bool(status) and status[-1]["values"]["paused_messages"] == "5", 10), status[-1:]
        assert status[-1]["message"] == "paused" and status[-1]["values"]["messages"] == "0"
        assert is_paused().paused  # rosbag2_interfaces/IsPaused, as ros2 bag record's
        resume(), resume()
        assert _says(peer, log, "~/resume", ["resumed", "not paused"]), log.read_text()
        assert not is_paused().paused
        send(range(5, 10))
        assert peer.spin(lambda: status[-1]["values"]["messages"] == "5", 10), status[-1:]  # all in before the pause
        pause(), pause()
        assert _says(peer, log, "~/pause", ["paused", "already paused"]), log.read_text()
        send(range(10, 15))
        assert peer.spin(lambda: status[-1]["values"]["paused_messages"] == "10"
                         and status[-1]["values"]["messages"] == "5", 10), status[-1:]
        toggle()
        assert _says(peer, log, "~/toggle_paused", ["resumed"]), log.read_text()  # the other state, named
        send(range(15, 17))
        assert peer.spin(lambda: status[-1]["values"]["messages"] == "7", 10), status[-1:]
        toggle()
        assert _says(peer, log, "~/toggle_paused", ["resumed", "paused"]), log.read_text()
        send(range(17, 18))
        assert peer.spin(lambda: status[-1]["values"]["paused_messages"] == "11", 10), status[-1:]
        rec.send_signal(signal.SIGINT)
        assert rec.wait(timeout=30) == 0, log.read_text()
    assert "7 messages, 0 dropped, 11 while paused" in log.read_text()
    assert texts(bag) == [str(k) for k in (*range(5, 10), 15, 16)]


def test_replay_pauses_where_it_is_and_plays_on_from_there(peer: Peer, tmp_path: Path) -> None:
    """``paused:=true`` and rosbag2_interfaces' ``~/pause``, ``~/resume``, ``~/play_next``, ``~/is_paused``,
    ``~/burst``, ``~/set_rate`` and ``~/get_rate``, as ros2 bag play's: started paused nothing plays (its
    /diagnostics say paused); ``~/play_next`` plays one message at a time (the log names it), /clock moved to its time;
    ``~/burst`` plays the next three at once; a rate of 0 is refused, 1.5 is set; resumed it plays; paused again it
    stops within a message or two, and /clock stands at the bag time reached; a burst of 0 plays the rest at once,
    every message once and in order, and the replay ends; ``~/play_next`` and ``~/burst`` while playing are
    refused."""
    from rosgraph_msgs.msg import Clock

    times = _timed_bag(tmp_path / "t.mcap", [0.0] + [0.1000000013] * 19)  # 20 ticks over 1.9 s, odd nanoseconds
    got: list[str] = []
    clocks: list[int] = []
    peer.node.create_subscription(String, "/tick", lambda m: got.append(m.data), 100)
    peer.node.create_subscription(Clock, "/clock", lambda m: clocks.append(m.clock.sec * 10**9 + m.clock.nanosec), 100)
    status = collect_diagnostics(peer.node, "replay: replay")
    pause, resume = _caller(peer, "/replay/pause", Pause), _caller(peer, "/replay/resume", Resume)
    step = _caller(peer, "/replay/play_next", PlayNext)
    burst, is_paused = _caller(peer, "/replay/burst", Burst), _caller(peer, "/replay/is_paused", IsPaused)
    set_rate, get_rate = _caller(peer, "/replay/set_rate", SetRate), _caller(peer, "/replay/get_rate", GetRate)
    log = tmp_path / "replay.log"
    params = {"bags": [str(tmp_path / "t.mcap")], "paused": True, "wait_for_subscribers_s": 20.0, "clock": True,
              "clock_rate_hz": 50.0, "diagnostics_period_s": 0.2}
    with node_process("replay", params, _domain(peer), log) as proc:
        ready = lambda: pause.ready() and resume.ready() and bool(status)  # noqa: E731
        assert peer.spin(lambda: ready() and status[-1]["message"] == "paused", 30), (status[-1:], log.read_text())
        # past its wait for subscribers, held by the pause
        peer.spin(lambda: False, 1.0)
        assert got == [] and status[-1]["message"] == "paused" and status[-1]["values"]["paused"] == "true"
        played = [f"played /tick at {(t - times[0]) / 1e9:.3f} s of the bag" for t in times]
        for k in range(2):  # one message a call, named in the log, /clock at its time
            assert step().success
            assert _says(peer, log, "~/play_next", played[:k + 1]), log.read_text()
            assert peer.spin(lambda k=k: len(got) == k + 1 and bool(clocks) and clocks[-1] == times[k], 10), \
                (got, clocks)
        peer.spin(lambda: False, 0.5)
        assert got == ["tick 0", "tick 1"] and clocks[-1] == times[1]  # held there again
        assert is_paused().paused and burst(num_messages=3).actually_burst == 3
        assert peer.spin(lambda: len(got) == 5 and clocks[-1] == times[4], 10), (got, clocks[-3:])
        assert not set_rate(rate=0.0).success and get_rate().rate == pytest.approx(1.0)  # rate > 0, as rosbag2's
        assert set_rate(rate=1.5).success and get_rate().rate == pytest.approx(1.5)
        peer.spin(lambda: False, 0.5)
        assert got == [f"tick {k}" for k in range(5)]  # still paused
        resume()
        assert _says(peer, log, "~/resume", ["resumed"]) and not is_paused().paused
        assert peer.spin(lambda: len(got) >= 7, 30), log.read_text()
        assert not step().success
        assert _says(peer, log, "~/play_next", played[:2] + ["refused: not paused: ~/play_next plays while paused"])
        assert burst(num_messages=2).actually_burst == 0
        pause()
        assert _says(peer, log, "~/pause", ["paused"]), log.read_text()
        held = len(got)
        peer.spin(lambda: False, 1.0)
        assert len(got) <= held + 2 < len(times), (held, got)  # at most the ones already on their way
        n, stood = len(got), clocks[-1]
        peer.spin(lambda: False, 0.5)
        assert len(got) == n and clocks[-1] == stood and times[0] <= stood <= times[n]  # /clock holds where it is
        assert burst(num_messages=0).actually_burst == len(times) - n  # 0: the rest of the pass, at once
        assert peer.spin(lambda: len(got) == len(times), 30), (got, log.read_text())
        assert proc.wait(timeout=20) == 0, log.read_text()
    assert got == [f"tick {k}" for k in range(len(times))]
    assert all(b >= a for a, b in zip(clocks, clocks[1:], strict=False)), clocks  # /clock never went back
    assert "set_rate to 0 refused: " in log.read_text() and "burst 0 of 2 messages: not paused" in log.read_text()


def test_a_long_burst_leaves_the_other_services_served_and_a_resume_ends_it(peer: Peer, tmp_path: Path) -> None:
    """``~/burst`` waits for its messages on the executor's second thread: while a whole-pass burst of 100,000
    messages plays, ``~/get_rate``, ``~/is_paused`` and a parameter set are answered and /diagnostics go on, and a
    resume ends the burst short, its answer counting what it played and its log saying why: at once, also where the
    replay is paused again before the burst's thread wakes (two ``~/toggle_paused`` calls back to back)."""
    import time

    _timed_bag(tmp_path / "t.mcap", [0.0] + [0.0002] * 99_999)  # 100,000 ticks over 20 s
    status = collect_diagnostics(peer.node, "replay: replay")
    burst, toggle = _caller(peer, "/replay/burst", Burst), _caller(peer, "/replay/toggle_paused", TogglePaused)
    get_rate, is_paused = _caller(peer, "/replay/get_rate", GetRate), _caller(peer, "/replay/is_paused", IsPaused)
    log = tmp_path / "replay.log"
    params = {"bags": [str(tmp_path / "t.mcap")], "paused": True, "diagnostics_period_s": 0.2}
    with node_process("replay", params, _domain(peer), log):
        ready = lambda: burst.ready() and toggle.ready() and get_rate.ready() and is_paused.ready()  # noqa: E731
        assert peer.spin(lambda: ready() and bool(status) and status[-1]["message"] == "paused", 30), log.read_text()
        deadline = time.monotonic() + 10
        while burst(num_messages=1).actually_burst != 1:  # refused while the play thread reads on to the first tick
            assert time.monotonic() < deadline, log.read_text()
            peer.spin(lambda: False, 0.1)
        answer = burst.send(num_messages=0)  # the rest of the pass
        t, reports = time.monotonic(), len(status)
        assert peer.spin(lambda: len(status) > reports, 5) and not answer.done(), "no /diagnostics during the burst"
        assert get_rate().rate == pytest.approx(1.0) and is_paused().paused and not answer.done()
        assert set_parameter(peer, "/replay", "rate", 2.0).successful and not answer.done()
        resumed = time.monotonic()
        toggles = [toggle.send(), toggle.send()]  # resumed, then paused again (one service's requests: in order)
        assert peer.spin(lambda: answer.done() and all(f.done() for f in toggles), 10), log.read_text()
        took, ended_in = time.monotonic() - t, time.monotonic() - resumed
        played = answer.result().actually_burst
        assert is_paused().paused
    assert 0 < played < 99_999, (played, took)
    assert f"burst {played} of the pass messages: resumed while it played" in log.read_text(), log.read_text()
    assert _said(log, "~/toggle_paused") == ["resumed", "paused"]
    assert ended_in < 3.0, ended_in  # at the resume, not after the 5 s a burst waits for its next message


def test_replay_seeks_back_and_forth_when_start_offset_s_is_set(peer: Peer, tmp_path: Path) -> None:
    """Setting ``start_offset_s`` while playing seeks, as ros2 bag play's seek: paused, a seek forward plays the
    first message at or after that bag time next; a seek back plays again from there, /clock back at the time sought;
    the same value again seeks again. Each tick is a chunk of its own, so a seek forward passes over the chunks
    before it unread, and a seek back among them reads the bags again. ``~/play_next`` while the replay waits for
    subscribers is refused at once, not after its 5 s wait. ``~/seek`` (rosbag2_interfaces/Seek) takes a stamp, and
    refuses one past the last message, as setting ``start_offset_s`` past it is refused; a stamp before the first
    message seeks to it. Resumed, the rest plays in order and the replay ends; its /diagnostics count
    the seeks."""
    import time

    from rosgraph_msgs.msg import Clock

    times = _timed_bag(tmp_path / "t.mcap", [0.0] + [0.1000000013] * 19, pad=4100)  # 20 ticks over 1.9 s
    got: list[str] = []
    clocks: list[int] = []
    peer.node.create_subscription(Clock, "/clock", lambda m: clocks.append(m.clock.sec * 10**9 + m.clock.nanosec), 100)
    status = collect_diagnostics(peer.node, "replay: replay")
    resume, step = _caller(peer, "/replay/resume", Resume), _caller(peer, "/replay/play_next", PlayNext)
    seek_stamp = _caller(peer, "/replay/seek", Seek)
    log = tmp_path / "replay.log"
    params = {"bags": [str(tmp_path / "t.mcap")], "paused": True, "wait_for_subscribers_s": 60.0, "clock": True,
              "clock_rate_hz": 50.0, "diagnostics_period_s": 0.2}

    def seek(to: float) -> int:  # how many /clock messages came before it
        n = len(clocks)
        assert set_parameter(peer, "/replay", "start_offset_s", to).successful
        return n

    def sought(to: float, n: int) -> bool:  # /clock went to the time sought (back too), after the seek
        return times[0] + int(to * 1e9) in clocks[n:]

    with node_process("replay", params, _domain(peer), log) as proc:
        assert peer.spin(lambda: step.ready() and resume.ready() and bool(status), 30), log.read_text()
        assert peer.spin(lambda: "subscribers" in status[-1]["message"], 10), status[-1:]  # no /tick subscriber yet
        t = time.monotonic()
        assert not step().success
        assert time.monotonic() - t < 3.0, "the refusal waited"
        said = ["refused: nothing to play yet (waiting up to 60 s for subscribers)"]
        assert _says(peer, log, "~/play_next", said), log.read_text()
        played = [f"played /tick at {(t - times[0]) / 1e9:.3f} s of the bag" for t in times]
        peer.node.create_subscription(String, "/tick", lambda m: got.append(m.data.rstrip()), 100)
        assert peer.spin(lambda: status[-1]["message"] == "paused", 30), status[-1:]
        for to, k in ((1.0, 10), (0.25, 3), (0.25, 3)):  # forward; back; the same value again
            n = seek(to)
            assert peer.spin(lambda to=to, n=n: sought(to, n), 10), (to, clocks[n:])
            assert step().success
            said.append(played[k])
            assert _says(peer, log, "~/play_next", said), (to, log.read_text())
            assert peer.spin(lambda k=k: clocks[-1] == times[k], 10), (to, clocks[-3:])
        n = seek(1.55)  # forward, past ticks 4-15 (their chunks passed over unread) ...
        assert peer.spin(lambda: sought(1.55, n), 10), clocks[n:]
        seek(0.55)  # ... then back among them, after the last tick read: the bags are read again
        assert step().success
        said.append(played[6])
        assert _says(peer, log, "~/play_next", said), log.read_text()
        # rosbag2_interfaces/Seek takes a stamp: past the last message it is refused, at a message's exact stamp
        # (odd nanoseconds) that message plays next
        assert not seek_stamp(time=stamp(times[-1] + 1)).success
        past = set_parameter(peer, "/replay", "start_offset_s", 1.91)
        assert not past.successful and past.reason == "start_offset_s 1.91 s: past the bags' last message at " \
            f"{stamp_text(times[-1])}, {(times[-1] - times[0]) / 1e9:g} s after the first message played", past.reason
        bad = set_parameter(peer, "/replay", "start_offset_s", "abc")  # validated before it is weighed as a seek
        assert not bad.successful and "'start_offset_s' = 'abc' is invalid" in bad.reason, bad.reason
        n = len(clocks)
        assert seek_stamp(time=stamp(times[0] - 10**9)).success  # a second before the first message: to it
        assert peer.spin(lambda: sought(0.0, n), 10), clocks[n:]
        assert step().success
        said.append("played /tick at 0.000 s of the bag")
        assert _says(peer, log, "~/play_next", said), log.read_text()
        n = len(clocks)
        assert seek_stamp(time=stamp(times[8])).success
        # /clock stands at the time sought (seconds after the first message: within a nanosecond of the stamp) ...
        assert peer.spin(lambda: any(abs(c - times[8]) <= 1 for c in clocks[n:]), 10), clocks[n:]
        assert step().success
        said.append(played[8])
        assert _says(peer, log, "~/play_next", said), log.read_text()
        assert peer.spin(lambda: clocks[-1] == times[8], 10), clocks[-3:]  # ... and at the stamp once it plays
        assert got == ["tick 10", "tick 3", "tick 3", "tick 6", "tick 0", "tick 8"]
        resume()
        assert peer.spin(lambda: len(got) == 17, 30), (got, log.read_text())
        assert proc.wait(timeout=30) == 0, log.read_text()
    assert got == ["tick 10", "tick 3", "tick 3", "tick 6", "tick 0", "tick 8"] + [f"tick {k}" for k in range(9, 20)]
    assert any(s["values"].get("seeks") == "7" for s in status), status[-1:]
    assert "seeking to 0.25 s of the bag" in log.read_text()
    assert f"seek to {stamp_text(times[-1] + 1)} refused: start_offset_s 1.9 s: past the bags' last message at " \
        f"{stamp_text(times[-1])}, {(times[-1] - times[0]) / 1e9:g} s after the first message played" in log.read_text()


def test_a_seek_while_playing_cuts_the_wait_for_a_far_message(peer: Peer, tmp_path: Path) -> None:
    """Playing at rate 1 with the next message 30 s away: a seek to 0.05 s before it plays it within seconds, the
    spacing after it kept, and the replay ends."""
    import time

    _timed_bag(tmp_path / "t.mcap", [0.0, 30.0, 0.2])
    got: list[tuple[str, float]] = []
    peer.node.create_subscription(String, "/tick", lambda m: got.append((m.data, time.monotonic())), 10)
    log = tmp_path / "replay.log"
    with node_process("replay", {"bags": [str(tmp_path / "t.mcap")], "wait_for_subscribers_s": 20.0}, _domain(peer),
                      log) as proc:
        assert peer.spin(lambda: bool(got), 30), log.read_text()
        t = time.monotonic()
        assert set_parameter(peer, "/replay", "start_offset_s", 29.95).successful
        assert peer.spin(lambda: len(got) == 3, 10), (got, log.read_text())
        assert proc.wait(timeout=20) == 0, log.read_text()
    assert [g for g, _ in got] == ["tick 0", "tick 1", "tick 2"]
    assert got[1][1] - t < 5.0, "tick 1 waited for its recorded time"
    assert 0.05 < got[2][1] - got[1][1] < 1.5  # 0.2 s apart, as recorded (received: the peer may lag)


def test_the_recorder_splits_its_bag_on_its_service(peer: Peer, tmp_path: Path) -> None:
    """``~/split_bagfile`` (rosbag2_interfaces/SplitBagfile), as ros2 bag record's: the log names the new file;
    what arrived before goes into the first file, what comes after into the next, each read back alone by rosbags;
    /diagnostics count the files. Its ``~/snapshot``, outside snapshot mode, refuses, the log saying why. Its
    ``qos_overrides_path`` subscribes /chatter volatile with depth 7, where it would take transient local (what the
    publisher offers) and ``qos_depth`` (the graph shows the durability; the depth, which discovery does not carry,
    its log)."""
    pub = peer.node.create_publisher(String, "/chatter",
                                     QoSProfile(depth=50, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    status = collect_diagnostics(peer.node, "recorder: recorder")
    split, snap = _caller(peer, "/recorder/split_bagfile", SplitBagfile), _caller(peer, "/recorder/snapshot", Snapshot)
    bag, log = tmp_path / "run.mcap", tmp_path / "rec.log"
    (tmp_path / "qos.yaml").write_text("/chatter:\n  durability: volatile\n  depth: 7\n")
    params = {"output": str(bag), "discovery_period_s": 0.1, "diagnostics_period_s": 0.2,
              "qos_overrides_path": str(tmp_path / "qos.yaml"), **ONLY_DATA}
    with node_process("recorder", params, _domain(peer), log) as rec:
        assert peer.spin(lambda: peer.node.count_subscribers("/chatter") > 0 and split.ready() and bool(status),
                         30), log.read_text()
        [sub] = peer.node.get_subscriptions_info_by_topic("/chatter")  # discovery carries no depth: the log does
        assert sub.qos_profile.durability == DurabilityPolicy.VOLATILE
        assert "durability=volatile history=keep_last depth=7 (qos_overrides_path)" in log.read_text()
        peer.spin(lambda: False, 0.5)
        _send(peer, pub, range(0, 5))
        assert peer.spin(lambda: status[-1]["values"]["messages"] == "5", 10), status[-1:]
        split()  # rosbag2's SplitBagfile answers nothing: the log names the new file
        assert _says(peer, log, "~/split_bagfile", [f"now writing {tmp_path / 'run_1.mcap'}"]), log.read_text()
        assert not snap().success  # not in snapshot mode: refused, the log says why
        assert _says(peer, log, "~/snapshot", ["refused: not in snapshot mode: snapshot_size_mb is 0, so everything "
                                               "is written as it arrives"]), log.read_text()
        _send(peer, pub, range(5, 8))
        assert peer.spin(lambda: status[-1]["values"]["messages"] == "8" and status[-1]["values"]["files"] == "2",
                         10), status[-1:]
        rec.send_signal(signal.SIGINT)
        assert rec.wait(timeout=30) == 0, log.read_text()
    for path, want in ((bag, range(0, 5)), (tmp_path / "run_1.mcap", range(5, 8))):
        assert texts(path) == [str(k) for k in want]


def test_the_recorder_in_snapshot_mode_writes_the_newest_messages_on_its_service(peer: Peer, tmp_path: Path) -> None:
    """``snapshot_size_mb`` > 0, as ros2 bag record --snapshot-mode: nothing is written as it arrives, and no file is
    made; ``~/snapshot`` (rosbag2_interfaces/Snapshot) writes the newest messages that fit the cache into a file of
    its own, complete at once (rosbags reads back exactly those, in order, while the recorder runs; the log names
    it); the next snapshot goes into the next file; /diagnostics count what arrives, what the cache holds and let go,
    and the snapshots; an empty cache writes nothing; ``~/split_bagfile`` refuses. (Outside snapshot mode
    ``~/snapshot`` refuses: the split test's recorder checks it.)"""
    pub = peer.node.create_publisher(String, "/chatter", QoSProfile(depth=50))
    status = collect_diagnostics(peer.node, "recorder: recorder")
    snap, split = _caller(peer, "/recorder/snapshot", Snapshot), _caller(peer, "/recorder/split_bagfile", SplitBagfile)
    bag, log = tmp_path / "snap.mcap", tmp_path / "rec.log"
    params = {"output": str(bag), "discovery_period_s": 0.1, "diagnostics_period_s": 0.2,
              "snapshot_size_mb": 0.001, **ONLY_DATA}  # 1,048 bytes: nine of these 112-byte messages
    with node_process("recorder", params, _domain(peer), log) as rec:
        assert peer.spin(lambda: peer.node.count_subscribers("/chatter") > 0 and snap.ready() and bool(status),
                         30), log.read_text()
        peer.spin(lambda: False, 0.5)
        for k in range(30):
            pub.publish(String(data=f"{k:03d}" + "x" * 97))
            peer.spin(lambda: False, 0.02)
        assert peer.spin(lambda: status[-1]["values"].get("cached") == "9"
                         and status[-1]["values"].get("expired") == "21", 10), status[-1:]
        assert [status[-1]["values"][k] for k in ("messages", "received", "taken")] == ["0", "30", "30"]
        assert not bag.exists()
        assert snap().success
        assert peer.spin(lambda: len(_said(log, "~/snapshot")) == 1, 10), log.read_text()
        [wrote] = _said(log, "~/snapshot")
        assert wrote.startswith("wrote 9 messages") and wrote.endswith(f"to {bag}"), wrote
        assert [text[:3] for text in texts(bag)] == [f"{k:03d}" for k in range(21, 30)]  # complete: read now
        assert snap().success
        assert _says(peer, log, "~/snapshot", [wrote, "the cache is empty: nothing to write"]), log.read_text()
        split()
        assert _says(peer, log, "~/split_bagfile", ["refused: snapshot mode writes each snapshot into a file of its "
                                                    "own: nothing to split"]), log.read_text()
        pub.publish(String(data="030" + "x" * 97))
        assert peer.spin(lambda: status[-1]["values"]["cached"] == "1", 10), status[-1:]
        assert snap().success
        assert peer.spin(lambda: len(_said(log, "~/snapshot")) == 3, 10), log.read_text()
        assert _said(log, "~/snapshot")[-1].endswith(f"to {tmp_path / 'snap_1.mcap'}"), log.read_text()
        assert peer.spin(lambda: status[-1]["values"]["snapshots"] == "2" and status[-1]["values"]["messages"] == "10",
                         10), status[-1:]
        rec.send_signal(signal.SIGINT)
        assert rec.wait(timeout=30) == 0, log.read_text()
    assert [text[:3] for text in texts(tmp_path / "snap_1.mcap")] == ["030"]
    assert sorted(p.name for p in tmp_path.glob("*.mcap")) == ["snap.mcap", "snap_1.mcap"]  # none left empty


def test_seeks_across_a_damaged_chunk_count_it_once(peer: Peer, tmp_path: Path) -> None:
    """A bag cut short after its last chunk (no summary: its chunks' channels are known only once read) with a
    damaged chunk in the middle: a seek forward past it reads over it (damaged 1), a seek back reads the bags again
    and a seek forward passes over what was read before, the damaged chunk too: /diagnostics keep damaged at 1
    throughout; played on, the cut is found (2: a total that never goes down), and what is intact plays to the
    end. Its ``qos_overrides_path`` publishes /tick transient local (recorded: volatile)."""
    from mcap.reader import make_reader
    from rosgraph_msgs.msg import Clock

    times = _timed_bag(tmp_path / "full.mcap", [0.0] + [0.002] * 199)  # 200 ticks over 0.398 s, 4 KiB chunks
    with open(tmp_path / "full.mcap", "rb") as f:
        chunks = sorted(make_reader(f).get_summary().chunk_indexes, key=lambda c: c.chunk_start_offset)
    bad = chunks[len(chunks) // 3]
    data = bytearray((tmp_path / "full.mcap").read_bytes())
    data[bad.chunk_start_offset + bad.chunk_length // 2] ^= 0xFF
    cut_after_last_chunk(tmp_path / "full.mcap", tmp_path / "hurt.mcap", bytes(data))
    cut_at = (bad.message_end_time - times[0]) / 1e9 + 0.02  # past the damaged chunk
    got: list[str] = []
    clocks: list[int] = []
    peer.node.create_subscription(String, "/tick", lambda m: got.append(m.data), 1000)
    peer.node.create_subscription(Clock, "/clock", lambda m: clocks.append(m.clock.sec * 10**9 + m.clock.nanosec), 100)
    status = collect_diagnostics(peer.node, "replay: replay")
    resume = _caller(peer, "/replay/resume", Resume)
    log = tmp_path / "replay.log"
    (tmp_path / "qos.yaml").write_text("/tick:\n  durability: transient_local\n  depth: 250\n")
    params = {"bags": [str(tmp_path / "hurt.mcap")], "paused": True, "wait_for_subscribers_s": 20.0, "clock": True,
              "clock_rate_hz": 50.0, "diagnostics_period_s": 0.1, "qos_overrides_path": str(tmp_path / "qos.yaml")}
    with node_process("replay", params, _domain(peer), log) as proc:
        assert peer.spin(lambda: resume.ready() and bool(status) and status[-1]["message"] == "paused", 30), \
            log.read_text()
        [tick] = peer.node.get_publishers_info_by_topic("/tick")
        assert tick.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL  # discovery carries no depth
        for to in (cut_at, 0.001, cut_at):
            n = len(clocks)
            assert set_parameter(peer, "/replay", "start_offset_s", to).successful
            assert peer.spin(lambda to=to, n=n: times[0] + int(to * 1e9) in clocks[n:], 10), (to, clocks[n:])
            peer.spin(lambda: False, 0.3)  # /diagnostics at 10 Hz: a count that went down would show
            assert peer.spin(lambda: status[-1]["values"]["damaged"] == "1", 5), (to, status[-1:])
        resume()
        assert proc.wait(timeout=30) == 0, log.read_text()
        peer.spin(lambda: False, 0.5)
    damaged = [int(s["values"]["damaged"]) for s in status]
    assert damaged == sorted(damaged) and damaged[-1] == 2, damaged
    first = next(k for k, t in enumerate(times) if t >= times[0] + int(cut_at * 1e9))
    assert got == [f"tick {k}" for k in range(first, 200)], got[:3]


def test_a_seek_back_among_stamps_out_of_order_plays_again_what_it_should(peer: Peer, tmp_path: Path) -> None:
    """Log times out of order (header stamps in arrival order): after ticks at 0, 0.5 and 0.2 s have played, a seek
    to 0.3 s is a seek back (0.5 s has played), so the next message played is the one at 0.5 s, not 0.6 s."""
    _timed_bag(tmp_path / "t.mcap", [0.0, 0.5, -0.3, 0.4, 0.1])  # 0, 0.5, 0.2, 0.6, 0.7 s
    got: list[str] = []
    peer.node.create_subscription(String, "/tick", lambda m: got.append(m.data), 100)
    step = _caller(peer, "/replay/play_next", PlayNext)
    status = collect_diagnostics(peer.node, "replay: replay")
    log = tmp_path / "replay.log"
    params = {"bags": [str(tmp_path / "t.mcap")], "paused": True, "wait_for_subscribers_s": 20.0,
              "diagnostics_period_s": 0.2}
    with node_process("replay", params, _domain(peer), log):
        assert peer.spin(lambda: step.ready() and bool(status) and status[-1]["message"] == "paused", 30), \
            log.read_text()  # past its wait for subscribers
        assert all(step().success for _ in range(3))
        said = [f"played /tick at {t} s of the bag" for t in ("0.000", "0.500", "0.200")]
        assert _says(peer, log, "~/play_next", said), log.read_text()
        assert set_parameter(peer, "/replay", "start_offset_s", 0.3).successful
        assert step().success
        assert _says(peer, log, "~/play_next", said + ["played /tick at 0.500 s of the bag"]), log.read_text()
        assert peer.spin(lambda: len(got) == 4, 10)
    assert got == ["tick 0", "tick 1", "tick 2", "tick 1"]
