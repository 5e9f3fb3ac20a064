"""Placer + three camera processes over real DDS: every camera publishes all four topics, same stamps; the points of
one lie on the zebras it shows."""

from __future__ import annotations

import json
from contextlib import ExitStack
from pathlib import Path

import numpy as np
import pytest
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from ros_helpers import Peer, fresh_domain_id, node_process, run_node_once, spin_until
from sensor_msgs.msg import CameraInfo, CompressedImage, Image, PointCloud2
from std_msgs.msg import String

from zebra_sim_ros.geometry.frames import xyzw_to_matrix
from zebra_sim_ros.recording.images import decompress_rgb

pytestmark = pytest.mark.integration
STEPS = 3
STRIDE = 2  # drone_0's points_stride


def cloud_fields(msg: PointCloud2) -> dict[str, np.ndarray]:
    """A PointCloud2's float32 fields as (height, width) arrays, read by the offsets it declares."""
    assert msg.point_step * msg.width == msg.row_step and not msg.is_bigendian
    dtype = np.dtype({"names": [f.name for f in msg.fields], "formats": ["<f4"] * len(msg.fields),
                      "offsets": [f.offset for f in msg.fields], "itemsize": msg.point_step})
    assert all(f.datatype == 7 and f.count == 1 for f in msg.fields)  # FLOAT32
    cloud = np.frombuffer(bytes(msg.data), dtype=dtype).reshape(msg.height, msg.width)
    return {f.name: cloud[f.name] for f in msg.fields}


def test_placer_and_three_cameras_in_lockstep(tmp_path: Path) -> None:
    domain = fresh_domain_id()
    peer = Peer(domain, "test_cameras")
    node, ex = peer.node, peer.ex
    got: dict[tuple[str, str], dict[int, object]] = {}
    scenes: dict[int, dict] = {}

    def keep(name: str, topic: str):  # type: ignore[no-untyped-def]
        def cb(msg) -> None:  # type: ignore[no-untyped-def]
            got.setdefault((name, topic), {})[msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec] = msg
        return cb

    latched = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)

    def on_scene(m: String) -> None:
        d = json.loads(m.data)
        scenes[d["stamp"]["sec"] * 10**9 + d["stamp"]["nanosec"]] = d

    node.create_subscription(String, "/zebra_sim/scene", on_scene, latched)
    compressed = {1: "png", 2: "jpeg"}  # drone_1 and drone_2 also publish image_raw/compressed
    for i in range(3):
        for topic, typ in (("image_raw", Image), ("depth", Image), ("instances", Image), ("camera_info", CameraInfo)):
            node.create_subscription(typ, f"/drone_{i}/{topic}", keep(f"drone_{i}", topic), 10)
        if i in compressed:
            node.create_subscription(CompressedImage, f"/drone_{i}/image_raw/compressed",
                                     keep(f"drone_{i}", "compressed"), 10)
    node.create_subscription(PointCloud2, "/drone_0/points", keep("drone_0", "points"), 10)
    try:
        with ExitStack() as stack:
            cams = [stack.enter_context(node_process(
                "camera", {"drone_index": i, "width": 256, "height": 144, "shadow_size": 512,
                           "compressed": compressed.get(i, "off"), "points_stride": STRIDE if i == 0 else 0},
                domain, tmp_path / f"camera_{i}.log", name=f"drone_{i}_camera")) for i in range(3)]
            # The images are volatile and the placer's lockstep waits for the cameras only: start it once this
            # test has discovered every camera's publishers, else a camera's first frame may go out before this
            # test's subscription is matched (seen in CI once cameras rendered their first frame in 0.6 s).
            topics = [f"/drone_{i}/{t}" for i in range(3) for t in ("image_raw", "depth", "instances", "camera_info")]
            topics += [f"/drone_{i}/image_raw/compressed" for i in compressed] + ["/drone_0/points"]
            assert spin_until(node, ex, lambda: all(node.count_publishers(t) for t in topics), 60), "cameras not up"
            spin_until(node, ex, lambda: False, 0.5)
            placer = stack.enter_context(node_process(
                "placer", {"mode": "lockstep", "max_steps": STEPS, "count_max": 40, "seed": 2, "rate_hz": 2.0,
                           "camera_width": 256, "camera_height": 144}, domain, tmp_path / "placer.log"))

            def complete() -> bool:
                return all(len(got.get((f"drone_{i}", t), {})) >= STEPS for i in range(3)
                           for t in ("image_raw", "depth", "instances", "camera_info")) and \
                    all(len(got.get((f"drone_{i}", "compressed"), {})) >= STEPS for i in compressed) and \
                    len(got.get(("drone_0", "points"), {})) >= STEPS and len(scenes) >= STEPS

            ok = spin_until(node, ex, complete, 180)
            logs = "\n".join(p.read_text()[-2000:] for p in sorted(tmp_path.glob("*.log")))
            assert ok, logs
            assert placer.wait(timeout=60) == 0, logs
            assert all(c.poll() is None for c in cams), logs
        stamps = sorted(scenes)[:STEPS]
        zebra_points = 0
        assert len(stamps) == STEPS
        for i in range(3):
            name = f"drone_{i}"
            for topic in ("image_raw", "depth", "instances", "camera_info"):
                assert sorted(got[(name, topic)])[:STEPS] == stamps, (name, topic)
            for s in stamps:
                rgb, depth, ids = (got[(name, t)][s] for t in ("image_raw", "depth", "instances"))
                info = got[(name, "camera_info")][s]
                for m in (rgb, depth, ids, info):
                    assert m.header.frame_id == f"{name}/camera_optical"
                assert (rgb.encoding, depth.encoding, ids.encoding) == ("rgb8", "32FC1", "mono16")
                assert rgb.width == depth.width == ids.width == info.width == 256
                assert rgb.height == info.height == 144
                d = np.frombuffer(bytes(depth.data), dtype="<f4").reshape(144, 256)
                assert np.isfinite(d).any() and (d[np.isfinite(d)] > 0).all()
                mask = np.frombuffer(bytes(ids.data), dtype="<u2")
                scene_ids = {z["id"] + 1 for z in scenes[s]["zebras"]}
                assert set(np.unique(mask)) - {0} <= scene_ids
                assert info.k[0] == pytest.approx(128 / np.tan(np.radians(40)))  # fx of 80 deg over 256 px
                if i in compressed:  # the same image: png to the byte, jpeg within its loss
                    c = got[(name, "compressed")][s]
                    assert c.header.frame_id == f"{name}/camera_optical"
                    assert c.format == f"rgb8; {compressed[i]} compressed bgr8"
                    raw = np.frombuffer(bytes(rgb.data), np.uint8).reshape(144, 256, 3)
                    back = decompress_rgb(c.format, bytes(c.data))
                    if compressed[i] == "png":
                        assert np.array_equal(back, raw)
                    else:
                        assert np.abs(back.astype(int) - raw).mean() < 4.0 and len(c.data) < raw.nbytes / 4
                if i == 0:
                    zebra_points += _check_points(got[(name, "points")][s], rgb, d, mask.reshape(144, 256), scenes[s])
        assert sorted(got[("drone_0", "points")])[:STEPS] == stamps
        assert zebra_points > 20, zebra_points
    finally:
        peer.close()


