"""Bags written the way rosbag2 does, read back by independent readers; recovery; scores from a bag."""

from __future__ import annotations

import io
import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bag_helpers import cut_after_last_chunk, texts
from cli_helpers import CliRun
from mcap.reader import make_reader
from rclpy.serialization import serialize_message
from rosbags.highlevel import AnyReader
from sensor_msgs.msg import Image
from std_msgs.msg import Header, String

import zebra_sim_ros.recording.reader as reader_module
from zebra_sim_ros.recording.cdr import cdr_string
from zebra_sim_ros.recording.evaluate import collect, score
from zebra_sim_ros.recording.qos import from_yaml, profile_dict, replay_profile, to_yaml
from zebra_sim_ros.recording.reader import (
    CAMERA_IMAGES,
    BagMessage,
    BagReader,
    last_name,
    recover,
    summarize,
    topic_owner,
)
from zebra_sim_ros.recording.schemas import schema_text
from zebra_sim_ros.recording.writer import BagFullError, BagWriter


def _write(path: Path, n: int = 50, **kw: object) -> list[Path]:
    w = BagWriter(path, chunk_size=16 * 1024, **kw)  # type: ignore[arg-type]
    w.add_channel("/text", "std_msgs/msg/String", [profile_dict(durability="transient_local", depth=1)])
    w.add_channel("/image", "sensor_msgs/msg/Image", [profile_dict(reliability="best_effort", depth=5)])
    for i in range(n):
        t = 1_000_000_000 + i * 100_000_000
        w.write("/text", serialize_message(String(data=f"message {i}")), t)
        img = Image(header=Header(frame_id="cam"), height=20, width=30, encoding="rgb8", step=90,
                    data=bytes([i % 256]) * 1800)
        img.header.stamp.sec, img.header.stamp.nanosec = divmod(t, 1_000_000_000)
        w.write("/image", serialize_message(img), t)
    return w.close()


def test_schema_text_holds_every_dependency() -> None:
    text = schema_text("sensor_msgs/msg/CameraInfo")
    assert text.startswith("# This message defines meta information for a camera.")
    assert "=" * 80 + "\nMSG: std_msgs/Header\n" in text
    assert "MSG: builtin_interfaces/Time" in text and "MSG: sensor_msgs/RegionOfInterest" in text
    assert text.count("MSG: builtin_interfaces/Time") == 1


def test_round_trip_with_independent_readers(tmp_path: Path) -> None:
    [path] = _write(tmp_path / "a.mcap")
    with open(path, "rb") as f:  # the mcap library's own reader: summary, indexes, CRCs
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        assert reader.get_header().profile == "ros2"
        assert summary is not None and summary.statistics.message_count == 100
        assert {c.topic: c.message_encoding for c in summary.channels.values()} == {"/text": "cdr", "/image": "cdr"}
        assert {s.name: s.encoding for s in summary.schemas.values()} == {"std_msgs/msg/String": "ros2msg",
                                                                         "sensor_msgs/msg/Image": "ros2msg"}
        assert summary.chunk_indexes and all(ci.message_index_offsets for ci in summary.chunk_indexes)
        assert len(list(reader.iter_messages())) == 100
        qos = {c.topic: from_yaml(c.metadata["offered_qos_profiles"]) for c in summary.channels.values()}
        assert qos["/text"][0]["durability"] == "transient_local" and qos["/image"][0]["reliability"] == "best_effort"
    with AnyReader([path]) as r:  # rosbags: parses our schema texts to deserialize
        seen = [(c.topic, t, r.deserialize(raw, c.msgtype)) for c, t, raw in r.messages()]
    texts = [m.data for topic, _, m in seen if topic == "/text"]
    assert texts == [f"message {i}" for i in range(50)]
    images = [(t, m) for topic, t, m in seen if topic == "/image"]
    assert all(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec == t for t, m in images)
    assert images[7][1].data[0] == 7


