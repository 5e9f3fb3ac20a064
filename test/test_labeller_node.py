"""Placer + three cameras + labeller over real DDS: labels for every camera and frame, with the image's stamp."""

from __future__ import annotations

import json
from contextlib import ExitStack
from pathlib import Path

import pytest
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
from sensor_msgs.msg import Image
from std_msgs.msg import String
from visualization_msgs.msg import ImageMarker, MarkerArray

pytestmark = pytest.mark.integration
STEPS = 3
DRONES = ("drone_0", "drone_1", "drone_2")
LENS = {"lens_k1": -0.2, "lens_k2": 0.05, "lens_p1": 0.001}  # drone_1's camera has a wide-angle lens


def test_labels_arrive_for_every_camera_and_frame(tmp_path: Path) -> None:
    domain = fresh_domain_id()
    peer = Peer(domain, "test_labels")
    node, ex = peer.node, peer.ex
    labels: dict[str, dict[int, dict]] = {d: {} for d in DRONES}
    image_stamps: dict[str, set[int]] = {d: set() for d in DRONES}
    markers: dict[str, list[ImageMarker]] = {d: [] for d in DRONES}
    boxes: dict[str, list[MarkerArray]] = {d: [] for d in DRONES}
    truth: dict[str, dict[int, dict]] = {d: {} for d in DRONES}
    health = {n: collect_diagnostics(node, n)
              for n in ("labeller: labeller", "placer: placer", "drone_1_camera: camera")}
    for d in DRONES:
        def on_truth(m: object, d: str = d) -> None:
            x = detections_dict(m)
            truth[d][x["stamp"]["sec"] * 10**9 + x["stamp"]["nanosec"]] = x

        def on_labels(m: String, d: str = d) -> None:
            x = json.loads(m.data)
            labels[d][x["stamp"]["sec"] * 10**9 + x["stamp"]["nanosec"]] = x

        def on_image(m: Image, d: str = d) -> None:
            image_stamps[d].add(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec)

        node.create_subscription(String, f"/{d}/labels", on_labels, 10)
        node.create_subscription(Image, f"/{d}/image_raw", on_image, 10)
        node.create_subscription(ImageMarker, f"/{d}/labels/markers", markers[d].append, 10)
        node.create_subscription(MarkerArray, f"/{d}/labels/boxes3d", boxes[d].append, 10)
        node.create_subscription(detection_array_class(), f"/{d}/labels/boxes2d", on_truth, 10)
    try:
        with ExitStack() as stack:
            for i, d in enumerate(DRONES):
                params = {"drone_index": i, "width": 256, "height": 144, "shadow_size": 512,
                          **(LENS if d == "drone_1" else {})}
                stack.enter_context(node_process("camera", {**params, "diagnostics_period_s": 0.5}, domain,
                                                 tmp_path / f"{d}.log", name=f"{d}_camera"))
            stack.enter_context(node_process("labeller", {"ack_name": "labeller", "image_reliability": "reliable",
                                                          "diagnostics_period_s": 0.5},
                                             domain, tmp_path / "labeller.log"))
            # volatile topics: start the placer once this test has discovered the cameras' and labeller's
            # publishers, so that no first frame goes out before this test's subscriptions are matched
            topics = [f"/{d}/{t}" for d in DRONES
                      for t in ("image_raw", "labels", "labels/markers", "labels/boxes3d", "labels/boxes2d")]
            assert spin_until(node, ex, lambda: all(node.count_publishers(t) for t in topics), 60), "nodes not up"
            spin_until(node, ex, lambda: False, 0.5)
            placer = stack.enter_context(node_process(
                "placer", {"mode": "lockstep", "max_steps": STEPS, "count_max": 60, "seed": 8,
                           "lockstep_ack_from": ["drone_0", "drone_1", "drone_2", "labeller"],
                           "camera_width": 256, "camera_height": 144}, domain, tmp_path / "placer.log"))
            ok = spin_until(node, ex, lambda: all(len(labels[d]) >= STEPS and set(labels[d]) <= image_stamps[d]
                                                  and len(truth[d]) >= STEPS for d in DRONES), 180)
            logs = "\n".join(p.read_text()[-1500:] for p in sorted(tmp_path.glob("*.log")))
            assert ok, logs
            assert placer.wait(timeout=60) == 0, logs
            # the placer ended by itself and said so on /diagnostics; the labeller reports every frame it labelled
            assert spin_until(node, ex, lambda: bool(health["placer: placer"]) and bool(health["labeller: labeller"])
                              and health["placer: placer"][-1]["message"].startswith("done")
                              and int(health["labeller: labeller"][-1]["values"]["frames"]) >= STEPS * len(DRONES),
                              10), health
        last = health["placer: placer"][-1]
        assert last["level"] == 0 and last["message"] == f"done: {STEPS} steps", last
        assert last["values"]["steps"] == str(STEPS) and last["values"]["navigation"] == "exact"
        assert all(s["level"] == 0 for n in ("labeller: labeller", "drone_1_camera: camera")
                   for s in health[n]), health  # nothing skipped, nothing unmatched
        assert {s["hardware_id"] for s in health["drone_1_camera: camera"]} == {"drone_1"}
        assert health["drone_1_camera: camera"][-1]["values"]["lens"] == "plumb_bob [-0.2, 0.05, 0.001, 0.0, 0.0]"
        assert any(float(s["values"].get("seconds per frame", 0)) > 0 for s in health["drone_1_camera: camera"])
        for d in DRONES:
            assert set(labels[d]) <= image_stamps[d]  # every label carries the stamp of an image
            for x in labels[d].values():
                assert x["camera"] == d and x["frame_id"] == f"{d}/camera_optical"
                # the labeller labels through the lens its camera_info's d gives
                assert x["D"] == pytest.approx([-0.2, 0.05, 0.001, 0.0, 0.0] if d == "drone_1" else [0.0] * 5,
                                               abs=1e-12), x["D"]
                assert x["width"] == 256 and x["in_view"] == len(x["zebras"])
                for z in x["zebras"]:
                    assert z["visible_pixels"] <= z["silhouette_pixels"] + 2, (d, z)
                    assert len(z["keypoints"]) == 26
            assert markers[d] and markers[d][-1].type == ImageMarker.LINE_LIST
            assert markers[d][-1].header.frame_id == f"{d}/camera_optical"
            assert len(markers[d][-1].points) % 2 == 0
            assert boxes[d]
            # the ground truth as detections: per labelled frame, its labelled zebras then the other species seen,
            # each with its scene id and visible box
            assert set(truth[d]) == set(labels[d])
            for t, x in labels[d].items():
                others = [z for z in x["zebras"] if z.get("species", "zebra") != "zebra"]
                want = [z for z in x["zebras"] if z["kept"]] + others
                got = truth[d][t]
                assert got["frame_id"] == f"{d}/camera_optical"
                assert [g["id"] for g in got["detections"]] == [str(z["id"]) for z in want]
                assert [g["class_name"] for g in got["detections"]] == [z.get("species", "zebra") for z in want]
                assert all(g["score"] == pytest.approx(1.0, abs=1e-12)
                           and g["box_xyxy"] == pytest.approx(z["box_visible"], abs=1e-6)
                           for g, z in zip(got["detections"], want, strict=True))
        assert sum(len(x["detections"]) for d in DRONES for x in truth[d].values()) > 0  # something was checked
    finally:
        peer.close()


