"""``zebra-sim predict`` on a folder, a video and a bag: drawn images, YOLO labels and JSON per image."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from cli_helpers import CliRun
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Image
from std_msgs.msg import Header

from zebra_sim_ros.messages import Detections
from zebra_sim_ros.recording.qos import profile_dict
from zebra_sim_ros.recording.writer import BagWriter


def _zebra_like(seed: int, size: tuple[int, int] = (160, 96)) -> np.ndarray:
    """A small RGB frame: savanna-coloured noise with a black-and-white striped blob."""
    rng = np.random.default_rng(seed)
    w, h = size
    img = (np.array([150, 130, 80]) + rng.normal(0, 20, (h, w, 3))).clip(0, 255).astype(np.uint8)
    x0, y0 = int(rng.integers(10, w - 60)), int(rng.integers(10, h - 40))
    stripes = ((np.arange(50) // 4) % 2 * 255).astype(np.uint8)
    img[y0:y0 + 25, x0:x0 + 50] = stripes[None, :, None]
    return img


def _predict(cli: CliRun, *args: str) -> dict:
    run = cli(["predict", *args, "--json"])
    assert run.returncode == 0, run.stderr[-3000:]
    assert "images/s" in run.stdout  # the throughput line
    return dict(json.loads(run.stdout.strip().splitlines()[-1]))


def test_predict_a_folder_writes_one_drawn_image_label_and_json_each(tmp_path: Path, cli: CliRun) -> None:
    src = tmp_path / "frames"
    (src / "sub").mkdir(parents=True)
    for k in range(20):
        cv2.imwrite(str(src / ("sub" if k % 5 == 0 else ".") / f"f{k:02d}.png"), _zebra_like(k)[..., ::-1])
    out = tmp_path / "out"
    # conf 0.001: a striped blob is no zebra to weights trained on rendered ones (stage 13 scores none of them
    # over 0.02); this test needs detections to check the files, not good ones
    s = _predict(cli, str(src), "--out", str(out), "--conf", "0.001", "--quiet")
    assert s["images"] == 20
    drawn = sorted((out / "images").glob("*.jpg"))
    labels = sorted((out / "labels").glob("*.txt"))
    jsons = sorted((out / "json").glob("*.json"))
    assert len(drawn) == len(labels) == len(jsons) == 20
    assert {p.stem for p in drawn} == {p.stem for p in labels} == {p.stem for p in jsons}
    assert "sub_f00" in {p.stem for p in labels}  # nested files keep their folder in the name
    total = 0
    for lab, js in zip(labels, jsons, strict=True):
        det = Detections.from_json(js.read_text())
        lines = [ln.split() for ln in lab.read_text().splitlines()]
        assert len(lines) == len(det.detections) and det.width == 160 and det.height == 96
        for ln, d in zip(lines, det.detections, strict=True):  # the YOLO line is the JSON box, normalised
            x0, y0, x1, y1 = d.box_xyxy
            assert [float(v) for v in ln[1:]] == pytest.approx([(x0 + x1) / 320, (y0 + y1) / 192, (x1 - x0) / 160,
                                                                (y1 - y0) / 96], abs=2e-4)
        total += len(lines)
    assert total == s["detections"] > 0  # conf 0.001: the weights find something in 20 frames
    assert cv2.imread(str(drawn[0])).shape == (96, 160, 3)


def test_predict_a_video_writes_a_drawn_video_and_labels_per_frame(tmp_path: Path, cli: CliRun) -> None:
    video = tmp_path / "clip.mp4"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter.fourcc(*"mp4v"), 10.0, (160, 96))
    for k in range(6):
        writer.write(_zebra_like(k)[..., ::-1])
    writer.release()
    out = tmp_path / "out"
    s = _predict(cli, str(video), "--out", str(out))
    assert s["images"] == 6 and s["video"] == str(out / "clip_detections.mp4")
    cap = cv2.VideoCapture(s["video"])
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 6
    cap.release()
    assert sorted(p.stem for p in (out / "labels").glob("*.txt")) == [f"clip_{k:06d}" for k in range(6)]
    assert Detections.from_json((out / "json" / "clip_000003.json").read_text()).stamp.ns == 300_000_000


def test_predict_a_bag_detects_every_camera_image_and_nothing_else(tmp_path: Path, cli: CliRun) -> None:
    bag = tmp_path / "b.mcap"
    w = BagWriter(bag)
    for topic, typ in (("/drone_0/image_raw", "sensor_msgs/msg/Image"), ("/drone_1/image_raw", "sensor_msgs/msg/Image"),
                       ("/drone_0/depth", "sensor_msgs/msg/Image")):
        w.add_channel(topic, typ, [profile_dict()])
    for k in range(3):
        h = Header()
        h.stamp.sec = k
        for d in ("drone_0", "drone_1"):
            rgb = _zebra_like(10 * k + len(d))
            enc, data = ("bgr8", rgb[..., ::-1]) if d == "drone_1" else ("rgb8", rgb)
            msg = Image(header=h, height=96, width=160, encoding=enc, step=480,
                        data=np.ascontiguousarray(data).tobytes())
            w.write(f"/{d}/image_raw", serialize_message(msg), k * 10**9)
        depth = Image(header=h, height=96, width=160, encoding="32FC1", step=640, data=bytes(96 * 640))
        w.write("/drone_0/depth", serialize_message(depth), k * 10**9)
    w.close()
    out = tmp_path / "out"
    s = _predict(cli, str(bag), "--out", str(out), "--quiet")
    assert s["images"] == 6  # one per camera image; the depth images are not camera colour
    names = sorted(p.stem for p in (out / "labels").glob("*.txt"))
    assert names == sorted(f"drone_{i}_image_raw_{k * 10**9}" for i in (0, 1) for k in range(3))
    assert Detections.from_json((out / "json" / "drone_1_image_raw_2000000000.json").read_text()).stamp.sec == 2
    s1 = _predict(cli, str(bag), "--out", str(tmp_path / "only"), "--topics", "/drone_1/image_raw", "--quiet")
    assert s1["images"] == 3


def test_predict_refuses_a_source_it_cannot_read(tmp_path: Path, cli: CliRun) -> None:
    (tmp_path / "notes.txt").write_text("x")
    for src in (tmp_path / "missing.jpg", tmp_path / "notes.txt"):
        run = cli(["predict", src, "--out", tmp_path / "o"])
        assert run.returncode == 2 and "SOURCE" in run.stderr and str(src) in run.stderr, run.stderr


def test_predict_a_bag_reads_compressed_images_as_their_pixels(tmp_path: Path, cli: CliRun) -> None:
    """A bag recorded with the cameras' ``compressed`` option: each png CompressedImage is detected as the image it
    holds (the same detections as the raw image of the same pixels); a compressed depth image is left out as a raw
    one is (not camera colour), and a colour image in a format it cannot read is named as skipped."""
    from sensor_msgs.msg import CompressedImage

    from zebra_sim_ros.recording.images import compress_rgb

    bag = tmp_path / "c.mcap"
    w = BagWriter(bag)
    w.add_channel("/drone_0/image_raw", "sensor_msgs/msg/Image", [profile_dict()])
    w.add_channel("/drone_1/image_raw/compressed", "sensor_msgs/msg/CompressedImage", [profile_dict()])
    w.add_channel("/drone_1/depth/compressedDepth", "sensor_msgs/msg/CompressedImage", [profile_dict()])
    for k in range(2):
        h = Header()
        h.stamp.sec = k
        rgb = _zebra_like(k)
        w.write("/drone_0/image_raw", serialize_message(Image(header=h, height=96, width=160, encoding="rgb8",
                                                                step=480, data=rgb.tobytes())), k * 10**9)
        fmt, data = compress_rgb(rgb, "png")
        w.write("/drone_1/image_raw/compressed", serialize_message(CompressedImage(header=h, format=fmt, data=data)),
                k * 10**9)
    w.write("/drone_1/depth/compressedDepth", serialize_message(CompressedImage(format="16UC1; compressedDepth",
                                                                                data=bytes(20))), 5 * 10**9)
    w.write("/drone_1/image_raw/compressed", serialize_message(CompressedImage(format="rgb8; webp compressed bgr8",
                                                                               data=bytes(20))), 6 * 10**9)
    w.close()
    out = tmp_path / "out"
    s = _predict(cli, str(bag), "--out", str(out), "--quiet", "--conf", "0.001")
    assert s["images"] == 4
    for k in range(2):
        raw = Detections.from_json((out / "json" / f"drone_0_image_raw_{k * 10**9}.json").read_text())
        png = Detections.from_json((out / "json" / f"drone_1_image_raw_compressed_{k * 10**9}.json").read_text())
        assert png.stamp.sec == k and len(png.detections) == len(raw.detections) > 0
        assert all(a.box_xyxy == pytest.approx(b.box_xyxy, abs=1e-3) and a.score == pytest.approx(b.score, abs=1e-4)
                   for a, b in zip(png.detections, raw.detections, strict=True))
    assert len(s["skipped"]) == 1 and "unsupported compressed format 'rgb8; webp" in s["skipped"][0], s
