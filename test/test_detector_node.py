"""The detector node over real DDS: detections with the image's stamp, conversions, bad input skipped."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from ros_helpers import (
    Peer,
    collect_diagnostics,
    detection_array_class,
    detections_dict,
    fresh_domain_id,
    node_process,
    run_node_once,
    spin_until,
)
from sensor_msgs.msg import CompressedImage, Image
from std_msgs.msg import Header

from zebra_sim_ros.detection.checkpoint import SHIPPED, save_checkpoint
from zebra_sim_ros.detection.model import ModelConfig, build_model
from zebra_sim_ros.recording.images import compress_rgb

pytestmark = pytest.mark.integration


def _weights(tmp_path: Path) -> str:
    if SHIPPED.exists():
        return ""
    path = tmp_path / "random.pt"
    save_checkpoint(path, build_model(ModelConfig(size="n", imgsz=320)).eval())
    return str(path)


def _image(stamp: Time, rgb: np.ndarray, encoding: str) -> Image:
    data = rgb[..., ::-1] if encoding == "bgr8" else rgb
    h, w = rgb.shape[:2]
    return Image(header=Header(stamp=stamp, frame_id="drone_0/camera_optical"), height=h, width=w,
                 encoding=encoding, is_bigendian=0, step=w * 3, data=np.ascontiguousarray(data).tobytes())


def _same_detections(a: list[dict], b: list[dict]) -> bool:
    """The same detections up to float noise (the same pixels through one code path, maybe in other batches) and
    the rounding the node applies (boxes to 0.01 px, scores to 1e-4): one rounding step apart at most."""
    return len(a) == len(b) and all(
        x["class_name"] == y["class_name"] and x["box_xyxy"] == pytest.approx(y["box_xyxy"], abs=0.011)
        and x["score"] == pytest.approx(y["score"], abs=1.1e-4) for x, y in zip(a, b, strict=True))


def test_detections_keep_the_image_stamp(tmp_path: Path) -> None:
    domain = fresh_domain_id()
    peer = Peer(domain, "test_detector")
    node, ex = peer.node, peer.ex
    got: list[dict] = []
    annotated: list[Image] = []
    node.create_subscription(detection_array_class(), "/drone_0/detections", lambda m: got.append(detections_dict(m)),
                             10)
    node.create_subscription(Image, "/drone_0/detections/image", annotated.append, 10)
    pub = node.create_publisher(Image, "/drone_0/image_raw", 10)
    from_png: list[dict] = []  # drone_1 sends the same pixels as a png CompressedImage
    node.create_subscription(detection_array_class(), "/drone_1/detections",
                             lambda m: from_png.append(detections_dict(m)), 10)
    pub_png = node.create_publisher(CompressedImage, "/drone_1/image_raw/compressed", 10)
    status = collect_diagnostics(node, "detector: detector")
    rgb = np.random.default_rng(0).integers(0, 255, (180, 320, 3), dtype=np.uint8)
    try:
        params = {"image_topics": ["/drone_0/image_raw", "/drone_1/image_raw/compressed"],
                  "weights": _weights(tmp_path), "imgsz": 320, "device": "cpu",
                  "diagnostics_period_s": 0.3}
        with node_process("detector", params, domain, tmp_path / "detector.log") as proc:
            assert spin_until(node, ex, lambda: node.count_subscribers("/drone_0/image_raw") > 0, 60), \
                (tmp_path / "detector.log").read_text()
            stamps = [Time(sec=10 + k, nanosec=500) for k in range(3)]
            bad = Image(header=Header(stamp=Time(sec=99), frame_id="x"), height=2, width=2, encoding="16UC1",
                        is_bigendian=0, step=4, data=bytes(8))
            log_path = tmp_path / "detector.log"
            # Our side sees the node's subscription before the node has matched our publisher (discovery is not
            # symmetric), and a message sent before that match is lost: send the bad image once a second until
            # the node has logged it; after that the match stands for the good ones.
            seen = False
            for _ in range(30):
                pub.publish(bad)
                if (seen := spin_until(node, ex, lambda: "unsupported encoding" in log_path.read_text(), 1.0)):
                    break
            assert seen, log_path.read_text()
            # /diagnostics warns in the period the bad image was skipped in
            assert spin_until(node, ex, lambda: any(s["level"] == 1 for s in status), 10), status
            warn = next(s for s in status if s["level"] == 1)
            assert "skipped" in warn["message"] and int(warn["values"]["skipped"]) >= 1, warn
            for k, s in enumerate(stamps):
                pub.publish(_image(s, rgb, "bgr8" if k == 1 else "rgb8"))
                spin_until(node, ex, lambda k=k: len(got) > k, 30)
            assert spin_until(node, ex, lambda: len(got) >= 3 and len(annotated) >= 3, 30), \
                (tmp_path / "detector.log").read_text()
            fmt, data = compress_rgb(rgb, "png")
            assert spin_until(node, ex, lambda: node.count_subscribers("/drone_1/image_raw/compressed") > 0, 30)
            for _ in range(30):  # sent again until the node has matched us (discovery is not symmetric)
                pub_png.publish(CompressedImage(header=Header(stamp=Time(sec=40), frame_id="drone_1/camera_optical"),
                                                format=fmt, data=data))
                if spin_until(node, ex, lambda: len(from_png) >= 1, 1.0):
                    break
            assert from_png, (tmp_path / "detector.log").read_text()
            assert proc.poll() is None  # the bad image did not stop it
            # ... and is OK again once images are detected without a new problem
            assert spin_until(node, ex, lambda: status[-1]["level"] == 0 and int(status[-1]["values"]["images"]) >= 4,
                              10), status[-3:]
        timed = [s for s in status if "seconds per image" in s["values"]]
        assert timed and all(0 < float(s["values"]["seconds per image"]) < 30 for s in timed), status
        assert {s["hardware_id"] for s in status} == {"cpu"} and status[-1]["values"]["verifier"] == "off"
        assert [(d["stamp"]["sec"], d["stamp"]["nanosec"]) for d in got] == [(s.sec, s.nanosec) for s in stamps]
        assert all(d["frame_id"] == "drone_0/camera_optical" for d in got)
        assert all(x["frame_id"] == "drone_0/camera_optical" and x["class_name"] == "zebra" for d in got
                   for x in d["detections"])
        assert all([x["id"] for x in d["detections"]] == [str(k) for k in range(len(d["detections"]))] for d in got)
        assert all(0 <= x["box_xyxy"][0] <= x["box_xyxy"][2] <= 320 for d in got for x in d["detections"])
        assert _same_detections(got[0]["detections"], got[1]["detections"])  # bgr8 was converted, not misread
        # the png decoded to the same pixels: the same detections, beside the compressed topic's image_raw
        assert from_png[0]["stamp"]["sec"] == 40 and from_png[0]["frame_id"] == "drone_1/camera_optical"
        assert _same_detections(from_png[0]["detections"], got[0]["detections"])
        assert annotated[0].encoding == "rgb8" and annotated[0].header.stamp.sec == 10
        log = (tmp_path / "detector.log").read_text()
        assert "unsupported encoding '16UC1'" in log
    finally:
        peer.close()


@pytest.mark.parametrize("kind", ["missing", "corrupt"])
def test_bad_weights_stop_the_node(tmp_path: Path, kind: str) -> None:
    path = tmp_path / "w.pt"
    if kind == "corrupt":
        path.write_bytes(b"not a checkpoint at all")
    proc = run_node_once("detector", {"weights": str(path)}, timeout=90)
    assert proc.returncode == 2
    assert "weights" in proc.stderr + proc.stdout and str(path) in proc.stderr + proc.stdout


@pytest.mark.parametrize("kind", ["missing", "a detector's weights"])
def test_a_bad_verifier_stops_the_node(tmp_path: Path, kind: str) -> None:
    from zebra_sim_ros.detection.checkpoint import SHIPPED

    path = tmp_path / "v.pt" if kind == "missing" else SHIPPED
    proc = run_node_once("detector", {"verifier": str(path)}, timeout=90)
    assert proc.returncode == 2
    assert "verifier" in proc.stderr + proc.stdout and str(path) in proc.stderr + proc.stdout


def test_an_empty_or_short_image_is_refused_by_name_not_detected() -> None:
    """An image of zero width or height (or too few bytes) is a ValueError the node counts and skips: it used to
    reach the detector, whose letterbox divided by zero and ended the node."""
    from zebra_sim_ros.nodes.detector import to_rgb

    for w, h in ((0, 4), (4, 0)):
        with pytest.raises(ValueError, match=rf"an empty image \({w}x{h}\)"):
            to_rgb(Image(height=h, width=w, encoding="rgb8", step=3 * w, data=bytes(3 * w * h)))
    with pytest.raises(ValueError, match="does not fit 4x4 rgb8"):
        to_rgb(Image(height=4, width=4, encoding="rgb8", step=12, data=bytes(40)))
    assert to_rgb(Image(height=1, width=2, encoding="bgr8", step=6, data=bytes([1, 2, 3, 4, 5, 6]))).tolist() == \
        [[[3, 2, 1], [6, 5, 4]]]


def test_marker_colours_follow_the_class() -> None:
    from zebra_sim_ros.detection.draw import OTHER_COLOUR
    from zebra_sim_ros.nodes.detector import ZEBRA_COLOUR, _marker_colour

    zebra = _marker_colour(np.array([0, 0, 10, 10, 0.9, 0.0]))
    other = _marker_colour(np.array([0, 0, 10, 10, 0.9, 1.0]))
    legacy = _marker_colour(np.array([0, 0, 10, 10, 0.9]))  # a one-class model's rows have no class column
    assert zebra == ZEBRA_COLOUR and legacy == ZEBRA_COLOUR
    assert (other.r, other.g, other.b) == pytest.approx(tuple(c / 255 for c in OTHER_COLOUR))
    assert other != ZEBRA_COLOUR


def test_image_topics_that_resolve_to_the_same_outputs_stop_the_node() -> None:
    """``drone_0/image_raw`` and ``/drone_0/image_raw/compressed`` differ as written but both publish
    ``/drone_0/detections`` in the root namespace: refused at start, naming the parameter, before any model loads."""
    proc = run_node_once("detector", {"image_topics": ["drone_0/image_raw", "/drone_0/image_raw/compressed"]})
    assert proc.returncode == 2
    assert "'image_topics'" in proc.stderr + proc.stdout and "/drone_0/detections" in proc.stderr + proc.stdout
    from zebra_sim_ros.detection.config import DetectorConfig
    from zebra_sim_ros.errors import ParameterError

    with pytest.raises(ParameterError, match="'image_topics'.*trailing /"):
        DetectorConfig.from_params({"image_topics": ["drone_0/image_raw/"]})