def test_an_uncalibrated_camera_info_is_a_skipped_frame_not_a_crash() -> None:
    """A CameraInfo whose K is all zeros (an uncalibrated camera) or not finite is refused with a ValueError, which
    the node counts and skips; it used to divide by zero and end the node."""
    from types import SimpleNamespace

    from zebra_sim_ros.nodes.labeller import LabellerNode

    def info(width: int, fx: float, fy: float = 500.0) -> SimpleNamespace:
        return SimpleNamespace(width=width, height=240, k=[fx, 0.0, 160.0, 0.0, fy, 120.0, 0.0, 0.0, 1.0])

    for bad in (info(320, 0.0, 0.0), info(320, float("nan")), info(320, float("inf")), info(320, -500.0),
                info(320, 500.0, 0.0)):
        with pytest.raises(ValueError, match=r"K = \[.*want a calibrated camera"):
            LabellerNode._labeller(SimpleNamespace(labellers={}), bad)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="0x240"):
        LabellerNode._labeller(SimpleNamespace(labellers={}), info(0, 500.0))  # type: ignore[arg-type]


def test_bad_labeller_parameter_stops_the_node() -> None:
    proc = run_node_once("labeller", {"min_visible_fraction": 1.5})
    assert proc.returncode == 2
    assert "min_visible_fraction" in proc.stderr + proc.stdout