def _check_points(msg: PointCloud2, rgb: Image, depth: np.ndarray, mask: np.ndarray, scene: dict) -> int:
    """drone_0's points: every STRIDE-th pixel's depth as z and colour as packed rgb, NaN for sky; in ``map`` by
    the scene's camera pose, a zebra pixel's point within its zebra's box (grown by 0.3 m). Returns how many zebra
    points it checked."""
    assert msg.header.frame_id == "drone_0/camera_optical"
    assert (msg.height, msg.width) == (144 // STRIDE, 256 // STRIDE)
    f = cloud_fields(msg)
    assert list(f) == ["x", "y", "z", "rgb"]
    d = depth[::STRIDE, ::STRIDE]
    sky = ~np.isfinite(d)
    assert msg.is_dense == (not sky.any())
    assert f["z"][~sky] == pytest.approx(d[~sky], rel=1e-6)  # each point's z its pixel's depth
    assert np.isnan(f["z"][sky]).all() and np.isnan(f["x"][sky]).all()
    colour = np.frombuffer(bytes(rgb.data), np.uint8).reshape(144, 256, 3)[::STRIDE, ::STRIDE].astype(np.uint32)
    assert np.array_equal(f["rgb"].view("<u4"), (colour[..., 0] << 16) | (colour[..., 1] << 8) | colour[..., 2])
    cam = next(c for c in scene["cameras"] if c["name"] == "drone_0")
    r = xyzw_to_matrix(np.array(cam["orientation_xyzw"]))
    points = np.stack([f["x"], f["y"], f["z"]], axis=-1).astype(np.float64) @ r.T + np.array(cam["position"])
    ids = mask[::STRIDE, ::STRIDE]
    zebras = {z["id"] + 1: z["box"] for z in scene["zebras"]}
    checked = 0
    for zid in set(np.unique(ids)) - {0}:
        box = zebras[int(zid)]
        rb = xyzw_to_matrix(np.array(box["orientation_xyzw"]))
        local = (points[ids == zid] - np.array(box["center"])) @ rb  # in the box's own axes
        assert (np.abs(local) <= np.array(box["size"]) / 2 + 0.3).all(), (zid, np.abs(local).max(axis=0), box)
        checked += len(local)
    return checked


def test_a_camera_that_does_not_acknowledge_has_no_acknowledgement_publisher(tmp_path: Path) -> None:
    """``ack:=false``: the camera offers nothing on zebra_sim/frame_done, so a lockstep placer, which starts once an
    acknowledger publishes there, does not start on its account (it did, racing ahead of the real acknowledgers)."""
    domain = fresh_domain_id()
    peer = Peer(domain, "test_camera_ack")
    node, ex = peer.node, peer.ex
    try:
        log = tmp_path / "camera.log"
        with node_process("camera", {"drone_index": 0, "width": 64, "height": 48, "ack": False}, domain, log):
            # its scene subscription is made after where the acknowledgement publisher would be: once this side
            # has discovered it, it would have discovered that publisher too
            assert spin_until(node, ex, lambda: node.count_subscribers("/zebra_sim/scene") > 0, 60), log.read_text()
            assert spin_until(node, ex, lambda: node.count_publishers("/drone_0/camera_info") == 1, 10)
            assert node.count_publishers("/zebra_sim/frame_done") == 0
    finally:
        peer.close()


def test_bad_camera_parameter_stops_the_node() -> None:
    proc = run_node_once("camera", {"jpeg_quality": 150})
    assert proc.returncode == 2
    assert "jpeg_quality" in proc.stderr + proc.stdout
    # each lens coefficient in range, but together a lens whose polynomial turns back inside the image
    proc = run_node_once("camera", {"lens_k1": -0.5, "width": 320, "height": 180})
    out = proc.stderr + proc.stdout
    assert proc.returncode == 2 and "lens_k1, lens_k2, lens_p1, lens_p2, lens_k3" in out and "fold" in out, out