def test_a_point_cloud_in_a_bag_reads_back_with_rosbags(tmp_path: Path) -> None:
    """The cameras' organised PointCloud2 (``points_stride``) in an MCAP bag: rosbags parses its schema (PointField's
    constants included) and its fields give back the points, NaN and packed colour."""
    from zebra_sim_ros.nodes.ros_adapter import point_cloud_msg

    rng = np.random.default_rng(5)
    points = rng.uniform(-5, 5, (3, 4, 3)).astype(np.float32)
    points[0, 1] = np.nan  # sky
    rgb = rng.integers(0, 256, (3, 4, 3), dtype=np.uint8)
    msg = point_cloud_msg(Header(frame_id="drone_0/camera_optical"), points, rgb)
    msg.header.stamp.sec = 7
    w = BagWriter(tmp_path / "p.mcap")
    w.add_channel("/drone_0/points", "sensor_msgs/msg/PointCloud2", [profile_dict()])
    w.write("/drone_0/points", serialize_message(msg), 7 * 10**9)
    [path] = w.close()
    with AnyReader([path]) as r:
        [(c, raw)] = [(c, raw) for c, _, raw in r.messages()]
        back = r.deserialize(raw, c.msgtype)
    assert (back.height, back.width, back.point_step, back.row_step) == (3, 4, 16, 64) and not back.is_dense
    assert [(f.name, f.offset, f.datatype, f.count) for f in back.fields] == \
        [("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("rgb", 12, 7, 1)]
    cloud = np.frombuffer(bytes(back.data), dtype="<f4").reshape(3, 4, 4)
    assert np.array_equal(cloud[..., :3], points, equal_nan=True)
    packed = cloud[..., 3].view("<u4")
    assert np.array_equal(np.stack([packed >> 16, (packed >> 8) & 255, packed & 255], axis=-1), rgb)


def test_split_by_size_and_duration(tmp_path: Path) -> None:
    files = _write(tmp_path / "s.mcap", n=200, split_bytes=40_000, compression="none")
    assert len(files) > 2 and all(p.name.startswith("s_") for p in files)
    s = summarize(tmp_path)  # a folder of split files reads as one bag
    assert s["messages"] == 400 and s["topics"]["/text"]["count"] == 200 and not s["damaged"]
    assert s["read"] == [] and s["topics"]["/text"]["bytes"] is None  # from the summaries: nothing decompressed
    full = summarize(tmp_path, full=True)  # every message read: the same figures, plus bytes
    assert full["read"] == s["files"] and full["topics"]["/image"]["bytes"] > 0
    assert {k: full[k] for k in ("messages", "start_ns", "end_ns", "duration_s")} == \
        {k: s[k] for k in ("messages", "start_ns", "end_ns", "duration_s")}
    assert {t: v["count"] for t, v in full["topics"].items()} == {t: v["count"] for t, v in s["topics"].items()}
    for p in files:
        with open(p, "rb") as f:
            assert make_reader(f).get_summary() is not None  # every piece is complete on its own
    files[-1].write_bytes(files[-1].read_bytes()[: files[-1].stat().st_size // 2])  # the last piece cut short
    cut = summarize(tmp_path)
    assert cut["read"] == [str(files[-1])] and len(cut["damaged"]) == 1 and 300 < cut["messages"] < 400
    files = _write(tmp_path / "d" / "d.mcap", n=60, split_seconds=2.0)
    assert len(files) == 3


def test_size_cap_ends_with_a_finalised_bag(tmp_path: Path) -> None:
    w = BagWriter(tmp_path / "c.mcap", chunk_size=4096, max_bytes=60_000)
    w.add_channel("/text", "std_msgs/msg/String", [profile_dict()])
    written = 0
    with pytest.raises(BagFullError, match="size cap"):
        for i in range(100_000):
            w.write("/text", serialize_message(String(data="x" * 200 + str(i))), 10**9 + i)
            written += 1
    [path] = w.close()
    assert path.stat().st_size <= 60_000
    with open(path, "rb") as f:
        assert make_reader(f).get_summary().statistics.message_count == written
    finished = path.read_bytes()
    with pytest.raises(RuntimeError, match="after close"):  # a late write must not reopen (and truncate) the bag
        w.write("/text", serialize_message(String(data="late")), 2 * 10**9)
    assert path.read_bytes() == finished


def test_a_cap_under_two_chunks_is_refused_by_name(tmp_path: Path) -> None:
    """The writer keeps two chunks and 16 KiB under its cap, so a smaller cap is refused when the bag is opened
    (naming it and the least it takes), not by a BagFullError on the first message."""
    from zebra_sim_ros.errors import ParameterError

    with pytest.raises(ParameterError, match=r"'max_bytes' = 1500000.*2113536 bytes with chunks of 1048576"):
        BagWriter(tmp_path / "c.mcap", chunk_size=1 << 20, max_bytes=1_500_000)
    assert not (tmp_path / "c.mcap").exists()
    # the recorder's parameters and the writer hold to one rule: the least cap passes both, a little less neither
    from zebra_sim_ros.recording.config import MB, RecorderConfig, least_cap

    least = least_cap(MB // 2)
    assert RecorderConfig.from_params({"chunk_size_mb": 0.5, "max_size_mb": least / MB}).max_size_mb == least / MB
    BagWriter(tmp_path / "ok.mcap", chunk_size=MB // 2, max_bytes=least).close()
    with pytest.raises(ParameterError, match="'max_size_mb'"):
        RecorderConfig.from_params({"chunk_size_mb": 0.5, "max_size_mb": (least - 1024) / MB})
    with pytest.raises(ParameterError, match="'max_bytes'"):
        BagWriter(tmp_path / "no.mcap", chunk_size=MB // 2, max_bytes=least - 1)


def test_output_names_never_collide_and_an_unwritable_one_is_named(tmp_path: Path) -> None:
    """``run.1`` and ``run.2`` are two bags (``.mcap`` is added to the name, not put in place of ``.1``); an output
    that cannot be opened is a ParameterError naming ``output``."""
    from zebra_sim_ros.errors import ParameterError

    paths = []
    for k in (1, 2):
        w = BagWriter(tmp_path / f"run.{k}")
        w.add_channel("/text", "std_msgs/msg/String", [profile_dict()])
        w.write("/text", serialize_message(String(data=f"bag {k}")), 10**9)
        paths += w.close()
    assert [p.name for p in paths] == ["run.1.mcap", "run.2.mcap"]
    for k, p in enumerate(paths, 1):
        assert [m.data for m in BagReader.open(p).messages()] == [serialize_message(String(data=f"bag {k}"))]
    (tmp_path / "a_file").write_text("x")
    with pytest.raises(ParameterError, match=r"'output'.*a_file/x\.mcap.*can be written"):
        BagWriter(tmp_path / "a_file" / "x.mcap")


def test_a_full_disk_at_a_split_is_a_bag_full_error_and_close_still_works(tmp_path: Path,
                                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """The disk fills while a split file is finished: the write says BagFullError (the recorder ends the recording
    on it), and close() afterwards returns the files instead of failing on a closed stream."""
    import errno

    from mcap.writer import Writer

    w = BagWriter(tmp_path / "s.mcap", split_seconds=1.0)
    w.add_channel("/text", "std_msgs/msg/String", [profile_dict()])
    w.write("/text", serialize_message(String(data="first")), 10**9)

    def full(self: Writer) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(Writer, "finish", full)
    with pytest.raises(BagFullError, match=r"disk full while finishing .*s_0\.mcap"):
        w.write("/text", serialize_message(String(data="second")), 3 * 10**9)
    monkeypatch.undo()
    assert w.close() == [tmp_path / "s_0.mcap"]


def test_cut_bag_reads_what_is_intact_and_recovers(tmp_path: Path) -> None:
    [path] = _write(tmp_path / "full.mcap", n=300)
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])
    reader = BagReader.open(cut)
    got = list(reader.messages())
    assert 0 < len(got) < 600 and reader.stopped and "stopped at byte" in reader.stopped[0]
    assert [m.log_time for m in got] == sorted(m.log_time for m in got)
    rec = recover(cut, tmp_path / "rec.mcap")
    assert rec["messages"] == len(got)
    with open(tmp_path / "rec.mcap", "rb") as f:
        assert make_reader(f, validate_crcs=True).get_summary().statistics.message_count == len(got)


def test_a_cameras_topics_are_told_apart_under_any_namespace() -> None:
    assert topic_owner("/drone_0/image_raw", CAMERA_IMAGES) == ("/drone_0", "image_raw")
    assert topic_owner("/g1/sub/drone_12/image_raw/compressed", CAMERA_IMAGES) == ("/g1/sub/drone_12",
                                                                                   "image_raw/compressed")
    assert topic_owner("/g1/drone_2/labels", ("labels", "detections")) == ("/g1/drone_2", "labels")
    for other in ("/image_raw", "drone_0/image_raw", "/drone_0/image_raw/theora", "/drone_0/depth",
                  "//image_raw", "/drone_0/image_rawx", "/drone_0/labels/markers"):
        assert topic_owner(other, (*CAMERA_IMAGES, "labels")) is None, other
    assert last_name("/g1/drone_3") == "drone_3" and last_name("drone_3") == "drone_3"


def test_qos_yaml_and_replay_profile() -> None:
    profiles = [profile_dict(durability="transient_local"), profile_dict(reliability="best_effort")]
    assert from_yaml(to_yaml(profiles)) == profiles
    p = replay_profile(profiles)
    assert p["reliability"] == "best_effort" and p["durability"] == "volatile"
    assert from_yaml("- history: 1\n  depth: 5\n  reliability: 1\n  durability: 1\n")[0]["durability"] == \
        "transient_local"


def test_qos_overrides_file_sets_policies_per_topic_and_names_what_is_wrong(tmp_path: Path) -> None:
    """``qos_overrides_path`` (the recorder's and the replay's, as ros2 bag's --qos-profile-overrides-path): topic
    -> policies, laid over the profile the node chose; a bad file, topic, key or value is refused naming it."""
    from zebra_sim_ros.errors import ParameterError
    from zebra_sim_ros.nodes.ros_adapter import profile_qos
    from zebra_sim_ros.recording.qos import load_overrides, overridden

    good = tmp_path / "qos.yaml"
    good.write_text("/tf_static:\n  durability: transient_local\n  depth: 1\n"
                    "/scan:\n  reliability: best_effort\n  history: keep_all\n  depth: 0\n")
    o = load_overrides(good)
    assert o == {"/tf_static": {"durability": "transient_local", "depth": 1},
                 "/scan": {"reliability": "best_effort", "history": "keep_all", "depth": 0}}
    chosen = profile_dict(depth=100)
    latched = overridden(chosen, o["/tf_static"])
    assert (latched["durability"], latched["depth"], latched["reliability"]) == ("transient_local", 1, "reliable")
    assert overridden(chosen, None) is chosen and chosen["durability"] == "volatile"  # the chosen one untouched
    q = profile_qos(overridden(chosen, o["/scan"]))
    assert (q.history.name, q.reliability.name, q.durability.name) == ("KEEP_ALL", "BEST_EFFORT", "VOLATILE")
    assert load_overrides("") == {}
    for text, named in (("/a:\n  reliability: sometimes\n", "reliability 'sometimes'"),
                        ("/a:\n  deadline: 5\n", "/a: deadline"),
                        ("a:\n  depth: 3\n", "a'"),
                        ("/a:\n  depth: -1\n", "depth -1"),
                        ("/a:\n  depth: 0\n", "depth 0"),
                        ("- /a\n", "qos.yaml"),
                        ("/a: [\n", "qos.yaml")):
        good.write_text(text)
        with pytest.raises(ParameterError, match="qos_overrides_path") as err:
            load_overrides(good)
        assert named in str(err.value), (text, str(err.value))
    with pytest.raises(ParameterError, match="readable"):
        load_overrides(tmp_path / "missing.yaml")


def _labels(stamp: dict, zebras: list[dict]) -> dict:
    """A labels message with only what scoring reads and the zebras' ids (the typed reader fills in the rest)."""
    return {"schema": "zebra_sim_ros/labels", "version": 1, "stamp": stamp,
            "zebras": [{"id": i, **z} for i, z in enumerate(zebras)]}


def _detections(stamp: dict, dets: list[dict]) -> dict:
    return {"schema": "zebra_sim_ros/detections", "version": 1, "stamp": stamp, "detections": dets}


def test_eval_from_recorded_labels_and_detections(tmp_path: Path) -> None:
    w = BagWriter(tmp_path / "e.mcap")
    for d in ("drone_0", "drone_1"):
        w.add_channel(f"/{d}/labels", "std_msgs/msg/String", [profile_dict()])
        w.add_channel(f"/{d}/detections", "std_msgs/msg/String", [profile_dict()])
    for k in range(4):
        stamp = {"sec": k, "nanosec": 0}
        for d, shift in (("drone_0", 0.0), ("drone_1", 30.0)):
            # kept; seen but dropped by the filters (don't-care); out of sight (no visible pixels)
            z = [{"box_visible": [10.0, 10, 50, 40], "kept": True, "visible_pixels": 1100},
                 {"box_visible": [100.0, 100, 104, 103], "kept": False, "visible_pixels": 8},
                 {"box_visible": [0.0, 0, 2, 2], "kept": False, "visible_pixels": 0}]
            dets = [{"box_xyxy": [10.0 + shift, 10, 50 + shift, 40], "score": 0.9},
                    {"box_xyxy": [100.0, 100, 104, 103], "score": 0.95}]  # on the don't-care zebra: not held against
            if k == 3:
                dets.append({"box_xyxy": [1.0, 1, 2, 2], "score": 0.99})  # on the unseen one: a false positive
            w.write(f"/{d}/labels", serialize_message(String(data=json.dumps(_labels(stamp, z)))), k)
            w.write(f"/{d}/detections", serialize_message(String(data=json.dumps(_detections(stamp, dets)))), k)
    w.close()
    s = score(collect(tmp_path / "e.mcap"))
    # one false positive ranked above all 4 true positives: precision 4/5 at every recall
    assert s["drone_0"]["frames"] == 4 and s["drone_0"]["mAP50"] == pytest.approx(0.8, abs=0.01)
    assert s["drone_0"]["instances"] == 4  # don't-care zebras are no instances
    assert s["drone_1"]["mAP50"] == pytest.approx(0.0, abs=1e-6)  # shifted by 30 px: IoU 0.14
    # both drones' step-3 false positives rank first, then drone_0's 4 true positives: 4/6 up to recall 4/8
    assert s["all"]["mAP50"] == pytest.approx(51 / 101 * 4 / 6, abs=0.01)
    # counted at the detector's threshold: the don't-care hit is neither counted nor missed, step 3's extra box is
    # one too many on each drone (a count cannot tell drone_1's misplaced boxes from hits: mAP does)
    want = {"conf": 0.25, "images": 4, "true": 4, "counted": 5, "mae": 0.25, "bias": 0.25, "relative": 0.25}
    assert s["drone_0"]["count"] == pytest.approx(want) and s["drone_1"]["count"] == pytest.approx(want)
    assert s["all"]["count"] == pytest.approx({**want, "images": 8, "true": 8, "counted": 10})
    high = score(collect(tmp_path / "e.mcap"), count_conf=0.95)["drone_0"]["count"]  # only step 3's 0.99 box
    assert high == pytest.approx({**want, "conf": 0.95, "counted": 1, "mae": 0.75, "bias": -0.75, "relative": -0.75})
    assert cdr_string(serialize_message(String(data="héllo"))) == "héllo"


def test_eval_skips_and_notes_malformed_labels_and_detections(tmp_path: Path) -> None:
    w = BagWriter(tmp_path / "bad.mcap")
    w.add_channel("/drone_0/labels", "std_msgs/msg/String", [profile_dict()])
    w.add_channel("/drone_0/detections", "std_msgs/msg/String", [profile_dict()])
    good = _labels({"sec": 1, "nanosec": 0}, [{"box_visible": [10.0, 10, 50, 40], "kept": True}])
    w.write("/drone_0/labels", serialize_message(String(data=json.dumps(good))), 1)
    w.write("/drone_0/detections", serialize_message(String(data=json.dumps(
        _detections({"sec": 1, "nanosec": 0}, [{"box_xyxy": [10.0, 10, 50, 40], "score": 0.8}])))), 2)
    w.write("/drone_0/labels", serialize_message(String(data="{not json")), 3)
    w.write("/drone_0/detections", serialize_message(String(data=json.dumps(
        {"schema": "zebra_sim_ros/detections", "version": 1, "stamp": {"sec": 2}}))), 4)
    w.write("/drone_0/labels", b"\x00\x01", 5)  # not even CDR
    w.close()
    s = score(collect(tmp_path / "bad.mcap"))
    assert s["drone_0"]["frames"] == 1 and s["drone_0"]["mAP50"] == pytest.approx(1.0)
    assert len(s["skipped"]) == 3
    assert [n.split(" at log time ")[1].split(" ns")[0] for n in s["skipped"]] == ["3", "4", "5"]
    assert "labels is not JSON" in s["skipped"][0] and "detections lacks 'detections'" in s["skipped"][1]


def test_eval_by_running_a_detector_over_recorded_images(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from zebra_sim_ros.detection.checkpoint import save_checkpoint
    from zebra_sim_ros.detection.model import ModelConfig, build_model
    from zebra_sim_ros.recording.evaluate import ImageDetector

    save_checkpoint(tmp_path / "w.pt", build_model(ModelConfig(size="n", imgsz=128)).eval())
    w = BagWriter(tmp_path / "i.mcap")
    w.add_channel("/drone_0/image_raw", "sensor_msgs/msg/Image", [profile_dict()])
    w.add_channel("/drone_0/labels", "std_msgs/msg/String", [profile_dict()])
    for k in range(3):
        img = Image(header=Header(frame_id="c"), height=72, width=128, encoding="bgr8", step=384,
                    data=bytes(72 * 384))
        img.header.stamp.sec = k
        w.write("/drone_0/image_raw", serialize_message(img), k)
        lab = _labels({"sec": k, "nanosec": 0}, [{"box_visible": [10.0, 10, 30, 20], "kept": True}])
        w.write("/drone_0/labels", serialize_message(String(data=json.dumps(lab))), k)
    mono = Image(header=Header(frame_id="c"), height=2, width=2, encoding="mono8", step=2, data=bytes(4))
    w.write("/drone_0/image_raw", serialize_message(mono), 3)
    w.write("/drone_0/image_raw", serialize_message(img)[:60], 4)  # cut short: pixels missing
    w.close()
    detector = ImageDetector(tmp_path / "w.pt", device="cpu", batch=2)
    seen: list[str] = []

    def both(m: BagMessage) -> None:  # the detector rides the same pass as the labels
        seen.append(m.topic)
        detector(m)

    collected = detector.apply(collect(tmp_path / "i.mcap", each=both))
    assert len(seen) == 8, "the bag is read once"
    assert sorted(collected.drones["drone_0"].detections) == [0, 10**9, 2 * 10**9]
    assert len(collected.skipped) == 2
    assert "not a colour image" in collected.skipped[0] and "log time 4 ns" in collected.skipped[1]
    s = score(collected)
    assert s["drone_0"]["frames"] == 3 and 0.0 <= s["drone_0"]["mAP50"] <= 1.0
    # --imgsz: the 128x72 frames at their own size (-1) are the checkpoint's 128 too; 256 differs.
    at = {size: ImageDetector(tmp_path / "w.pt", device="cpu", imgsz=size) for size in (-1, 256)}
    got = {size: d.apply(collect(tmp_path / "i.mcap", each=d)).drones["drone_0"].detections[0]
           for size, d in at.items()}
    # the same model and pixels in batches of 8 here, of 2 above: equal to float noise, not necessarily to the bit
    batched = collected.drones["drone_0"].detections[0]
    assert got[-1].shape == batched.shape
    np.testing.assert_allclose(got[-1], batched, atol=1e-3)
    assert got[256].shape != got[-1].shape or not np.allclose(got[256], got[-1], atol=1e-3)
    # --scale: 2 x the frames' 128 px is 256 again; a scale out of range is refused, naming it.
    twice = ImageDetector(tmp_path / "w.pt", device="cpu", scale=2.0)
    at_twice = twice.apply(collect(tmp_path / "i.mcap", each=twice)).drones["drone_0"].detections[0]
    assert at_twice.shape == got[256].shape
    np.testing.assert_allclose(at_twice, got[256], atol=1e-3)
    from zebra_sim_ros.cli import main

    for bad in ("9", "-1", "0.1"):
        assert main(["bag", "eval", str(tmp_path / "i.mcap"), "--weights", str(tmp_path / "w.pt"), "--scale", bad]) == 2
    assert "--scale: '0.1': allowed 0 (off) or 0.25..4" in capsys.readouterr().err


def test_cdr_image_reader_matches_rclpy() -> None:
    from zebra_sim_ros.recording.cdr import cdr_image

    img = Image(header=Header(frame_id="drone_1/camera_optical"), height=3, width=5, encoding="bgr8", step=15,
                data=bytes(range(45)))
    img.header.stamp.sec, img.header.stamp.nanosec = 1234, 5678
    assert cdr_image(serialize_message(img)) == (1234 * 10**9 + 5678, 3, 5, "bgr8", 15, bytes(range(45)))


def test_pose_reader_matches_rclpy() -> None:
    """A PoseStamped's stamp and position, whatever the frame name's length does to the alignment."""
    from geometry_msgs.msg import Point, Pose, PoseStamped

    from zebra_sim_ros.recording.cdr import cdr_pose_position

    for frame in ("", "m", "ma", "map", "mapx", "drone_0", "drone_0/camera_optical"):
        msg = PoseStamped(header=Header(frame_id=frame), pose=Pose(position=Point(x=1.5, y=-2.25, z=60.125)))
        msg.header.stamp.sec, msg.header.stamp.nanosec = 7, 11
        assert cdr_pose_position(serialize_message(msg)) == (7 * 10**9 + 11, (1.5, -2.25, 60.125)), frame


def _census_bag(path: Path, views: dict[str, dict[int, np.ndarray]], poses: bool = True,
                recorded: dict[int, int] | None = None, ns: str = "", ids: dict[str, int] | None = None,
                scenes: dict[int, str] | None = None, located: str = "detections/located",
                census: str = "census/animals", pose: str = "camera/pose",
                reports: dict[str, dict[str, str]] | None = None, pose_around_ns: int = 0) -> Path:
    """A bag as up --locate records it, less the images: per camera and stamp its placed zebras (a
    Detection3DArray on ``<camera>/<located>``, scores 0.9, 0.8 ..., ids from ``ids[camera]`` up where given, else
    none) and its pose on ``<camera>/<pose>`` (the camera 60 m up, 80 m from the origin along its name's order), the
    locator's census of some stamps (on ``census``), the placer's scenes (JSON by stamp) where given, and
    ``reports`` on /diagnostics (status name: its values) where given. With ``pose_around_ns``, the poses are
    stamped that long before and after each image instead (a source at its own rate)."""
    from geometry_msgs.msg import Point, Pose, PoseStamped

    from zebra_sim_ros.nodes.ros_adapter import detection3d_array_type, message_class, stamp
    from zebra_sim_ros.recording.writer import BagWriter

    kind = detection3d_array_type()
    msg = __import__(kind.split("/")[0] + ".msg", fromlist=["Detection3D"])
    w = BagWriter(path)
    for i, (cam, by_stamp) in enumerate(views.items()):
        w.add_channel(f"{ns}/{cam}/{located}", kind, [])
        w.add_channel(f"{ns}/{cam}/{pose}", "geometry_msgs/msg/PoseStamped", [])
        for t, pts in by_stamp.items():
            h = Header(stamp=stamp(t), frame_id="map")
            dets = [msg.Detection3D(header=h, results=[msg.ObjectHypothesisWithPose(
                hypothesis=msg.ObjectHypothesis(class_id="zebra", score=0.9 - 0.1 * k))],
                bbox=msg.BoundingBox3D(center=Pose(position=Point(x=x, y=y, z=z))),
                id=str(ids[cam] + k) if ids and cam in ids else "") for k, (x, y, z) in enumerate(pts)]
            w.write(f"{ns}/{cam}/{located}", serialize_message(message_class(kind)(header=h, detections=dets)), t)
            if poses:
                angle = 2.1 * i
                for at in ((t - pose_around_ns, t + pose_around_ns) if pose_around_ns else (t,)):
                    w.write(f"{ns}/{cam}/{pose}", serialize_message(PoseStamped(
                        header=Header(stamp=stamp(at), frame_id="map"),
                        pose=Pose(position=Point(x=80 * np.cos(angle), y=80 * np.sin(angle), z=60.0)))), at)
    if scenes:
        w.add_channel(f"{ns}/zebra_sim/scene", "std_msgs/msg/String", [])
        for t, text in scenes.items():
            w.write(f"{ns}/zebra_sim/scene", serialize_message(String(data=text)), t)
    if reports:
        from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

        w.add_channel("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray", [])
        for k in range(2):  # the latest report of each name is the one read: written first, a stale one after it
            w.write("/diagnostics", serialize_message(DiagnosticArray(status=[DiagnosticStatus(
                name=name, message="placed", values=[KeyValue(key=key, value=value if k == 0 else "stale")
                                                     for key, value in values.items()])
                for name, values in reports.items()])), 10**9 * (2 - k))
    if recorded:
        w.add_channel(f"{ns}/{census}", kind, [])
        for t, n in recorded.items():
            h = Header(stamp=stamp(t), frame_id="map")
            dets = [msg.Detection3D(header=h, results=[msg.ObjectHypothesisWithPose(
                hypothesis=msg.ObjectHypothesis(class_id="zebra", score=0.9))]) for _ in range(n)]
            w.write(f"{ns}/{census}", serialize_message(message_class(kind)(header=h, detections=dets)), t)
    (out,) = w.close()
    return out


def test_a_recorded_census_is_counted_again_from_the_bag(tmp_path: Path) -> None:
    """``bag census`` on a bag of cameras not named drone_N and without labels (a real flight's): each stamp every
    camera placed and posed joined as ``join_views`` joins it, in the order asked; a stamp one camera lacks is not
    counted; the recorded census scored on the same stamps; bags it cannot count are refused by name."""
    from zebra_sim_ros.errors import ParameterError
    from zebra_sim_ros.geometry.census import join_views
    from zebra_sim_ros.recording.census import bag_census

    rng = np.random.default_rng(5)
    herd = np.column_stack([rng.uniform(-10, 10, (12, 2)), np.full(12, 0.7)])
    s1, s2 = 10**9, 2 * 10**9
    views = {cam: {s1: herd[rng.permutation(12)[:9]] + [*rng.normal(0, 0.1, 2), 0.0]} for cam in ("north", "south",
                                                                                                    "east")}
    views["north"][s2] = herd[:5]  # north alone has stamp 2: never counted
    bag = _census_bag(tmp_path / "flight.mcap", views, recorded={s1: 11, s2: 4})
    got = bag_census(bag)
    assert got["cameras"] == ["east", "north", "south"] and (got["stamps_placed"], got["stamps_counted"]) == (2, 1)
    origins = {cam: np.array([80 * np.cos(2.1 * i), 80 * np.sin(2.1 * i), 60.0]) for i, cam in enumerate(views)}

    def joined(order: list[str]) -> int:
        return join_views([views[c][s1] for c in order], [origins[c] for c in order],
                          scores=[0.9 - 0.1 * np.arange(9)] * 3).count

    assert got["recounted"] == {"steps": 1, "animals": joined(["east", "north", "south"]), "true": None,
                                "error": None, "summed": 27, "summed_error": None}  # north's stamp 2 left out
    assert 9 <= got["recounted"]["animals"] <= 12
    assert got["recorded"]["animals"] == 11 and got["recorded_stamps"] == 2  # scored on stamp 1 only
    ordered = bag_census(bag, drones=["south", "north", "east"])
    assert ordered["cameras"] == ["south", "north", "east"]
    assert ordered["recounted"]["animals"] == joined(["south", "north", "east"])
    with pytest.raises(ParameterError, match="'drones'.*the bag's cameras"):
        bag_census(bag, drones=["north", "south"])
    no_poses = _census_bag(tmp_path / "no_poses.mcap", views, poses=False)
    with pytest.raises(ParameterError, match="camera/pose"):
        bag_census(no_poses)
    # poses at their own rate, 50 ms either side of each image: none has an image's stamp; interpolated between the
    # two about it (the locator's pose_max_gap_s) they give the same census; farther apart than allowed, none
    around = _census_bag(tmp_path / "around.mcap", views, recorded={s1: 11, s2: 4}, pose_around_ns=50_000_000)
    with pytest.raises(ParameterError, match="camera/pose"):
        bag_census(around)
    assert bag_census(around, {"pose_max_gap_s": 0.2})["recounted"] == got["recounted"]
    with pytest.raises(ParameterError, match="camera/pose"):
        bag_census(around, {"pose_max_gap_s": 0.05})
    two = _census_bag(tmp_path / "g1.mcap", {"drone_0": views["north"]}, ns="/g1")
    other = _census_bag(tmp_path / "g2.mcap", {"drone_0": views["south"]}, ns="/g2")
    with pytest.raises(ParameterError, match="2 namespaces: /g1, /g2"):
        bag_census([two, other])
    plain = tmp_path / "plain"
    plain.mkdir()
    [path] = _write(plain / "plain.mcap", n=3)
    with pytest.raises(ParameterError, match=f"{re.escape(str(path))}.*placed detections"):
        bag_census(path)


def test_a_bag_census_follows_what_the_bags_locator_reported(tmp_path: Path, cli: CliRun) -> None:
    """A run whose locator placed from the navigation's poses, joined with its own gate and camera order, and
    published under other names: its reports on /diagnostics say so, and ``bag census`` with nothing given counts
    as it did (each followed setting named), the same as with every setting given; a setting given wins over the
    bag's; the latest report counts; a bag with two locators' reports follows neither (the defaults, which do not
    find these topics); the camera order is followed past drone_9, and a reported value this version refuses is
    left to its default."""
    from zebra_sim_ros.errors import ParameterError
    from zebra_sim_ros.recording.census import bag_census

    rng = np.random.default_rng(9)
    herd = np.column_stack([rng.uniform(-10, 10, (10, 2)), np.full(10, 0.7)])
    views = {cam: {t * 10**9: herd[rng.permutation(10)[:8]] + [*rng.normal(0, 0.3, 2), 0.0] for t in (1, 2)}
             for cam in ("drone_0", "drone_1", "drone_2")}
    reported = {"drones": "drone_2, drone_0, drone_1", "output": "placed", "pose": "camera/pose_nav",
                "census_output": "herd/count", "census_along": "0.8", "census_across": "0.25", "census_gate": "2.0",
                "census_separation": "0.5", "last census": "zebra 9"}
    bag = _census_bag(tmp_path / "followed.mcap", views, recorded={10**9: 9}, located="placed", census="herd/count",
                      pose="camera/pose_nav", reports={"locator: locator": reported})
    got = bag_census(bag)
    given = {"output": "placed", "census_output": "herd/count", "pose": "camera/pose_nav", "census_along": 0.8,
             "census_across": 0.25, "census_gate": 2.0, "census_separation": 0.5}
    want = bag_census(bag, given, drones=["drone_2", "drone_0", "drone_1"])
    followed = dict(got["followed"])
    assert followed.pop("drones") == ["drone_2", "drone_0", "drone_1"]
    assert {k: followed.pop(k) for k in ("output", "census_output", "pose")} == {k: given[k] for k in
                                                                                ("output", "census_output", "pose")}
    assert followed == pytest.approx({k: v for k, v in given.items() if isinstance(v, float)}, abs=1e-12)
    assert got["cameras"] == want["cameras"] == ["drone_2", "drone_0", "drone_1"]
    assert got["recounted"] == want["recounted"] and got["rule"] == want["rule"] and got["recorded"]["animals"] == 9
    wider = bag_census(bag, {"census_gate": 6.0})  # given: it wins, the rest still followed
    assert wider["rule"]["census_gate"] == pytest.approx(6.0) and "census_gate" not in wider["followed"]
    assert wider["pose"] == "camera/pose_nav"
    run = cli(["bag", "census", str(bag), "--json"])
    assert run.returncode == 0, run.stderr
    assert "as the bag's locator reported on /diagnostics: " in run.stdout and "pose camera/pose_nav" in run.stdout
    assert json.loads(run.stdout.strip().splitlines()[-1])["recounted"] == want["recounted"]
    two = _census_bag(tmp_path / "two.mcap", views, located="placed", census="herd/count", pose="camera/pose_nav",
                      reports={"locator: locator": reported, "other_locator: locator": reported})
    with pytest.raises(ParameterError, match=re.escape("<drone>/detections/located")):
        bag_census(two)
    clash = _census_bag(tmp_path / "clash.mcap", views, reports={"locator: locator": {"pose": "detections/located"}})
    with pytest.raises(ParameterError, match="followed from the bag's locator's /diagnostics"):
        bag_census(clash)  # each valid alone; the pose on the placed detections' topic is refused
    # drone_10 joined before drone_2, as its (namespaced) locator had them; a value this version refuses (an
    # absolute pose topic) is left to its default
    tens = {"drone_10": views["drone_0"], "drone_2": views["drone_2"]}
    odd = _census_bag(tmp_path / "tens.mcap", tens, ns="/g1", reports={"g1/locator: locator": {
        "drones": "drone_10, drone_2", "pose": "/abs/pose", "census_gate": "3.0"}})
    got = bag_census(odd)
    assert got["cameras"] == ["drone_10", "drone_2"] and got["pose"] == "camera/pose"
    assert set(got["followed"]) == {"census_gate", "drones"} and got["followed"]["drones"] == ["drone_10", "drone_2"]
    assert got["followed"]["census_gate"] == pytest.approx(3.0, abs=1e-12)


def test_the_diagnostics_reader_matches_rclpy() -> None:
    """Each status's name and values of a DiagnosticArray, whatever the strings' lengths do to the alignment."""
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

    from zebra_sim_ros.recording.cdr import cdr_diagnostics

    statuses = [DiagnosticStatus(level=bytes([k % 3]), name="n" * k, message="m" * (k + 1), hardware_id="h" * (2 * k),
                                 values=[KeyValue(key="k" * j, value="v" * (j + k)) for j in range(k)])
                for k in range(6)]
    msg = DiagnosticArray(header=Header(frame_id="abc"), status=statuses)
    assert cdr_diagnostics(serialize_message(msg)) == [("n" * k, {"k" * j: "v" * (j + k) for j in range(k)})
                                                       for k in range(6)]


def test_a_locator_publishing_under_other_names_is_read_by_its_names(tmp_path: Path, cli: CliRun) -> None:
    """A locator whose file renames its outputs (``output``, ``census_output``) and places from the navigation's
    poses (``pose``: camera/pose_nav): ``bag census`` (``--output``, ``--census-output``, ``--pose`` on the command
    line) and the run's summary read the placed detections, the census and the poses by the names given, the same
    figures as under the default names; asked by the default names, the bag census refuses naming the topic it
    looked for, and the summary has neither part."""
    from zebra_sim_ros.detection.config import LocatorConfig
    from zebra_sim_ros.errors import ParameterError
    from zebra_sim_ros.graph.summary import summarize_run
    from zebra_sim_ros.recording.census import bag_census

    rng = np.random.default_rng(8)
    herd = np.column_stack([rng.uniform(-10, 10, (10, 2)), np.full(10, 0.7)])
    views = {cam: {t * 10**9: herd[rng.permutation(10)[:8]] for t in (1, 2)} for cam in ("drone_0", "drone_1")}
    named = LocatorConfig(output="placed", census_output="herd/count", pose="camera/pose_nav")
    renamed = _census_bag(tmp_path / "renamed.mcap", views, recorded={10**9: 9, 2 * 10**9: 7}, located="placed",
                          census="herd/count", pose="camera/pose_nav")
    default = _census_bag(tmp_path / "default.mcap", views, recorded={10**9: 9, 2 * 10**9: 7})
    names = {"output": "placed", "census_output": "herd/count", "pose": "camera/pose_nav"}
    got, want = bag_census(renamed, names), bag_census(default)
    assert got["stamps_counted"] == 2 and got["recounted"] == want["recounted"] and got["recorded"] == want["recorded"]
    assert got["recorded"]["animals"] == 16
    with pytest.raises(ParameterError, match=re.escape("<drone>/detections/located")):
        bag_census(renamed)
    with pytest.raises(ParameterError, match=re.escape("poses (<drone>/camera/pose,")):
        bag_census(renamed, {"output": "placed", "census_output": "herd/count"})
    run = cli(["bag", "census", str(renamed), "--output", "placed", "--census-output", "herd/count", "--pose",
               "camera/pose_nav", "--json"])
    assert run.returncode == 0, run.stderr
    assert "recorded (the locator's herd/count" in run.stdout
    assert json.loads(run.stdout.strip().splitlines()[-1])["recounted"] == want["recounted"]
    refused = cli(["bag", "census", str(renamed)])
    assert refused.returncode == 2 and "<drone>/detections/located" in refused.stderr
    bad = cli(["bag", "census", str(renamed), "--pose", "/abs"])
    assert bad.returncode == 2 and "--pose: '/abs': allowed a topic name relative to the drone" in bad.stderr
    summary, by_default = summarize_run(renamed, locator=named), summarize_run(default)
    assert summary["located"]["frames"] == 4 and summary["located"]["detections"] == 32
    assert (summary["located"]["pose"], by_default["located"]["pose"]) == ("camera/pose_nav", "camera/pose")
    assert {**summary["located"], "pose": ""} == {**by_default["located"], "pose": ""}
    assert summary["census"] == by_default["census"]
    assert summary["census"]["animals"] == 16
    unnamed = summarize_run(renamed)
    assert "located" not in unnamed and "census" not in unnamed


def test_a_recounted_census_on_the_earth(tmp_path: Path, library: Any, savanna: Any, cli: CliRun) -> None:
    """``bag census --geojson``: every recounted animal a WGS84 point that converts back to its map position to the
    millimetre, with its score and cameras; every zebra detection of a counted stamp in exactly one animal, named
    by its id, or its place in the message where it has none. The datum is the bag's scenes'; ``datum`` only where
    they carry none: a bag whose scenes carry none wants it, scenes that disagree or a ``datum`` unlike theirs are
    refused by name, as is a file that cannot be written; the CLI reads ``--datum`` or refuses it by name."""
    from zebra_sim_ros.cli.bag import parse_datum
    from zebra_sim_ros.errors import ParameterError
    from zebra_sim_ros.geometry.geodesy import geodetic_to_enu
    from zebra_sim_ros.messages import Datum
    from zebra_sim_ros.placement.config import PlacerConfig
    from zebra_sim_ros.placement.placer import Placer
    from zebra_sim_ros.recording.census import bag_census
    from zebra_sim_ros.recording.stamps import iso_time, stamp_text

    rng = np.random.default_rng(9)
    herd = np.column_stack([rng.uniform(-10, 10, (12, 2)), np.full(12, 0.7)])
    s1 = 10**9
    views = {cam: {s1: herd[rng.permutation(12)[:9]] + [*rng.normal(0, 0.1, 2), 0.0]} for cam in ("north", "south",
                                                                                                    "east")}
    bag = _census_bag(tmp_path / "flight.mcap", views, ids={"east": 10})
    with pytest.raises(ParameterError, match="'datum' = \\[\\].*one datum"):
        bag_census(bag, geojson=tmp_path / "no.geojson")
    assert not (tmp_path / "no.geojson").exists()
    datum = Datum(-2.3, 34.8, 1550.0)
    got = bag_census(bag, geojson=tmp_path / "out" / "census.geojson", datum=datum)
    doc = json.loads((tmp_path / "out" / "census.geojson").read_text())
    assert got["geojson"] == str(tmp_path / "out" / "census.geojson") and got["datum"] == datum.to_dict()
    features = doc["features"]
    assert doc["type"] == "FeatureCollection" and len(features) == got["recounted"]["animals"] >= 9
    assert doc["zebra_sim"]["datum"] == datum.to_dict() and doc["zebra_sim"]["census"] == "recounted"
    assert doc["zebra_sim"]["per_class"] == {"zebra": len(features)} and doc["zebra_sim"]["source"] == [str(bag)]
    assert len({f["id"] for f in features}) == len(features)
    lon_lat_h = np.array([f["geometry"]["coordinates"] for f in features])
    back = geodetic_to_enu(lon_lat_h[:, [1, 0, 2]], datum)
    xyz = np.array([[f["properties"][f"map_{a}"] for a in "xyz"] for f in features])
    assert np.abs(back - xyz).max() < 2e-3  # the rounding alone
    assert np.abs(back[:, :2]).max() < 15  # the herd, around map's origin
    parts = [p for f in features for p in f["properties"]["detections"].split(",")]
    want = [f"east:{10 + k}" for k in range(9)] + [f"{c}:{k}" for c in ("north", "south") for k in range(9)]
    assert sorted(parts) == sorted(want)  # each detection in one animal
    for f in features:
        props = f["properties"]
        joined = props["detections"].split(",")
        assert props["views"] == len({p.split(":")[0] for p in joined}) and props["class"] == "zebra"
        assert props["stamp_ns"] == s1 and props["time_s"] == pytest.approx(1.0)
        assert props["time"] == "1970-01-01T00:00:01.000Z"
        ranks = [int(p.split(":")[1]) % 10 for p in joined]  # east's ids start at 10
        assert props["score"] == pytest.approx(0.9 - 0.1 * min(ranks), abs=1e-4)  # its best detection's
    # a real flight's stamp (past 2^53 ns, where a JSON number loses its nanoseconds): to the millisecond, truncated
    assert [iso_time(t) for t in (1_764_577_532_123_999_999, 10**18, 999_999)] == [
        "2025-12-01T08:25:32.123Z", "2001-09-09T01:46:40.000Z", "1970-01-01T00:00:00.000Z"]
    assert stamp_text(1_764_577_532_123_999_999) == "2025-12-01T08:25:32.123Z (1764577532.123999999)"  # bag info's
    assert stamp_text(999_999) == "1970-01-01T00:00:00.000Z (0.000999999)"
    assert stamp_text(-1) == "1969-12-31T23:59:59.999Z (-0.000000001)"  # a Time's sec may be negative
    # a bag whose scenes carry their datum: that one, the same animals elsewhere on the Earth
    world = savanna
    scene = Placer(PlacerConfig.from_params({"seed": 3, "count_max": 5}), world, library).scene(0)
    arctic = Datum(78.2, 15.6, 10.0)
    far_north = Placer(PlacerConfig.from_params({"seed": 3, "count_max": 5, "latitude_deg": 78.2, "longitude_deg": 15.6,
                                                 "origin_altitude_m": 10.0}), world, library).scene(0)
    assert far_north.datum == arctic and scene.datum == datum
    with_scenes = _census_bag(tmp_path / "with_scenes.mcap", views, ids={"east": 10},
                              scenes={s1: far_north.to_json()})
    north = bag_census(with_scenes, geojson=tmp_path / "arctic.geojson")
    moved = json.loads((tmp_path / "arctic.geojson").read_text())["features"]
    assert north["datum"] == arctic.to_dict() and len(moved) == len(features)
    assert all(f["geometry"]["coordinates"][1] == pytest.approx(78.2, abs=1e-3) for f in moved)
    assert bag_census(with_scenes, geojson=tmp_path / "same.geojson", datum=arctic)["datum"] == arctic.to_dict()
    with pytest.raises(ParameterError, match="'datum' = \\(-2.3, 34.8, 1550.0\\).*\\(78.2, 15.6, 10.0\\)"):
        bag_census(with_scenes, geojson=tmp_path / "other.geojson", datum=datum)  # not the bag's own
    disagree = _census_bag(tmp_path / "disagree.mcap", views, scenes={s1: far_north.to_json(),
                                                                       2 * s1: scene.to_json()})
    with pytest.raises(ParameterError, match="'datum' = \\[\\(-2.3.*\\(78.2.*one datum"):
        bag_census(disagree, geojson=tmp_path / "two.geojson")
    (tmp_path / "a_folder").mkdir()
    with pytest.raises(ParameterError, match="'geojson'.*a_folder.*a file that can be written"):
        bag_census(bag, geojson=tmp_path / "a_folder", datum=datum)
    assert parse_datum("-2.3,34.8") == Datum(-2.3, 34.8, 0.0)
    for bad in ("91,0", "1", "a,b", "1,2,3,4"):
        with pytest.raises(ParameterError, match="'datum'"):
            parse_datum(bad)
    run = cli(["bag", "census", str(bag), "--geojson", str(tmp_path / "cli.geojson"), "--datum=-2.3,34.8,1550"])
    assert run.returncode == 0, run.stderr
    assert "on the map: " in run.stdout and "origin at -2.3, 34.8, 1550.0 m" in run.stdout
    assert json.loads((tmp_path / "cli.geojson").read_text())["features"] == features  # as called in Python
    alone = cli(["bag", "census", str(bag), "--datum=-2.3,34.8"])  # a datum for no GeoJSON
    assert alone.returncode != 0 and "'datum'" in alone.stderr and "only with geojson" in alone.stderr
    # the scenes' own datum, typed back rounded from a printout, is theirs
    assert bag_census(with_scenes, geojson=tmp_path / "typed.geojson", datum=Datum(78.2 + 1e-12, 15.6, 10.0004))[
        "datum"] == Datum(78.2 + 1e-12, 15.6, 10.0004).to_dict()

def test_a_damaged_chunk_in_the_middle_loses_only_that_chunk(tmp_path: Path) -> None:
    [path] = _write(tmp_path / "full.mcap", n=300)
    with open(path, "rb") as f:
        chunks = sorted(make_reader(f).get_summary().chunk_indexes, key=lambda c: c.chunk_start_offset)
    assert len(chunks) > 6
    bad = chunks[len(chunks) // 3]
    data = bytearray(path.read_bytes())
    data[bad.chunk_start_offset + bad.chunk_length // 2] ^= 0xFF  # one flipped byte inside its payload
    hurt = tmp_path / "hurt.mcap"
    hurt.write_bytes(bytes(data))
    reader = BagReader.open(hurt)
    got = list(reader.messages())
    times = {m.log_time for m in got}
    assert len(reader.stopped) == 1 and "skipped a damaged chunk" in reader.stopped[0]
    assert bad.message_start_time not in times and max(times) == 1_000_000_000 + 299 * 100_000_000  # goes on
    assert 600 * 0.8 < len(got) < 600
    assert recover(hurt, tmp_path / "rec.mcap")["messages"] == len(got)


def test_a_damaged_first_chunk_loses_only_its_own_messages_and_recover_keeps_every_type(tmp_path: Path) -> None:
    """The first chunk holds every topic's channel and schema records. Damaged in a finished bag, the summary's
    copies define them and only that chunk's messages are lost; damaged in a bag also cut short (no summary), the
    messages of the undefined channels are counted in a note, not dropped silently. ``recover`` writes each intact
    message under its own type, read back by rosbags, also when a type first appears after the damage."""
    [path] = _write(tmp_path / "full.mcap", n=300)
    with open(path, "rb") as f:
        chunks = sorted(make_reader(f).get_summary().chunk_indexes, key=lambda c: c.chunk_start_offset)
    first = chunks[0]
    data = bytearray(path.read_bytes())
    data[first.chunk_start_offset + first.chunk_length // 2] ^= 0xFF
    hurt = tmp_path / "hurt.mcap"
    hurt.write_bytes(bytes(data))
    reader = BagReader.open(hurt)
    got = list(reader.messages())
    assert len(reader.stopped) == 1 and "skipped a damaged chunk" in reader.stopped[0]
    assert first.message_start_time not in {m.log_time for m in got} and 600 * 0.8 < len(got) < 600
    assert {m.type_name for m in got} == {"std_msgs/msg/String", "sensor_msgs/msg/Image"}
    rec = recover(hurt, tmp_path / "rec.mcap")
    assert rec["messages"] == len(got) and not list(tmp_path.glob(".rec.mcap.*"))  # no temporary left
    with AnyReader([tmp_path / "rec.mcap"]) as r:  # an independent reader: each topic under its own type
        assert {c.topic: c.msgtype for c in r.connections} == {"/text": "std_msgs/msg/String",
                                                               "/image": "sensor_msgs/msg/Image"}
        texts = [r.deserialize(raw, c.msgtype).data for c, _, raw in r.messages() if c.topic == "/text"]
    kept = sorted((m.log_time - 1_000_000_000) // 100_000_000 for m in got if m.topic == "/text")
    assert texts == [f"message {i}" for i in kept]  # every intact one, decoded, in order
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(bytes(data[: len(data) * 2 // 3]))  # no summary: the definitions are lost with the chunk
    reader = BagReader.open(cut)
    assert list(reader.messages()) == []
    assert any("messages of channels whose definition was not read" in s for s in reader.stopped), reader.stopped
    # a type first written after a damaged chunk is still recovered under its own schema
    w = BagWriter(tmp_path / "late.mcap", chunk_size=4096)
    w.add_channel("/text", "std_msgs/msg/String", [profile_dict()])
    w.add_channel("/image", "sensor_msgs/msg/Image", [profile_dict()])
    for i in range(300):
        w.write("/text", serialize_message(String(data="x" * 100 + str(i))), 10**9 + i)
    for i in range(20):
        w.write("/image", serialize_message(Image(height=1, width=1, encoding="rgb8", step=3, data=b"abc")),
                2 * 10**9 + i)
    [late] = w.close()
    with open(late, "rb") as f:
        chunks = sorted(make_reader(f).get_summary().chunk_indexes, key=lambda c: c.chunk_start_offset)
    data = bytearray(late.read_bytes())
    data[chunks[2].chunk_start_offset + chunks[2].chunk_length // 2] ^= 0xFF
    (tmp_path / "late_hurt.mcap").write_bytes(bytes(data))
    rec = recover(tmp_path / "late_hurt.mcap", tmp_path / "late_rec.mcap")
    assert 280 <= rec["messages"] < 320
    with AnyReader([tmp_path / "late_rec.mcap"]) as r:
        counts = {c.topic: c.msgcount for c in r.connections}
    assert counts["/image"] == 20 and counts["/text"] == rec["messages"] - 20


def test_a_folder_of_split_files_plays_in_the_order_they_were_written(tmp_path: Path) -> None:
    """Twelve pieces of a split recording (``run_0`` .. ``run_11``): read as a folder, ``run_10`` comes after
    ``run_9``, not after ``run_1``, and the messages come back in time order."""
    w = BagWriter(tmp_path / "split" / "run.mcap", split_seconds=1.0)
    w.add_channel("/t", "std_msgs/msg/String", [profile_dict()])
    for i in range(12):
        w.write("/t", serialize_message(String(data=str(i))), 10**9 * (i + 1))
    assert len(w.close()) == 12
    reader = BagReader.open(tmp_path / "split")
    assert [p.name for p in reader.paths] == [f"run_{i}.mcap" for i in range(12)]
    assert [m.log_time // 10**9 for m in reader.messages()] == list(range(1, 13))


def test_a_seek_passes_over_chunks_before_it_and_gives_every_message_after_it(tmp_path: Path,
                                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    """``BagReader.messages(from_ns=T)`` (the replay's seek): chunks whose messages all come before T are passed
    over unread (of each, only its record header and its two times are read from the file), and every message at or
    after T still comes, as a full read gives them; ``pass_before_ns`` moved while reading (a seek forward) passes
    over what follows up to it. In a file without a summary (cut short) no
    chunk is passed over until a reader has read it (its channels are known only so): a reader that takes what one
    that has learnt (``carry_from``) does pass over them, but not once the file has changed (a recording still
    written). A summary without the channels (written without repeating them) passes over nothing either."""
    w = BagWriter(tmp_path / "full.mcap", chunk_size=4096)
    w.add_channel("/t", "std_msgs/msg/String", [profile_dict()])
    w.add_channel("/u", "std_msgs/msg/String", [profile_dict()])
    for k in range(400):  # /u defined only after the first chunks: its definition is in a chunk a seek passes
        w.write("/t" if k < 100 or k % 2 else "/u", serialize_message(String(data=f"{k:03d}" + "x" * 60)),
                10**9 + k * 10**7)
    w.close()
    full = list(BagReader.open(tmp_path / "full.mcap").messages())
    t = full[300].log_time
    after = [(m.topic, m.data) for m in full if m.log_time >= t]

    def read(reader: BagReader, from_ns: int | None) -> list[tuple[str, bytes]]:
        return [(m.topic, m.data) for m in reader.messages(from_ns=from_ns) if m.log_time >= t]

    counted = [0]  # bytes the reader reads from its files (the summary's included)

    class Counted(io.BufferedReader):
        def read(self, n: int = -1) -> bytes:
            data = super().read(n)
            counted[0] += len(data)
            return data

    monkeypatch.setattr(reader_module, "open", lambda path, mode="rb": Counted(io.FileIO(path, mode)), raising=False)
    list(BagReader.open(tmp_path / "full.mcap").messages())
    whole, counted[0] = counted[0], 0
    r = BagReader.open(tmp_path / "full.mcap")
    got = list(r.messages(from_ns=t))
    assert [(m.topic, m.data) for m in got if m.log_time >= t] == after and r.stopped == []
    assert r.passed_chunks >= 5 and len(got) - len(after) < 100  # only the chunk holding t from before it
    with open(tmp_path / "full.mcap", "rb") as f:
        chunks = make_reader(f).get_summary().chunk_indexes
    # of a chunk passed over, its opcode and length (9 bytes) and its two times (16) are read, and of each of its
    # message indexes after it only the opcode and length; of every other chunk, each byte once
    passed = [c for c in chunks if c.message_end_time < t]
    assert len(passed) == r.passed_chunks
    assert whole - counted[0] == sum(c.chunk_length - 9 - 16 + c.message_index_length - 9 * len(c.message_index_offsets)
                                     for c in passed)
    monkeypatch.undo()
    moved = BagReader.open(tmp_path / "full.mcap")
    stream = moved.messages()
    assert next(stream).log_time == full[0].log_time
    moved.pass_before_ns = t
    assert [(m.topic, m.data) for m in stream if m.log_time >= t] == after and moved.passed_chunks >= 4

    cut_after_last_chunk(tmp_path / "full.mcap", tmp_path / "cut.mcap")  # every chunk, no summary
    first = BagReader.open(tmp_path / "cut.mcap")
    assert read(first, t) == after and first.passed_chunks == 0  # nothing known of its chunks: all opened
    second = BagReader.open(tmp_path / "cut.mcap").carry_from(first)
    assert read(second, t) == after and second.passed_chunks >= 5 and second.stopped == first.stopped != []
    with open(tmp_path / "cut.mcap", "ab") as f:  # it grew (a recording still written): nothing known of it
        f.write(b"\0")
    grown = BagReader.open(tmp_path / "cut.mcap").carry_from(first)
    assert read(grown, t) == after and grown.passed_chunks == 0

    from mcap.writer import Writer

    with open(tmp_path / "bare.mcap", "wb") as f:  # a summary without its channels and schemas
        mw = Writer(f, chunk_size=4096, repeat_channels=False, repeat_schemas=False)
        mw.start(profile="ros2", library="test")
        ids = {topic: mw.register_channel(topic, "cdr", mw.register_schema("std_msgs/msg/String", "ros2msg",
                                                                             b"string data")) for topic in ("/t", "/u")}
        for m in full:
            mw.add_message(ids[m.topic], m.log_time, m.data, m.publish_time)
        mw.finish()
    bare = BagReader.open(tmp_path / "bare.mcap")
    assert read(bare, t) == after and bare.passed_chunks == 0


def test_the_data_sections_crc_is_checked_where_every_byte_was_read(tmp_path: Path) -> None:
    """A bag written with a data-section CRC (mcap's ``enable_data_crcs``; ours and rosbag2's write 0): a full read
    checks it and finds it right (a chunk's bytes are read in two parts, its times and the rest), a read that passes
    chunks over does not check it (no false mismatch), and a byte flipped outside any chunk is reported after every
    message; a message record shorter than its fields ends the stream there, named with its byte."""
    from mcap.writer import Writer

    def write(path: Path, chunked: bool) -> Path:
        with open(path, "wb") as f:
            mw = Writer(f, chunk_size=2048, use_chunking=chunked, enable_data_crcs=True)
            mw.start(profile="ros2", library="test")
            cid = mw.register_channel("/t", "cdr", mw.register_schema("std_msgs/msg/String", "ros2msg", b"string data"))
            for k in range(200):
                mw.add_message(cid, 10**9 + k * 10**7, serialize_message(String(data=f"{k:03d}" + "x" * 40)), 0)
            mw.finish()
        return path

    chunked = write(tmp_path / "chunked.mcap", True)
    full = BagReader.open(chunked)
    assert len(list(full.messages())) == 200 and full.stopped == []
    seek = BagReader.open(chunked)
    assert len([m for m in seek.messages(from_ns=10**9 + 150 * 10**7) if m.log_time >= 10**9 + 150 * 10**7]) == 50
    assert seek.passed_chunks >= 3 and seek.stopped == []

    plain = write(tmp_path / "plain.mcap", False)
    data = bytearray(plain.read_bytes())
    records, at = [], 8  # (opcode, offset) of each record after the magic
    while at < len(data) - 8:
        records.append((data[at], at))
        at += 9 + int.from_bytes(data[at + 1:at + 9], "little")
    messages = [at for op, at in records if op == 0x05]
    assert len(messages) == 200
    flipped = bytearray(data)
    flipped[messages[100] + 9 + 22 + 6] ^= 0x01  # a character of message 100's text
    (tmp_path / "flipped.mcap").write_bytes(bytes(flipped))
    hurt = BagReader.open(tmp_path / "flipped.mcap")
    got = list(hurt.messages())
    assert len(got) == 200 and len(hurt.stopped) == 1 and "CRCValidationError" in hurt.stopped[0], hurt.stopped
    short = bytearray(data)
    short[messages[50] + 1:messages[50] + 9] = (10).to_bytes(8, "little")
    (tmp_path / "short.mcap").write_bytes(bytes(short))
    cut = BagReader.open(tmp_path / "short.mcap")
    assert len(list(cut.messages())) == 50
    assert len(cut.stopped) == 1 and f"a message record at byte {messages[50]} of 10 bytes" in cut.stopped[0]


def test_bag_filter_writes_the_topics_and_the_stretch_of_time_asked_for(tmp_path: Path, cli: CliRun) -> None:
    """``zebra-sim bag filter`` (``rewrite``), as ros2 bag convert with a topic and time filter: two files read in
    order, only the topics the options keep and the messages from --start to --end seconds after the first (both
    ends inclusive), each under its own type; rosbags reads back exactly those, and the chunks before --start are not
    opened. A cut input (no summary) gives the same window. A folder of split files reads in order; ``--topics``
    names topics, and one not found is said; nothing found exits 1; bags it took (given after it) are refused, naming
    them, and ``--`` ends it. Bad values are refused naming the option, and nothing is written (an output in a
    folder read would join its recording: refused too). The files' last log time comes from their summaries, and is
    not known where one is cut."""
    from zebra_sim_ros.recording.reader import file_summary, first_log_time, last_log_time, rewrite

    written: list[tuple[str, int, str]] = []
    for k, name in enumerate(("a.mcap", "b.mcap")):
        w = BagWriter(tmp_path / name, chunk_size=2048)
        w.add_channel("/drone_0/labels", "std_msgs/msg/String", [profile_dict()])
        w.add_channel("/drone_0/image_raw", "sensor_msgs/msg/Image", [profile_dict()])
        w.add_channel("/rosout_like", "std_msgs/msg/String", [profile_dict()])
        for i in range(100):
            step = k * 100 + i
            t = 10**9 + step * 10**8  # 0.1 s apart: 20 s over the two files
            w.write("/drone_0/labels", serialize_message(String(data=f"L{step}")), t)
            w.write("/rosout_like", serialize_message(String(data=f"R{step}")), t)
            if step % 10 == 0:
                img = Image(height=2, width=2, encoding="mono8", step=2, data=bytes([step % 256] * 4))
                w.write("/drone_0/image_raw", serialize_message(img), t)
                written.append(("/drone_0/image_raw", t, str(step)))
            written.append(("/drone_0/labels", t, f"L{step}"))
        w.close()
    out = cli(["bag", "filter", tmp_path / "a.mcap", tmp_path / "b.mcap", "--out", tmp_path / "clip.mcap",
               "--topic-regex", "^/drone_0/", "--exclude-regex", "image", "--start", "5", "--end", "12.5"])
    assert out.returncode == 0, out.stderr
    assert "wrote 76 messages of 1 topics (7.500 s)" in out.stdout, out.stdout
    with AnyReader([tmp_path / "clip.mcap"]) as r:
        got = [(c.topic, t, r.deserialize(raw, c.msgtype).data) for c, t, raw in r.messages()]
    want = [(topic, t, data) for topic, t, data in written if topic == "/drone_0/labels" and 50 <= (t - 10**9) // 10**8
            <= 125]
    assert got == want
    info = cli(["bag", "info", tmp_path / "clip.mcap"])  # as ros2 bag info: its start and end, date and seconds
    assert info.returncode == 0 and "start:     1970-01-01T00:00:06.000Z (6.000000000)\n" in info.stdout and \
        "end:       1970-01-01T00:00:13.500Z (13.500000000)\n" in info.stdout, info.stdout

    s = rewrite([tmp_path / "a.mcap", tmp_path / "b.mcap"], tmp_path / "imgs.mcap",
                keep=lambda topic: topic == "/drone_0/image_raw", start_s=15.0)
    assert (s["messages"], s["topics"], s["start_ns"]) == (5, {"/drone_0/image_raw": 5}, 10**9 + 150 * 10**8)
    assert s["passed_chunks"] >= 8  # a.mcap's 6 chunks of 2 KiB and b.mcap's before 15 s (3 today): not opened
    with AnyReader([tmp_path / "imgs.mcap"]) as r:
        [conn] = r.connections
        assert conn.msgtype == "sensor_msgs/msg/Image"
        assert [r.deserialize(raw, conn.msgtype).data[0] for _, _, raw in r.messages()] == [150, 160, 170, 180, 190]

    cut_after_last_chunk(tmp_path / "b.mcap", tmp_path / "cut.mcap")
    assert first_log_time([tmp_path / "cut.mcap"]) == 10**9 + 100 * 10**8
    # the last from the summaries alone (the replay's ~/seek refuses past it); a cut file's is not known so
    assert last_log_time([tmp_path / "b.mcap", tmp_path / "a.mcap"]) == 10**9 + 199 * 10**8
    assert last_log_time([tmp_path / "a.mcap", tmp_path / "cut.mcap"]) is None
    # each file's summary is parsed once per version of it: asked again, the same; rewritten at the same path (each
    # time with a size of its own), read again
    summary = file_summary(tmp_path / "a.mcap")
    assert summary is not None and file_summary(tmp_path / "a.mcap") is summary
    changing = tmp_path / "changing.mcap"
    for src, end in ((tmp_path / "a.mcap", 10**9 + 99 * 10**8), (tmp_path / "b.mcap", 10**9 + 199 * 10**8),
                     (tmp_path / "cut.mcap", None)):  # the same path, each time other bytes (the last cut short)
        changing.write_bytes(src.read_bytes())
        assert last_log_time([changing]) == end, src.name
    cut = rewrite(tmp_path / "cut.mcap", tmp_path / "cut_clip.mcap", start_s=2.0, end_s=2.0)
    assert (cut["messages"], cut["start_ns"], cut["end_ns"]) == (3, 10**9 + 120 * 10**8, 10**9 + 120 * 10**8)

    (tmp_path / "run").mkdir()
    for k in (0, 1):  # a split recording's folder: read in order, and no output may go into it
        (tmp_path / "run" / f"run_{k}.mcap").write_bytes((tmp_path / ("a.mcap", "b.mcap")[k]).read_bytes())
    out = cli(["bag", "filter", tmp_path / "run", "--out", tmp_path / "img.mcap", "--topics", "/drone_0/image_raw",
               "/nothing", "--end", "1.0"])
    assert out.returncode == 0 and "wrote 2 messages of 1 topics (1.000 s)" in out.stdout, out.stdout
    assert "not in the bags, or no message in the stretch asked for: /nothing" in out.stdout
    empty = cli(["bag", "filter", tmp_path / "run", "--out", tmp_path / "none.mcap", "--start", "100"])
    assert empty.returncode == 1 and "no message matched" in empty.stderr, empty.stderr

    for bad, named in ((["--start", "-1"], "'--start'"), (["--start", "5", "--end", "2"], "'--end'"),
                       (["--topic-regex", "(x"], "'--topic-regex'"), (["--compression", "gzip"], "--compression"),
                       (["--out", tmp_path / "a.mcap"], "'--out'"), (["--out", tmp_path / "run" / "x.mcap"], "'--out'"),
                       (["--out", tmp_path / "run"], "'--out'")):
        args = ["bag", "filter", tmp_path / "a.mcap", tmp_path / "run",
                *(["--out", tmp_path / "bad.mcap"] if "--out" not in bad else []), *bad]
        run = cli(args)
        assert run.returncode == 2 and named in run.stderr, (bad, run.stderr)
    swallowed = cli(["bag", "filter", "--out", tmp_path / "bad.mcap", "--topics", "/drone_0/labels",
                     tmp_path / "b.mcap"])
    assert swallowed.returncode == 2 and "'--topics'" in swallowed.stderr and "is a bag" in swallowed.stderr
    one_left = cli(["bag", "filter", tmp_path / "a.mcap", "--out", tmp_path / "bad.mcap", "--topics", "/drone_0/labels",
                    tmp_path / "run"])  # a bag before it does not hide the one it took
    assert one_left.returncode == 2 and "is a bag" in one_left.stderr and str(tmp_path / "run") in one_left.stderr
    (tmp_path / "no_bags").mkdir()  # topic names that are also a folder, but of no bags, and a file, but no MCAP one
    (tmp_path / "notes").write_text("not a bag\n")
    folder = cli(["bag", "filter", tmp_path / "a.mcap", "--out", tmp_path / "folder.mcap", "--topics",
                  str(tmp_path / "no_bags"), str(tmp_path / "notes")])
    assert folder.returncode == 1 and "not in the bags" in folder.stdout + folder.stderr, folder.stderr
    ended = cli(["bag", "filter", "--out", tmp_path / "end.mcap", "--topics", "/drone_0/labels", "--",
                 tmp_path / "run"])
    assert ended.returncode == 0 and "/drone_0/labels" in ended.stdout, ended.stderr
    none = cli(["bag", "filter", "--out", tmp_path / "bad.mcap", "--topics", "/drone_0/labels"])
    assert none.returncode == 2 and "'bag'" in none.stderr
    assert not (tmp_path / "bad.mcap").exists() and sorted(p.name for p in (tmp_path / "run").iterdir()) == \
        ["run_0.mcap", "run_1.mcap"]


def test_run_summary_reads_a_cut_bag_once_and_notes_the_cut_once(tmp_path: Path) -> None:
    from zebra_sim_ros.graph.summary import summarize_run

    [path] = _write(tmp_path / "full.mcap", n=300)
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    s = summarize_run(cut)
    assert len(s["damaged"]) == 1 and "stopped at byte" in s["damaged"][0]


def test_typed_detections_decode_as_rosbags_reads_them_and_score(tmp_path: Path) -> None:
    """The detector's Detection2DArray in a bag: our CDR reader gives the boxes and scores rosbags (an independent
    reader, from the schema in the bag) gives, and bag evaluation scores them as it scored the JSON."""
    from zebra_sim_ros.messages import Detection, Detections, Stamp
    from zebra_sim_ros.nodes.ros_adapter import detection_array_msg, detection_array_type
    from zebra_sim_ros.recording.cdr import cdr_detections

    type_name = detection_array_type()
    w = BagWriter(tmp_path / "t.mcap")
    w.add_channel("/drone_0/labels", "std_msgs/msg/String", [profile_dict()])
    w.add_channel("/drone_0/detections", type_name, [profile_dict()])
    sent = []
    for k in range(3):
        stamp = {"sec": k, "nanosec": 7}
        z = [{"box_visible": [10.0, 10, 50, 40], "kept": True, "visible_pixels": 1100}]
        dets = Detections(Stamp(k, 7), "drone_0/camera_optical", 320, 180, (
            Detection((10.0, 10.0, 50.0, 40.0), 0.9), Detection((200.5, 20.25, 230.0, 60.0), 0.3 + 0.1 * k)))
        header = Header(frame_id="drone_0/camera_optical")
        header.stamp.sec, header.stamp.nanosec = k, 7
        data = serialize_message(detection_array_msg(type_name, header, dets))
        sent.append(dets)
        w.write("/drone_0/labels", serialize_message(String(data=json.dumps(_labels(stamp, z)))), k * 10**9 + 7)
        w.write("/drone_0/detections", data, k * 10**9 + 7)
    w.close()
    with AnyReader([tmp_path / "t.mcap"]) as reader:
        conns = [c for c in reader.connections if c.topic == "/drone_0/detections"]
        theirs = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=conns)]
    for msg, back, orig in zip(theirs, (cdr_detections(m.data) for m in BagReader.open(tmp_path / "t.mcap").messages()
                                        if m.topic == "/drone_0/detections"), sent, strict=True):
        assert back.stamp == orig.stamp and back.frame_id == orig.frame_id
        for d, b, o in zip(msg.detections, back.detections, orig.detections, strict=True):
            cx, cy = d.bbox.center.position.x, d.bbox.center.position.y
            assert b.box_xyxy == pytest.approx((cx - d.bbox.size_x / 2, cy - d.bbox.size_y / 2,
                                                cx + d.bbox.size_x / 2, cy + d.bbox.size_y / 2))
            assert b.box_xyxy == pytest.approx(o.box_xyxy) and b.score == pytest.approx(o.score)
            assert d.results[0].hypothesis.class_id == b.class_name == "zebra"
    s = score(collect(tmp_path / "t.mcap"))
    assert s["drone_0"]["frames"] == 3 and s["drone_0"]["mAP50"] == pytest.approx(1.0)


def test_bag_eval_scores_zebras_only(tmp_path: Path) -> None:
    """Detections of another class (a model with other_animal) in a bag are neither true nor false zebras."""
    from zebra_sim_ros.messages import Detection, Detections, Stamp
    from zebra_sim_ros.nodes.ros_adapter import detection_array_msg, detection_array_type

    type_name = detection_array_type()
    w = BagWriter(tmp_path / "o.mcap")
    w.add_channel("/drone_0/labels", "std_msgs/msg/String", [profile_dict()])
    w.add_channel("/drone_0/detections", type_name, [profile_dict()])
    for k in range(2):
        z = [{"box_visible": [10.0, 10, 50, 40], "kept": True, "visible_pixels": 1100}]
        dets = Detections(Stamp(k, 0), "drone_0/camera_optical", 320, 180, (
            Detection((10.0, 10.0, 50.0, 40.0), 0.6),
            Detection((200.0, 20.0, 260.0, 60.0), 0.95, 1, "other_animal")))  # outscores the zebra
        header = Header(frame_id="drone_0/camera_optical")
        header.stamp.sec = k
        w.write("/drone_0/labels", serialize_message(String(data=json.dumps(_labels({"sec": k, "nanosec": 0}, z)))),
                k * 10**9)
        w.write("/drone_0/detections", serialize_message(detection_array_msg(type_name, header, dets)), k * 10**9)
    w.close()
    s = score(collect(tmp_path / "o.mcap"))
    assert s["drone_0"]["frames"] == 2
    assert s["drone_0"]["mAP50"] == pytest.approx(1.0) and s["drone_0"]["precision"] == pytest.approx(1.0)


def test_compressed_images_read_back_as_image_transport_writes_them() -> None:
    """CompressedImage data as compressed_image_transport writes and reads it: png to the byte, jpeg within its
    loss; the bare formats camera drivers send; a clear error for what is not a colour image."""
    import cv2

    from zebra_sim_ros.recording.images import compress_rgb, decompress_rgb

    yy, xx = np.mgrid[0:90, 0:160]
    rgb = np.stack([xx * 1.5, yy * 2.5, (xx + yy) % 256], axis=-1).astype(np.uint8)  # smooth, each channel its own
    fmt, data = compress_rgb(rgb, "png")
    assert fmt == "rgb8; png compressed bgr8" and np.array_equal(decompress_rgb(fmt, data), rgb)
    fmt, data = compress_rgb(rgb, "jpeg", 95)
    assert fmt == "rgb8; jpeg compressed bgr8" and np.abs(decompress_rgb(fmt, data).astype(int) - rgb).mean() < 2.0
    assert len(compress_rgb(rgb, "jpeg", 30)[1]) < len(data)  # quality is applied
    bgr_jpeg = cv2.imencode(".jpg", np.ascontiguousarray(rgb[..., ::-1]), [cv2.IMWRITE_JPEG_QUALITY, 95])[1].tobytes()
    assert np.abs(decompress_rgb("jpeg", bgr_jpeg).astype(int) - rgb).mean() < 2.0  # a driver's bare format
    grey = cv2.imencode(".png", rgb[..., 0])[1].tobytes()
    assert np.array_equal(decompress_rgb("mono8; png compressed mono8", grey), np.repeat(rgb[..., :1], 3, axis=2))
    with pytest.raises(ValueError, match="unsupported compressed format '16UC1; compressedDepth'"):
        decompress_rgb("16UC1; compressedDepth", data)
    with pytest.raises(ValueError, match="not an 8-bit colour or grey image"):  # a depth image through png
        decompress_rgb("16UC1; png compressed ", data)
    with pytest.raises(ValueError, match="an empty jpeg image"):
        decompress_rgb("rgb8; jpeg compressed bgr8", b"")
    from zebra_sim_ros.recording.images import CompressedFormat

    parsed = {f: CompressedFormat.parse(f) for f in ("rgb8; jpeg compressed bgr8", "JPG", "16UC1; png compressed ",
                                                    "mono8; png compressed mono8", "bgr8; jpeg compressed rgb8")}
    with pytest.raises(ValueError, match="unsupported compressed format"):  # bare: the whole string is the codec
        decompress_rgb("jpeg compressed rgb8", data)
    assert [(p.encoding, p.codec, p.codec_encoding, p.colour, p.holds_bgr) for p in parsed.values()] == [
        ("rgb8", "jpeg", "bgr8", True, True), ("", "jpeg", "", True, True), ("16UC1", "png", "", False, False),
        ("mono8", "png", "mono8", True, False), ("bgr8", "jpeg", "rgb8", True, False)]
    # a codec that held RGB is not turned around
    rgb_png = cv2.imencode(".png", rgb)[1].tobytes()
    assert np.array_equal(decompress_rgb("rgb8; png compressed rgb8", rgb_png), rgb)
    from rclpy.serialization import serialize_message as ser
    from sensor_msgs.msg import CompressedImage

    from zebra_sim_ros.recording.images import message_rgb

    depth = CompressedImage(format="32FC1; png compressed ", data=data)
    assert message_rgb("sensor_msgs/msg/CompressedImage", ser(depth)) is None  # not camera colour: left out
    with pytest.raises(ValueError, match="cut short"):
        message_rgb("sensor_msgs/msg/CompressedImage", ser(CompressedImage(format=fmt, data=data))[:-10])
    with pytest.raises(ValueError, match="10 bytes do not decode as png"):
        decompress_rgb("rgb8; png compressed bgr8", bytes(10))
    with pytest.raises(ValueError, match="compressed format 'webp'"):
        compress_rgb(rgb, "webp")
    with pytest.raises(ValueError, match=r"H x W x 3 uint8 image, not float64 \(90, 160, 3\)"):
        compress_rgb(rgb.astype(float), "png")


def test_eval_reads_compressed_images_and_detects_a_frame_once(tmp_path: Path,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """``bag eval --weights`` on a bag with image_raw/compressed: a drone with only compressed images is detected
    from them (as the raw image of the same pixels is), and a frame recorded both ways is detected once."""
    from sensor_msgs.msg import CompressedImage

    from zebra_sim_ros.detection.checkpoint import save_checkpoint
    from zebra_sim_ros.detection.model import ModelConfig, build_model
    from zebra_sim_ros.recording.evaluate import ImageDetector
    from zebra_sim_ros.recording.images import compress_rgb

    save_checkpoint(tmp_path / "w.pt", build_model(ModelConfig(size="n", imgsz=128)).eval())
    w = BagWriter(tmp_path / "c.mcap")
    for topic, typ in (("/drone_0/image_raw", "Image"), ("/drone_0/image_raw/compressed", "CompressedImage"),
                       ("/drone_1/image_raw/compressed", "CompressedImage")):
        w.add_channel(topic, f"sensor_msgs/msg/{typ}", [profile_dict()])
    rng = np.random.default_rng(3)
    for k in range(2):
        rgb = rng.integers(0, 255, (72, 128, 3), dtype=np.uint8)
        h = Header(frame_id="c")
        h.stamp.sec = k
        raw = serialize_message(Image(header=h, height=72, width=128, encoding="rgb8", step=384, data=rgb.tobytes()))
        fmt, data = compress_rgb(rgb, "png")
        other = serialize_message(CompressedImage(header=h, format=fmt, data=compress_rgb(rgb // 2, "png")[1]))
        # drone_0's compressed copy holds other pixels, before its raw image at stamp 0 and after it at stamp 1:
        # the raw image is detected either way; drone_1 has the raw pixels as png only
        for topic, msg in ((("/drone_0/image_raw/compressed", other), ("/drone_0/image_raw", raw)) if k == 0 else
                           (("/drone_0/image_raw", raw), ("/drone_0/image_raw/compressed", other))):
            w.write(topic, msg, k)
        w.write("/drone_1/image_raw/compressed", serialize_message(CompressedImage(header=h, format=fmt, data=data)), k)
    w.close()
    detector = ImageDetector(tmp_path / "w.pt", device="cpu", batch=8)
    import zebra_sim_ros.detection.predict as predict

    calls: list[int] = []
    detect = predict.detect

    def counted(model: Any, images: list, *args: Any, **kw: Any) -> Any:  # the images the model is given
        calls.append(len(images))
        return detect(model, images, *args, **kw)
    monkeypatch.setattr(predict, "detect", counted)
    got = detector.apply(collect(tmp_path / "c.mcap", each=detector))
    assert sum(calls) == 4 and detector.skipped == []  # drone_0's compressed copies never (its raw image came)
    for k in range(2):
        t = k * 10**9  # the header's stamp
        assert len(got.drones["drone_1"].detections[t]) > 0
        np.testing.assert_allclose(got.drones["drone_1"].detections[t], got.drones["drone_0"].detections[t],
                                   atol=1e-3)


def test_a_report_is_logged_at_the_latest_data_stamp_not_its_own() -> None:
    """Data messages are logged at their header stamp (one time base with the steps); a /diagnostics report carries
    its node's clock, wall time in a node run without sim time, and is logged at the latest stamp given so far, or
    at the recorder's clock before any; a message without a stamp at the recorder's clock."""
    from diagnostic_msgs.msg import DiagnosticArray

    from zebra_sim_ros.recording.stamps import LogTimes, header_stamp_ns

    wall = Header()
    wall.stamp.sec, wall.stamp.nanosec = 1_795_000_000, 5
    report = serialize_message(DiagnosticArray(header=wall))
    assert header_stamp_ns("diagnostic_msgs/msg/DiagnosticArray", report) == 1_795_000_000 * 10**9 + 5

    def image(sec: int) -> bytes:
        step = Header()
        step.stamp.sec = sec
        return serialize_message(Image(header=step, height=1, width=1, encoding="rgb8", step=3, data=bytes(3)))

    log_time, clock = LogTimes(), iter(range(100, 110))
    times = [log_time(t, data, lambda: next(clock)) for t, data in (
        ("diagnostic_msgs/msg/DiagnosticArray", report), ("sensor_msgs/msg/Image", image(3)),
        ("diagnostic_msgs/msg/DiagnosticArray", report), ("sensor_msgs/msg/Image", image(2)),
        ("diagnostic_msgs/msg/DiagnosticArray", report), ("std_msgs/msg/String", serialize_message(String(data="x"))))]
    assert times == [100, 3 * 10**9, 3 * 10**9, 2 * 10**9, 3 * 10**9, 101]


def test_the_preview_puts_four_drones_to_a_row_in_their_order(tmp_path: Path) -> None:
    """``up``'s preview: one tile per drone, drone_2 before drone_10, four to a row (a row of 16 large frames would
    be past JPEG's 65535 px), each tile its drone's frame (a grey level per drone here)."""
    import cv2

    from zebra_sim_ros.graph.summary import PREVIEW_COLUMNS, write_preview

    images = {f"drone_{k}": (0, np.full((40, 64, 3), 10 * k, np.uint8)) for k in range(11)}
    sheet = cv2.imread(str(write_preview(tmp_path / "p.png", {}, images)))
    assert PREVIEW_COLUMNS == 4 and sheet.shape == (3 * 40, 4 * 64, 3)
    # each tile's bottom right corner, which no legend reaches
    order = [int(sheet[39 + 40 * (k // 4), 64 * (k % 4) + 63, 0]) // 10 for k in range(11)]
    assert order == list(range(11))
    assert not sheet[80:, 3 * 64:].any()  # the last row's empty place is black


def test_bag_export_pairs_images_with_labels_as_a_yolo_set(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``bag export``: each image with the labels of its stamp, the kept zebras as YOLO lines and the ones seen but
    not kept as don't-care boxes, the pixels as recorded (bgr8 here, written as png); an image without labels,
    labels without an image, a mask-like image and a message that does not parse are counted or noted, not written."""
    import cv2

    from zebra_sim_ros.cli import main
    from zebra_sim_ros.dataset.bag_export import ExportConfig, export_bag

    w = BagWriter(tmp_path / "x.mcap")
    w.add_channel("/drone_0/image_raw", "sensor_msgs/msg/Image", [profile_dict()])
    w.add_channel("/drone_0/labels", "std_msgs/msg/String", [profile_dict()])
    zebras = [{"box_visible": [10.0, 10, 30, 20], "kept": True, "visible_pixels": 150},
              {"box_visible": [64.0, 36, 68, 39], "kept": False, "visible_pixels": 8}]
    for k in range(3):
        img = Image(header=Header(frame_id="c"), height=72, width=128, encoding="bgr8", step=384,
                    data=bytes([10 + k, 20, 30]) * (72 * 128))
        img.header.stamp.sec = k
        w.write("/drone_0/image_raw", serialize_message(img), k)
        if k < 2:  # step 2 has no labels
            lab = {**_labels({"sec": k, "nanosec": 0}, zebras), "width": 128, "height": 72}
            w.write("/drone_0/labels", serialize_message(String(data=json.dumps(lab))), k)
    lost = {**_labels({"sec": 5, "nanosec": 0}, zebras), "width": 128, "height": 72}  # no image comes
    w.write("/drone_0/labels", serialize_message(String(data=json.dumps(lost))), 5)
    w.write("/drone_0/labels", serialize_message(String(data="{not json")), 6)
    mono = Image(header=Header(frame_id="c"), height=2, width=2, encoding="mono8", step=2, data=bytes(4))
    mono.header.stamp.sec = 7
    w.write("/drone_0/image_raw", serialize_message(mono), 7)
    w.write("/drone_0/labels", serialize_message(String(data=json.dumps(
        {**_labels({"sec": 7, "nanosec": 0}, zebras), "width": 2, "height": 2}))), 7)
    w.close()
    s = export_bag(ExportConfig((str(tmp_path / "x.mcap"),), str(tmp_path / "set"), "png", val_fraction=0.0))
    assert s["frames"] == {"train": 2, "val": 0} and s["zebras_labelled"] == 2
    assert s["images_without_labels"] == 1 and s["labels_without_image"] == 1
    assert len(s["skipped"]) == 2 and "not JSON" in s["skipped"][0] and "rgb8 or bgr8" in s["skipped"][1]
    names = sorted(p.stem for p in (tmp_path / "set" / "images" / "train").glob("*.png"))
    assert names == ["x_drone_0_0", "x_drone_0_1000000000"]
    second = cv2.imread(str(tmp_path / "set" / "images" / "train" / "x_drone_0_1000000000.png"))
    assert second.shape == (72, 128, 3) and second[5, 5].tolist() == [11, 20, 30]  # B, G, R as recorded
    label = (tmp_path / "set" / "labels" / "train" / "x_drone_0_0.txt").read_text().split()
    assert [float(v) for v in label] == pytest.approx([0, 20 / 128, 15 / 72, 20 / 128, 10 / 72], abs=1e-6)
    ignore = (tmp_path / "set" / "ignore" / "train" / "x_drone_0_0.txt").read_text().split()
    assert [float(v) for v in ignore] == pytest.approx([0, 66 / 128, 37.5 / 72, 4 / 128, 3 / 72], abs=1e-6)
    from zebra_sim_ros.detection.data import resolve_splits

    # no val step drawn (--val-fraction 0): val reads the train split, so train and val both start
    assert s["val_is_train"] and resolve_splits(tmp_path / "set" / "dataset.yaml", "val") == resolve_splits(
        tmp_path / "set" / "dataset.yaml", "train") == [tmp_path / "set" / "images" / "train"]
    assert main(["bag", "export", str(tmp_path / "x.mcap"), "--out", str(tmp_path / "y"), "--format", "gif"]) == 2
    assert "'--format' = 'gif'" in capsys.readouterr().err and not (tmp_path / "y").exists()


def test_bag_export_keeps_runs_bags_and_colours_apart(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Two bags of one name, a namespaced camera, a run that starts again at the same stamps, raw and jpeg copies of
    a frame, jpeg whose codec holds RGB, a depth image in compressedDepth, a size that is not the labels': each frame
    written once with its own run's labels and its recorded colours; both splits hold a step; and a folder that
    already holds files, or is a file, is refused."""
    import cv2
    from sensor_msgs.msg import CompressedImage

    from zebra_sim_ros.dataset.bag_export import ExportConfig, export_bag
    from zebra_sim_ros.errors import ParameterError

    def labels(sec: int, x0: float, w: int = 64, h: int = 48) -> bytes:
        z = [{"box_visible": [x0, 10.0, x0 + 20, 20.0], "kept": True, "visible_pixels": 150}]
        return serialize_message(String(data=json.dumps({**_labels({"sec": sec, "nanosec": 0}, z), "width": w,
                                                         "height": h})))

    def compressed(sec: int, fmt: str, data: bytes) -> bytes:
        msg = CompressedImage(format=fmt, data=data)
        msg.header.stamp.sec = sec
        return serialize_message(msg)

    bgr = np.zeros((48, 64, 3), np.uint8)
    bgr[...] = (200, 100, 0)  # blue
    jpeg = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, 100])[1].tobytes()
    swapped = cv2.imencode(".jpg", bgr[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, 100])[1].tobytes()  # codec holds RGB
    cam = "/g1/drone_0"
    for folder in ("a", "b"):
        (tmp_path / folder).mkdir()
        w = BagWriter(tmp_path / folder / "run.mcap")
        w.add_channel(f"{cam}/image_raw", "sensor_msgs/msg/Image", [profile_dict()])
        w.add_channel(f"{cam}/image_raw/compressed", "sensor_msgs/msg/CompressedImage", [profile_dict()])
        w.add_channel(f"{cam}/labels", "std_msgs/msg/String", [profile_dict()])
        for run, x0 in ((0, 5.0), (1, 30.0)):  # the second run's zebra elsewhere: its labels must not pair back
            for sec in range(4):
                log = 100 * run + sec  # log and receive times, s: the second run 100 s after the first
                if sec in (0, 2):  # raw, and at 0 a jpeg copy too: the raw one is written
                    img = Image(header=Header(frame_id="c"), height=48, width=64, encoding="bgr8", step=192,
                                data=bgr.tobytes())
                    img.header.stamp.sec = sec
                    w.write(f"{cam}/image_raw", serialize_message(img), log, log * 10**9)
                    if sec == 0:
                        w.write(f"{cam}/image_raw/compressed", compressed(sec, "bgr8; jpeg compressed bgr8", jpeg),
                                log, log * 10**9)
                elif sec == 1:
                    fmt, data = ("bgr8; jpeg compressed bgr8", jpeg) if run == 0 else ("rgb8; jpeg compressed rgb8",
                                                                                        swapped)
                    w.write(f"{cam}/image_raw/compressed", compressed(sec, fmt, data), log, log * 10**9)
                else:
                    w.write(f"{cam}/image_raw/compressed", compressed(sec, "16UC1; compressedDepth png", b"x"), log,
                            log * 10**9)
                w.write(f"{cam}/labels", labels(sec, x0), log, log * 10**9 + 3 * 10**8)  # 0.3 s after its image
        w.close()
    (tmp_path / "c").mkdir()
    w = BagWriter(tmp_path / "c" / "odd.mcap")  # an image of another size than its labels say
    w.add_channel("/drone_0/image_raw/compressed", "sensor_msgs/msg/CompressedImage", [profile_dict()])
    w.add_channel("/drone_0/labels", "std_msgs/msg/String", [profile_dict()])
    w.write("/drone_0/image_raw/compressed", compressed(0, "jpeg", jpeg), 1)
    w.write("/drone_0/labels", labels(0, 5.0, 640, 480), 1)
    w.close()
    bags = tuple(str(tmp_path / f) for f in ("a/run.mcap", "b/run.mcap", "c/odd.mcap"))
    s = export_bag(ExportConfig(bags, str(tmp_path / "set"), val_fraction=0.5, seed=1))
    files = {p.stem: p for p in (tmp_path / "set" / "images").glob("*/*")}
    # per bag (prefixes run0, run1), per run: stamps 0 to 2 (stamp 3 is depth: skipped, as is the odd size)
    assert sorted(files) == sorted(f"b{b}_run_g1_drone_0_{sec * 10**9}{'_r1' if r else ''}"
                                   for b in (0, 1) for r in (0, 1) for sec in (0, 1, 2))
    assert sum(s["frames"].values()) == 12 and min(s["frames"].values()) > 0 and not s["val_is_train"]
    assert s["images_without_labels"] == 0 and s["labels_without_image"] == 0  # the jpeg copy of a raw frame too
    assert len(s["skipped"]) == 5 and sum("compressedDepth" in n for n in s["skipped"]) == 4
    assert "64x48 px with labels of a 640x480 image" in s["skipped"][-1]
    for stem, path in files.items():
        x0 = 30.0 if stem.endswith("_r1") else 5.0
        label = (path.parent.parent.parent / "labels" / path.parent.name / f"{stem}.txt").read_text().split()
        assert float(label[1]) == pytest.approx((x0 + 10) / 64), stem  # its own run's labels
        pixel = cv2.imread(str(path))[24, 32].tolist()
        assert abs(pixel[0] - 200) <= 3 and abs(pixel[1] - 100) <= 3 and pixel[2] <= 3, (stem, pixel)  # blue
    assert files["b0_run_g1_drone_0_1000000000"].read_bytes() == jpeg  # a BGR codec's jpeg: the recorded bytes
    assert files["b0_run_g1_drone_0_0"].suffix == ".jpg"  # raw, encoded
    with pytest.raises(ParameterError, match="'--out'"):  # it holds the export now
        export_bag(ExportConfig(bags, str(tmp_path / "set")))
    with pytest.raises(ParameterError, match="'--out'"):
        export_bag(ExportConfig(bags, bags[0]))
    # one step only, or no val drawn: val is the train split, and dataset.yaml says so
    one = export_bag(ExportConfig((bags[2],), str(tmp_path / "one"), val_fraction=0.5))
    assert one["val_is_train"] and "val: images/train" in (tmp_path / "one" / "dataset.yaml").read_text()


def test_bag_export_pairs_by_arrival_so_late_labels_and_a_run_without_labels_pair_right(tmp_path: Path) -> None:
    """Labels arriving out of order (steps 0, 2, 1) still pair with their images; a run of images the labeller
    missed (restarted later) is counted, not paired with the next run's labels; a step sent again with the same
    labels is one frame."""
    from zebra_sim_ros.dataset.bag_export import ExportConfig, export_bag

    def labels(sec: int, x0: float) -> bytes:
        z = [{"box_visible": [x0, 10.0, x0 + 20, 20.0], "kept": True, "visible_pixels": 150}]
        return serialize_message(String(data=json.dumps({**_labels({"sec": sec, "nanosec": 0}, z), "width": 64,
                                                         "height": 48})))

    def image(sec: int, level: int) -> bytes:
        img = Image(header=Header(frame_id="c"), height=48, width=64, encoding="bgr8", step=192,
                    data=bytes([level]) * (48 * 192))
        img.header.stamp.sec = sec
        return serialize_message(img)

    w = BagWriter(tmp_path / "lag.mcap")
    w.add_channel("/drone_0/image_raw", "sensor_msgs/msg/Image", [profile_dict()])
    w.add_channel("/drone_0/labels", "std_msgs/msg/String", [profile_dict()])
    s = 10**9
    for sec in range(3):  # run 0, level 10: images at 0, 1, 2 s; labels of 0, then 2, then 1 (and 1 sent again)
        w.write("/drone_0/image_raw", image(sec, 10), sec, sec * s)
    for sec, at in ((0, 0.3), (2, 2.3), (1, 2.4), (1, 2.5)):
        w.write("/drone_0/labels", labels(sec, 5.0), sec, int(at * s))
    for sec in range(3):  # run 1, level 50, 100 s later: no labeller yet
        w.write("/drone_0/image_raw", image(sec, 50), sec, (100 + sec) * s)
    for sec in range(3):  # run 2, level 90, 200 s later: labels with the zebra elsewhere
        w.write("/drone_0/image_raw", image(sec, 90), sec, (200 + sec) * s)
        w.write("/drone_0/labels", labels(sec, 30.0), sec, (200 + sec) * s + 3 * 10**8)
    w.close()
    out = export_bag(ExportConfig((str(tmp_path / "lag.mcap"),), str(tmp_path / "set"), "png", val_fraction=0.0))
    assert out["frames"] == {"train": 6, "val": 0} and out["images_without_labels"] == 3
    assert out["labels_without_image"] == 0 and out["not_written"] == 0
    import cv2

    for sec in range(3):
        for suffix, level, x0 in (("", 10, 5.0), ("_r1", 90, 30.0)):  # run 1's images (level 50) are in neither
            name = f"lag_drone_0_{sec * s}{suffix}"
            assert cv2.imread(str(tmp_path / "set" / "images" / "train" / f"{name}.png"))[0, 0, 0] == level, name
            label = (tmp_path / "set" / "labels" / "train" / f"{name}.txt").read_text().split()
            assert float(label[1]) == pytest.approx((x0 + 10) / 64), name


def test_a_paused_recorder_core_counts_what_arrives_and_writes_none_of_it(tmp_path: Path) -> None:
    """``RecorderCore.paused``: offered messages are counted per topic as paused (neither written nor dropped) and
    none reaches the bag; after the pause the next ones are written, in order, as rosbags reads them back."""
    from zebra_sim_ros.recording.recorder import RecorderCore

    w = BagWriter(tmp_path / "p.mcap")
    w.add_channel("/chatter", "std_msgs/msg/String", [profile_dict()])
    core = RecorderCore(w, queue_size=10, paused=True)
    assert [core.offer("/chatter", serialize_message(String(data=f"m{k}")), 10 + k) for k in range(3)] == [False] * 3
    core.paused = False
    assert all(core.offer("/chatter", serialize_message(String(data=f"m{k}")), 10 + k) for k in range(3, 5))
    (path,) = core.close()
    t = core.totals()
    assert (t["messages"], t["dropped"], t["paused"]) == (2, 0, 3)
    assert t["topics"]["/chatter"]["received"] == 5
    assert texts(Path(path)) == ["m3", "m4"]


def test_a_split_on_demand_goes_on_in_the_next_file_and_each_file_is_a_bag(tmp_path: Path) -> None:
    """``RecorderCore.split`` (the recorder's ``~/split_bagfile``): what was queued before it goes into the open
    file, what comes after into the next, each file complete on its own as rosbags reads it; a bag not split by size
    or duration keeps its name for the first file and goes on in ``<stem>_1.mcap``; one split by size numbers on from
    its own files; a split before any message leaves an empty, valid bag; after the recording ends a split is
    refused, saying why. A folder of them replays in the order written."""
    from zebra_sim_ros.recording.recorder import RecorderCore

    def offer(core: RecorderCore, ks: range) -> None:
        assert all(core.offer("/chatter", serialize_message(String(data=f"m{k}")), 10 + k) for k in ks)

    w = BagWriter(tmp_path / "a" / "run.mcap")
    w.add_channel("/chatter", "std_msgs/msg/String", [profile_dict()])
    core = RecorderCore(w, queue_size=100)
    offer(core, range(0, 3))
    assert core.split(timeout=30) == (True, f"now writing {tmp_path / 'a' / 'run_1.mcap'}")
    offer(core, range(3, 5))
    assert core.split(timeout=30)[1].endswith("run_2.mcap")
    assert core.split(timeout=30)[1].endswith("run_3.mcap")  # before any message: run_2 stays empty
    offer(core, range(5, 6))
    files = [Path(p) for p in core.close()]
    assert [p.name for p in files] == ["run.mcap", "run_1.mcap", "run_2.mcap", "run_3.mcap"]
    assert [texts(p) for p in files] == [["m0", "m1", "m2"], ["m3", "m4"], [], ["m5"]]
    assert [m.data for m in BagReader.open(tmp_path / "a").messages()] == \
        [serialize_message(String(data=f"m{k}")) for k in range(6)]  # the folder, in the order written
    ok, why = core.split()
    assert not ok and why.startswith("the recording has ended")

    w = BagWriter(tmp_path / "b" / "s.mcap", split_bytes=1 << 30)
    w.add_channel("/chatter", "std_msgs/msg/String", [profile_dict()])
    core = RecorderCore(w, queue_size=100)
    offer(core, range(0, 2))
    assert core.split(timeout=30)[1].endswith("s_1.mcap")
    offer(core, range(2, 3))
    assert [(Path(p).name, texts(Path(p))) for p in core.close()] == [("s_0.mcap", ["m0", "m1"]), ("s_1.mcap", ["m2"])]


def test_a_split_run_is_summarised_from_every_piece_in_the_order_written(tmp_path: Path) -> None:
    """``up`` reads a recording the recorder split (by size, duration or ``~/split_bagfile``) from all its pieces:
    ``UpConfig.bag_files`` lists the bag and its ``zebra_sim_<k>.mcap`` pieces by number (``_2`` before ``_10``),
    nothing else of the folder; ``summarize_run`` over two pieces gives the figures of the same run in one file and
    names both as its source."""
    from zebra_sim_ros.graph.spec import UpConfig
    from zebra_sim_ros.graph.summary import summarize_run

    cfg = UpConfig(out=str(tmp_path / "run"))
    assert cfg.bag_files() == []
    Path(cfg.out).mkdir()
    for name in ("zebra_sim.mcap", "zebra_sim_10.mcap", "zebra_sim_2.mcap", "zebra_sim_x.mcap", "other_1.mcap",
                 "zebra_sim_1.jpg"):
        (Path(cfg.out) / name).write_bytes(b"")
    assert [p.name for p in cfg.bag_files()] == ["zebra_sim.mcap", "zebra_sim_2.mcap", "zebra_sim_10.mcap"]

    rng = np.random.default_rng(9)
    herd = np.column_stack([rng.uniform(-10, 10, (10, 2)), np.full(10, 0.7)])
    views = {cam: {t * 10**9: herd[rng.permutation(10)[:8]] for t in (1, 2)} for cam in ("drone_0", "drone_1")}
    whole = _census_bag(tmp_path / "whole.mcap", views, recorded={10**9: 9, 2 * 10**9: 7})
    pieces = [_census_bag(tmp_path / f"piece_{t}.mcap", {c: {t * 10**9: v[t * 10**9]} for c, v in views.items()},
                          recorded={t * 10**9: n}) for t, n in ((1, 9), (2, 7))]
    one, split = summarize_run(whole), summarize_run(list(pieces))
    assert (split["bag"], split["bags"]) == (str(pieces[0]), [str(p) for p in pieces])
    assert (one["bag"], one["bags"]) == (str(whole), [str(whole)])
    for part in ("located", "census"):  # the same figures, to float rounding
        assert split[part].keys() == one[part].keys()
        assert all(v == pytest.approx(one[part][k], rel=1e-9, abs=1e-12) if isinstance(v, float) else v == one[part][k]
                   for k, v in split[part].items()), (split[part], one[part])
    assert split["located"]["frames"] == 4


def test_snapshot_mode_keeps_the_newest_messages_in_memory_and_writes_them_on_a_snapshot(tmp_path: Path) -> None:
    """``RecorderCore`` in snapshot mode (the recorder's ``snapshot_size_mb`` and ``~/snapshot``): nothing reaches
    the disk until a snapshot (a deferred writer makes no file); the cache keeps the newest messages that fit its
    size, the older ones counted as expired; a snapshot writes the cache, in order, into a file of its own that is
    complete at once (read back while the recording goes on), names it, and empties the cache; with a duration, only
    that much log time before the newest is kept; an empty cache writes nothing and says so; a split is refused;
    outside snapshot mode, or after close, a snapshot is refused; a duration without a size is refused, naming it
    (the node's parameter too)."""
    from zebra_sim_ros.errors import ParameterError
    from zebra_sim_ros.recording.config import RecorderConfig
    from zebra_sim_ros.recording.recorder import RecorderCore

    def msg(k: int) -> bytes:
        return serialize_message(String(data=f"{k:03d}" + "x" * 97))  # 112 bytes each

    size = len(msg(0))
    bag = tmp_path / "snaps" / "snap.mcap"
    w = BagWriter(bag, defer_open=True)
    assert bag.parent.is_dir() and w.files == [] and w.open_file is None
    w.add_channel("/chatter", "std_msgs/msg/String", [profile_dict()])
    core = RecorderCore(w, queue_size=10, snapshot_bytes=4 * size + 10, snapshot_ns=10**9)
    assert all(core.offer("/chatter", msg(k), k * 10**8) for k in range(10))  # 0.1 s apart
    t = core.totals()
    assert (t["messages"], t["cached"], t["expired"], t["received"], t["taken"]) == (0, 4, 6, 10, 10)
    assert t["cached_mb"] == pytest.approx(4 * size / 2**20, abs=0.006)  # MiB, as every size of the recorder
    assert not bag.exists()
    assert core.split() == (False, "snapshot mode writes each snapshot into a file of its own: nothing to split")
    assert core.snapshot(timeout=10) == (True, f"wrote 4 messages ({4 * size / 2**20:.2f} MB, 0.30 s of log time) "
                                               f"to {bag}")
    assert [s[:3] for s in texts(bag)] == ["006", "007", "008", "009"]  # complete now, not at close
    assert core.snapshot() == (True, "the cache is empty: nothing to write")
    core.paused = True  # counted as received and paused, not taken into the cache
    assert not core.offer("/chatter", msg(11), 11 * 10**8) and core.totals()["taken"] == 10
    core.paused = False
    for k in (20, 30, 45):  # 2.0, 3.0, 4.5 s: only the last is within 1 s of the newest
        core.offer("/chatter", msg(k), k * 10**8)
    assert core.snapshot(timeout=10)[1].endswith(f"to {bag.with_name('snap_1.mcap')}")
    files = core.close()
    t = core.totals()
    assert (t["messages"], t["expired"], t["snapshots"], t["paused"], t["taken"]) == (5, 8, 2, 1, 13)
    assert t["topics"]["/chatter"]["received"] == 14
    assert files == [str(bag), str(bag.with_name("snap_1.mcap"))]  # no empty file after the last snapshot
    assert [s[:3] for s in texts(Path(files[1]))] == ["045"]
    ok, why = core.snapshot()
    assert not ok and "ended" in why
    unused = BagWriter(tmp_path / "none.mcap", defer_open=True)
    assert unused.close() == [] and not (tmp_path / "none.mcap").exists()
    with pytest.raises(ParameterError, match="output"):  # a file where its folder should be: refused at once
        BagWriter(bag / "x.mcap", defer_open=True)

    # a snapshot that reaches the size cap on the way: what it wrote is in a finished file, and the answer says so
    capped = BagWriter(tmp_path / "cap.mcap", chunk_size=1024, max_bytes=20_000, defer_open=True)
    capped.add_channel("/chatter", "std_msgs/msg/String", [profile_dict()])
    core = RecorderCore(capped, snapshot_bytes=1 << 20)
    for k in range(50):
        core.offer("/chatter", serialize_message(String(data=f"{k:03d}" + "y" * 997)), k * 10**8)
    ok, why = core.snapshot(timeout=10)
    k = int(why.split(" of ")[0])
    assert not ok and 0 < k < 50 and f"written to {tmp_path / 'cap.mcap'}; the recording has ended: bag reached its " \
        "size cap" in why, why
    assert [text[:3] for text in texts(tmp_path / "cap.mcap")] == [f"{i:03d}" for i in range(k)]  # finished
    assert core.close() == [str(tmp_path / "cap.mcap")] and core.totals()["dropped"] == 50 - k

    # a writer with its file open already: the first snapshot goes into it
    opened = BagWriter(tmp_path / "open.mcap")
    opened.add_channel("/chatter", "std_msgs/msg/String", [profile_dict()])
    core = RecorderCore(opened, snapshot_bytes=10 * size)
    core.offer("/chatter", msg(1), 10**8)
    assert core.snapshot(timeout=10)[1].endswith(f"to {tmp_path / 'open.mcap'}")
    assert core.close() == [str(tmp_path / "open.mcap")]

    plain = RecorderCore(BagWriter(tmp_path / "plain.mcap"), queue_size=10)
    assert plain.snapshot() == (False, "not in snapshot mode")
    plain.close()
    with pytest.raises(ValueError, match="a duration only with a size"):
        RecorderCore(BagWriter(tmp_path / "bad.mcap"), snapshot_ns=10**9)
    with pytest.raises(ParameterError, match="snapshot_duration_s"):
        RecorderConfig(snapshot_duration_s=5.0).check()
    with pytest.raises(ParameterError, match="snapshot_size_mb"):  # under a byte would be no snapshot mode at all
        RecorderConfig(snapshot_size_mb=1e-7).check()


def test_a_next_file_that_cannot_be_opened_ends_the_recording_with_its_reason(tmp_path: Path) -> None:
    """A split whose next file cannot be opened (a folder in its place) ends the recording: the split is refused
    with the reason naming the file, later messages are dropped and counted, nothing hangs, and the first file is a
    finalised bag with every message written before it."""
    import time

    from zebra_sim_ros.recording.recorder import RecorderCore

    (tmp_path / "run_1.mcap").mkdir()  # where the split would go
    w = BagWriter(tmp_path / "run.mcap")
    w.add_channel("/chatter", "std_msgs/msg/String", [profile_dict()])
    core = RecorderCore(w, queue_size=10)
    assert all(core.offer("/chatter", serialize_message(String(data=f"m{k}")), 10 + k) for k in range(3))
    ok, why = core.split(timeout=30)
    assert not ok and why.startswith("the recording has ended") and "run_1.mcap" in why, why
    assert not core.offer("/chatter", serialize_message(String(data="m3")), 13)
    t = time.monotonic()
    files = core.close(timeout=30)
    assert time.monotonic() - t < 20
    totals = core.totals()
    assert (totals["messages"], totals["dropped"]) == (3, 1) and "run_1.mcap" in totals["error"]
    assert files[0] == str(tmp_path / "run.mcap") and texts(Path(files[0])) == ["m0", "m1", "m2"]