def test_box_markers_and_step_acknowledgements() -> None:
    from std_msgs.msg import ColorRGBA, Header

    from zebra_sim_ros.nodes.ros_adapter import ACK_TOPIC, StepAcks, box_marker, stamp

    red, green = ColorRGBA(r=1.0, a=1.0), ColorRGBA(g=1.0, a=1.0)
    m = box_marker(Header(frame_id="cam"), "boxes", [((0, 0, 10, 5), red), ((1, 1, 2, 2), green)])
    assert m.type == ImageMarker.LINE_LIST and m.ns == "boxes" and m.header.frame_id == "cam"
    assert [(p.x, p.y) for p in m.points[:8]] == [(0, 0), (10, 0), (10, 0), (10, 5), (10, 5), (0, 5), (0, 5), (0, 0)]
    assert len(m.points) == 16 and list(m.outline_colors) == [red] * 8 + [green] * 8 and m.outline_color == red

    sent: list[tuple[str, Header]] = []

    class Publisher:
        def __init__(self, topic: str) -> None:
            self.topic = topic

        def publish(self, msg: Header) -> None:
            sent.append((self.topic, msg))

    class FakeNode:
        def create_publisher(self, _type: object, topic: str, _qos: object) -> Publisher:
            return Publisher(topic)

    acks = StepAcks(FakeNode(), "detector", ["a", "b"], window=2)  # type: ignore[arg-type]
    assert acks.part_done(stamp(1), "a") is False and not sent
    assert acks.part_done(stamp(1), "a") is False  # the same part twice is still one part
    assert acks.part_done(stamp(1), "b") is True
    assert [(t, h.frame_id, h.stamp.sec) for t, h in sent] == [(ACK_TOPIC, "detector", 0)]
    assert sent[0][1].stamp.nanosec == 1
    for t in (2, 3, 4):
        acks.part_done(stamp(t), "a")
    assert list(acks.done.items) == [3, 4]  # only the last `window` stamps are remembered
    # a restarted placer (or a looping replay) sends older stamps again: they are the latest to arrive, kept until
    # every part is done (they were forgotten as they came, and lockstep stalled)
    sent.clear()
    assert acks.part_done(stamp(1), "a") is False and acks.part_done(stamp(1), "b") is True
    assert [h.stamp.nanosec for _, h in sent] == [1] and list(acks.done.items) == [4]  # done: let go
    assert acks.part_done(stamp(1), "a") is False  # the same step sent again waits for every part again
    assert acks.part_done(stamp(1), "b") is True and len(sent) == 2
    from zebra_sim_ros.nodes.ros_adapter import RecentStamps

    recent: RecentStamps[str] = RecentStamps(2)
    assert recent.put(10, "x") == [] and recent.put(20, "y") == [] and recent.put(5, "z") == [(10, "x")]
    value, pushed = recent.touch(20, str)  # seen again: the latest now, its value kept
    assert value == "y" and pushed == [] and list(recent.items) == [5, 20]
    assert recent.touch(7, lambda: "w") == ("w", [(5, "z")]) and 7 in recent and recent.pop(7) == "w"
    silent = StepAcks(FakeNode(), "", ["a"], window=5)  # type: ignore[arg-type]
    assert silent.pub is None and silent.part_done(stamp(1), "a") is True


def test_frame_parts_hold_a_cameras_messages_of_a_stamp_until_all_have_arrived() -> None:
    """The labeller's and the locator's input sync: a camera's parts of a stamp are given once, when the last
    arrives, and no longer held; another camera's parts of that stamp wait on; a stamp pushed out of the window
    returns each camera whose parts were not taken."""
    from zebra_sim_ros.nodes.ros_adapter import FrameParts

    frames = FrameParts(2, ("image", "depth"))
    assert frames.put(1, "a", "image", "a1") == [] and frames.take(1, "a") is None  # its depth still missing
    assert frames.put(1, "b", "image", "b1") == [] and frames.put(1, "a", "depth", "a1d") == []
    assert frames.take(1, "a") == {"image": "a1", "depth": "a1d"} and frames.take(1, "a") is None  # given once
    assert frames.waiting() == [1]  # b's depth of stamp 1 is still awaited
    assert frames.put(2, "a", "image", "a2") == [] and frames.put(1, "b", "image", "b1 again") == []
    assert frames.waiting() == [2, 1]  # stamp 1 arrived last: a replay's older stamps are kept, not forgotten
    assert sorted(frames.put(3, "c", "depth", "c3")) == [(2, "a")]  # stamp 2 pushed out, a's incomplete
    assert frames.put(1, "b", "depth", "b1d") == [] and frames.take(1, "b") == {"image": "b1 again", "depth": "b1d"}
    assert frames.waiting() == [3]  # stamp 1 is let go once no camera waits on it
