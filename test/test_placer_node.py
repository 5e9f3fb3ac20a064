"""The placer as a real process over DDS: scenes and camera poses arrive, in rate and lockstep modes."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rclpy
from cli_helpers import CliRun
from geometry_msgs.msg import PoseStamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from ros_helpers import fresh_domain_id, node_process, run_node_once, spin_until
from sensor_msgs.msg import NavSatFix, NavSatStatus
from std_msgs.msg import Header, String
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import MarkerArray

from zebra_sim_ros.geometry.camera import body_rotation
from zebra_sim_ros.geometry.frames import OPTICAL_IN_BASE_XYZW, xyzw_to_matrix
from zebra_sim_ros.geometry.geodesy import ATTITUDE_STREAM, NavNoise, geodetic_to_enu
from zebra_sim_ros.geometry.rotations import rotvec_to_matrix
from zebra_sim_ros.messages import Datum
from zebra_sim_ros.nodes.ros_adapter import detection3d_array_type, message_class

pytestmark = pytest.mark.integration
SMALL = {"count_max": 40, "world": "savanna"}


class Listener:
    """A test-side node collecting what the placer publishes."""

    def __init__(self, domain: int, name: str = "test_listener", stream: QoSProfile | int = 10,
                 animals: bool = True) -> None:
        """``stream``: the QoS of its pose and marker subscriptions (the scene's is reliable, as a camera's);
        ``animals``: it subscribes the typed 3D boxes too."""
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        latched = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.scenes: list[dict] = []
        self.scene_times: list[float] = []
        self.poses: dict[str, list[PoseStamped]] = {f"drone_{i}": [] for i in range(3)}
        self.markers: list[MarkerArray] = []
        self.tf: list[TFMessage] = []
        self.node.create_subscription(String, "/zebra_sim/scene", self._on_scene, latched)
        for name in self.poses:
            self.node.create_subscription(PoseStamped, f"/{name}/camera/pose",
                                          lambda m, n=name: self.poses[n].append(m), stream)
        self.node.create_subscription(MarkerArray, "/zebra_sim/zebras/markers", self.markers.append, stream)
        self.animals: list[Any] = []  # Detection3DArray, vision_msgs' or ours
        if animals:
            self.node.create_subscription(message_class(detection3d_array_type()), "/zebra_sim/zebras",
                                          self.animals.append, stream)
        self.node.create_subscription(TFMessage, "/tf", self.tf.append, 100)
        self.fixes: dict[str, list[NavSatFix]] = {name: [] for name in self.poses}
        self.nav_poses: dict[str, list[PoseStamped]] = {name: [] for name in self.poses}
        for name in self.fixes:
            self.node.create_subscription(NavSatFix, f"/{name}/fix", lambda m, n=name: self.fixes[n].append(m), stream)
            self.node.create_subscription(PoseStamped, f"/{name}/camera/pose_nav",
                                          lambda m, n=name: self.nav_poses[n].append(m), stream)
        self.ack_pub = self.node.create_publisher(Header, "/zebra_sim/frame_done", 100)

    def _on_scene(self, msg: String) -> None:
        self.scenes.append(json.loads(msg.data))
        self.scene_times.append(time.monotonic())

    def spin_until(self, cond, timeout: float) -> bool:  # type: ignore[no-untyped-def]
        return spin_until(self.node, self.executor, cond, timeout)

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)


@pytest.fixture
def domain() -> int:
    return fresh_domain_id()


def test_rate_mode_publishes_scene_and_three_poses(domain: int, tmp_path: Path, cli: CliRun) -> None:
    listener = Listener(domain)
    try:
        # Poses, markers and /tf are volatile: the placer waits until this listener is matched on each, else the
        # first steps may go out before discovery (CI: 5 steps published, fewer received).
        params = dict(SMALL, mode="rate", rate_hz=4.0, max_steps=5, seed=9, wait_for_subscribers=1,
                      other_animals_max=6)  # other species too, in the typed 3D boxes by their own names
        with node_process("placer", params, domain, tmp_path / "placer.log") as proc:
            assert listener.spin_until(lambda: len(listener.scenes) >= 5 and len(listener.tf) >= 5 and
                                       all(len(p) >= 5 for p in listener.poses.values()) and
                                       all(len(f) >= 5 for f in listener.fixes.values()), 60), \
                (tmp_path / "placer.log").read_text()
            assert proc.wait(timeout=20) == 0  # stops by itself after max_steps
        steps = [s["step"] for s in listener.scenes]
        assert steps == sorted(steps) and steps[-1] == 4
        for name, poses in listener.poses.items():
            by_stamp = {(p.header.stamp.sec, p.header.stamp.nanosec): p for p in poses}
            for s in listener.scenes:
                cam = next(c for c in s["cameras"] if c["name"] == name)
                pose = by_stamp[(s["stamp"]["sec"], s["stamp"]["nanosec"])]
                assert pose.header.frame_id == "map"
                assert pose.pose.position.x == pytest.approx(cam["position"][0])
                assert pose.pose.orientation.w == pytest.approx(cam["orientation_xyzw"][3])
        # without navigation errors asked for, the navigated pose is the exact one, bit for bit
        assert listener.spin_until(lambda: all(len(p) >= 5 for p in listener.nav_poses.values()), 10)
        for name, navs in listener.nav_poses.items():
            exact = {(p.header.stamp.sec, p.header.stamp.nanosec): p.pose for p in listener.poses[name]}
            assert all(n.pose == exact[(n.header.stamp.sec, n.header.stamp.nanosec)] for n in navs)
        # each camera on the Earth: its NavSatFix, converted back by the scene's datum, is its position in map
        datum = Datum.from_dict(listener.scenes[0]["datum"])
        assert datum == Datum(-2.3, 34.8, 1550.0)  # the placer's defaults
        for name, fixes in listener.fixes.items():
            by_stamp = {(f.header.stamp.sec, f.header.stamp.nanosec): f for f in fixes}
            for s in listener.scenes:
                cam = next(c for c in s["cameras"] if c["name"] == name)
                fix = by_stamp[(s["stamp"]["sec"], s["stamp"]["nanosec"])]
                assert fix.header.frame_id == f"{name}/base_link" and fix.status.status == NavSatStatus.STATUS_FIX
                back = geodetic_to_enu([[fix.latitude, fix.longitude, fix.altitude]], datum)[0]
                assert back == pytest.approx(cam["position"], abs=1e-4)  # 0.1 mm
                assert fix.position_covariance_type == NavSatFix.COVARIANCE_TYPE_UNKNOWN  # exact: no noise asked
        assert listener.markers and len(listener.markers[-1].markers) == listener.scenes[-1]["placed"] + 1
        shown = listener.markers[-1].markers
        last = next(s for s in listener.scenes
                    if (s["stamp"]["sec"], s["stamp"]["nanosec"]) == (shown[1].header.stamp.sec,
                                                                        shown[1].header.stamp.nanosec))
        for cube in shown[1:]:  # each zebra's oriented box, where its step's scene has it
            box = next(z["box"] for z in last["zebras"] if z["id"] == cube.id)
            p, q = cube.pose.position, cube.pose.orientation
            assert (p.x, p.y, p.z, q.x, q.y, q.z, q.w) == pytest.approx([*box["center"], *box["orientation_xyzw"]])
            assert (cube.scale.x, cube.scale.y, cube.scale.z) == pytest.approx(box["size"])
        # the placed animals, typed: one Detection3DArray per step in map, each animal of the scene's JSON with
        # its species, pose, oriented box and id
        assert listener.spin_until(lambda: len(listener.animals) >= 5, 10)
        animals = {(m.header.stamp.sec, m.header.stamp.nanosec): m for m in listener.animals}
        species = set()
        for s in listener.scenes:
            msg = animals[(s["stamp"]["sec"], s["stamp"]["nanosec"])]
            assert msg.header.frame_id == "map" and len(msg.detections) == len(s["zebras"]) > 0
            for d, z in zip(msg.detections, s["zebras"], strict=True):
                hyp = d.results[0]
                assert d.id == str(z["id"]) and hyp.hypothesis.class_id == z.get("species", "zebra")
                assert hyp.hypothesis.score == pytest.approx(1.0) and d.header == msg.header
                p, b = hyp.pose.pose, d.bbox
                assert [p.position.x, p.position.y, p.position.z] == pytest.approx(z["position"], abs=1e-9)
                assert [p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w] == pytest.approx(
                    z["orientation_xyzw"], abs=1e-9)
                assert [b.center.position.x, b.center.position.y, b.center.position.z] == pytest.approx(
                    z["box"]["center"], abs=1e-9)
                assert [b.size.x, b.size.y, b.size.z] == pytest.approx(z["box"]["size"], abs=1e-9)
                assert [b.center.orientation.x, b.center.orientation.y, b.center.orientation.z,
                        b.center.orientation.w] == pytest.approx(z["box"]["orientation_xyzw"], abs=1e-9)
                species.add(hyp.hypothesis.class_id)
        assert "zebra" in species and len(species) > 1, species
        # /tf from the first step on: one map -> drone_i/base_link per drone, stamped as the scene.
        tf_stamps = [(m.transforms[0].header.stamp.sec, m.transforms[0].header.stamp.nanosec) for m in listener.tf]
        assert tf_stamps == [(s["stamp"]["sec"], s["stamp"]["nanosec"]) for s in listener.scenes]
        assert all(sorted(t.child_frame_id for t in m.transforms) == [f"drone_{i}/base_link" for i in range(3)]
                   for m in listener.tf)
        # each body where its camera is, turned as the camera's angles say (an independent path: Euler angles, not
        # the scene's quaternion), and with /tf_static's base_link -> camera_optical the scene's optical frame (the
        # body was once turned by a quaternion read in the wrong order: RViz showed every camera askew)
        for m, s in zip(listener.tf, listener.scenes, strict=True):
            for t in m.transforms:
                cam = next(c for c in s["cameras"] if f"{c['name']}/base_link" == t.child_frame_id)
                q, at = t.transform.rotation, t.transform.translation
                body = xyzw_to_matrix((q.x, q.y, q.z, q.w))
                want = body_rotation(*np.radians([cam["yaw_deg"], cam["pitch_deg"], cam["roll_deg"]]))
                assert np.abs(body - want).max() < 1e-9, (cam, body, want)
                assert np.abs(body @ xyzw_to_matrix(OPTICAL_IN_BASE_XYZW)
                              - xyzw_to_matrix(cam["orientation_xyzw"])).max() < 1e-9
                assert [at.x, at.y, at.z] == pytest.approx(cam["position"], abs=1e-9)
        # The node's scenes are exactly the command line's (same parameters, no ROS).
        placed = cli(["place", "--steps", "2", "--set", "count_max=40", "--set", "rate_hz=4.0", "--set",
                      "other_animals_max=6", "--seed", "9"])
        assert placed.returncode == 0, placed.stderr
        assert [json.loads(line) for line in placed.stdout.splitlines()[:2]] == listener.scenes[:2]
    finally:
        listener.close()


def test_service_mode_publishes_one_step_per_call_and_says_which(domain: int, tmp_path: Path) -> None:
    """``mode:=service``: each call of ``/placer/step`` (std_srvs/Trigger) publishes one step and answers with its
    index and stamp; a call while subscribers are still awaited publishes nothing and says so; after ``max_steps``
    the node ends by itself. A reader that matches after two steps gets both scenes. With GNSS noise asked for
    (wandering, a time constant of 3 steps, half of it shared by the drones), each drone's fix is its camera's
    position moved by the error the scene's seed and step give (recomputed here from each scene alone: step 1's sums
    step 0's draws too), with that covariance, known, and its camera/pose_nav is at that fix, turned from its exact
    pose by the attitude error of the scene's seed and step (0.5 deg of tilt, 2 deg of heading)."""
    from std_srvs.srv import Trigger

    listener = Listener(domain)
    second: Listener | None = None
    client = listener.node.create_client(Trigger, "/placer/step")

    def call() -> Trigger.Response:
        future = client.call_async(Trigger.Request())
        assert listener.spin_until(future.done, 30), "no answer"
        return future.result()
    try:
        params = dict(SMALL, mode="service", max_steps=3, seed=9, wait_for_subscribers=2, fix_sigma_m=2.5,
                      fix_vertical_sigma_m=5.0, fix_correlation_s=3.0, fix_common_fraction=0.5, nav_tilt_sigma_deg=0.5,
                      nav_heading_sigma_deg=2.0)
        with node_process("placer", params, domain, tmp_path / "placer.log") as proc:
            assert listener.spin_until(client.service_is_ready, 60), (tmp_path / "placer.log").read_text()
            first = call()
            assert not first.success and "waiting for 2 subscribers" in first.message, first.message
            listener.spin_until(lambda: False, 1.0)
            assert listener.scenes == []  # nothing published for it
            second = Listener(domain, "test_second_listener")
            answers = [call()]
            end = time.monotonic() + 30
            while not answers[-1].success and time.monotonic() < end:  # until the second listener is discovered
                listener.spin_until(lambda: False, 0.2)
                answers[-1] = call()
            answers.append(call())
            assert [a.success for a in answers] == [True, True], [a.message for a in answers]
            assert listener.spin_until(lambda: len(listener.scenes) == 2, 30)
            # a reader that matches after both steps still gets both (the last qos_depth scenes are kept), where
            # a scene history of 1 gave it step 1 alone
            late = Listener(domain, "test_late_listener")
            try:
                late.spin_until(lambda: len(late.scenes) >= 2, 15)
                late_steps = [s["step"] for s in late.scenes]
            finally:
                late.close()
            assert late_steps == [0, 1], late_steps
            answers.append(call())
            assert answers[-1].success, answers[-1].message
            assert listener.spin_until(lambda: len(listener.scenes) == 3, 30)
            assert proc.wait(timeout=20) == 0  # ends by itself after max_steps
        for answer, scene in zip(answers, listener.scenes, strict=True):
            stamp = f"{scene['stamp']['sec']}.{scene['stamp']['nanosec']:09d}"
            assert answer.message.startswith(f"step {scene['step']}, stamp {stamp}: {scene['placed']}/"), answer.message
        assert [s["step"] for s in listener.scenes] == [0, 1, 2]
        assert "published 3 steps on request; stopping" in (tmp_path / "placer.log").read_text()
        assert listener.spin_until(lambda: all(len(f) == 3 for f in (*listener.fixes.values(),
                                                                     *listener.nav_poses.values())), 10)
        for scene in listener.scenes:
            cams = scene["cameras"]  # the draw's order: the scene's cameras
            names = [c["name"] for c in cams]
            assert sorted(names) == sorted(listener.fixes)
            datum = Datum.from_dict(scene["datum"])
            # each step alone, in a model of its own: step 1's error sums step 0's draws too
            want, cov = NavNoise(2.5, 5.0, correlation_steps=3.0, common_fraction=0.5).fixes(
                [c["position"] for c in cams], datum, scene["seed"], scene["step"])
            attitude = NavNoise(0.5, 2.0, stream=ATTITUDE_STREAM).errors(len(cams), scene["seed"], scene["step"])
            for name, cam, (lat, lon, height) in zip(names, cams, want, strict=True):
                fix = next(f for f in listener.fixes[name] if (f.header.stamp.sec, f.header.stamp.nanosec) ==
                           (scene["stamp"]["sec"], scene["stamp"]["nanosec"]))
                assert (fix.latitude, fix.longitude) == pytest.approx((lat, lon), abs=1e-9)
                assert fix.altitude == pytest.approx(height, abs=1e-6)
                assert fix.position_covariance_type == NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
                assert list(fix.position_covariance) == pytest.approx([6.25, 0, 0, 0, 6.25, 0, 0, 0, 25.0])
                off = geodetic_to_enu([[fix.latitude, fix.longitude, fix.altitude]], datum)[0] - cam["position"]
                assert 1e-3 < np.linalg.norm(off) < 6 * 5.0  # moved, by a draw of these sigmas
                # the navigation's pose: at the fix, in map (1e-6 m: the round trip through latitude), turned from
                # the exact one by the attitude error of the scene's seed and step
                nav = next(p for p in listener.nav_poses[name] if p.header.stamp == fix.header.stamp)
                p, o = nav.pose.position, nav.pose.orientation
                assert [p.x, p.y, p.z] == pytest.approx(cam["position"] + off, abs=1e-6)
                turn = rotvec_to_matrix(np.radians(attitude[names.index(name)]))
                np.testing.assert_allclose(xyzw_to_matrix((o.x, o.y, o.z, o.w)),
                                           turn @ xyzw_to_matrix(cam["orientation_xyzw"]), atol=1e-9)
                angle = np.degrees(np.arccos(np.clip((np.trace(turn) - 1) / 2, -1, 1)))
                assert 1e-4 < angle < 6 * 2.0  # turned, by a draw of these sigmas
                assert nav.header.frame_id == "map"
    finally:
        listener.close()
        if second is not None:
            second.close()


def test_a_best_effort_placer_still_sends_its_scene_reliable(domain: int, tmp_path: Path) -> None:
    """``qos_reliability:=best_effort`` makes the markers and poses best effort; the scene stays reliable, as the
    cameras and the labeller subscribe it (a best-effort scene used to match none of them, and the graph stalled)."""
    listener = Listener(domain, stream=QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT))
    try:
        params = dict(SMALL, mode="rate", rate_hz=4.0, max_steps=3, seed=9, wait_for_subscribers=1,
                      qos_reliability="best_effort")
        offered: list[ReliabilityPolicy] = []  # the animals' boxes as the placer offers them, seen while it runs

        def seen() -> bool:
            if not offered:
                offered.extend(i.qos_profile.reliability
                               for i in listener.node.get_publishers_info_by_topic("/zebra_sim/zebras"))
            return len(listener.scenes) >= 3 and all(listener.poses.values()) and bool(listener.animals)
        with node_process("placer", params, domain, tmp_path / "placer.log") as proc:
            assert listener.spin_until(seen, 60), (tmp_path / "placer.log").read_text()
            assert proc.wait(timeout=20) == 0
        log = (tmp_path / "placer.log").read_text()
        assert "zebra_sim/scene: reliability=reliable" in log, log[-1500:]
        assert "animals and markers: reliability=best_effort" in log, log[-1500:]
        # the poses too, kept for late readers (transient local), and a volatile best-effort reader still gets them
        assert "poses and fixes: reliability=best_effort durability=transient_local" in log, log[-1500:]
        assert offered == [ReliabilityPolicy.BEST_EFFORT]  # the animals' boxes follow qos_reliability too
        assert [s["step"] for s in listener.scenes] == [0, 1, 2]
    finally:
        listener.close()


def test_the_first_step_waits_for_the_named_node_not_for_any_subscriber(domain: int, tmp_path: Path) -> None:
    """``wait_for_nodes``: a bystander subscribed to every output (RViz, say) does not start the run; the named
    node does, and it receives every step from step 0 on."""
    bystander = Listener(domain, "bystander")
    recorder: Listener | None = None
    try:
        params = dict(SMALL, mode="rate", rate_hz=4.0, max_steps=3, seed=9, wait_for_subscribers=1,
                      wait_for_nodes=["late_recorder"])
        with node_process("placer", params, domain, tmp_path / "placer.log") as proc:
            assert not bystander.spin_until(lambda: bool(bystander.scenes or bystander.tf), 8.0), \
                "the placer started with only a bystander subscribed"
            # it says what it waits for: the node, and the outputs it has not subscribed yet
            assert "/late_recorder to subscribe to ['/zebra_sim/scene', '/zebra_sim/zebras'" in (
                tmp_path / "placer.log").read_text()
            recorder = Listener(domain, "late_recorder")
            assert recorder.spin_until(lambda: len(recorder.scenes) >= 3 and len(recorder.tf) >= 3 and
                                       len(recorder.markers) >= 3 and
                                       all(len(p) >= 3 for p in recorder.poses.values()), 60), \
                (tmp_path / "placer.log").read_text()
            assert proc.wait(timeout=20) == 0
        assert [s["step"] for s in recorder.scenes] == [0, 1, 2]
        assert len(recorder.tf) == 3 and len(recorder.markers) == 3
        assert all(len(p) == 3 for p in recorder.poses.values())
    finally:
        bystander.close()
        if recorder is not None:
            recorder.close()


@pytest.mark.parametrize("names", [["/bad name"], ["9recorder"], []])
def test_a_bad_node_name_to_wait_for_is_named(names: list[str]) -> None:
    from zebra_sim_ros.errors import ParameterError
    from zebra_sim_ros.placement.config import PlacerConfig

    with pytest.raises(ParameterError, match="wait_for_nodes"):
        PlacerConfig.from_params({"wait_for_nodes": names})


def test_lockstep_waits_for_every_camera(domain: int, tmp_path: Path) -> None:
    listener = Listener(domain)
    try:
        params = dict(SMALL, mode="lockstep", max_steps=4, seed=5, lockstep_timeout_s=30.0)
        with node_process("placer", params, domain, tmp_path / "placer.log") as proc:
            for k in range(4):
                assert listener.spin_until(lambda k=k: any(s["step"] == k for s in listener.scenes), 60), \
                    (tmp_path / "placer.log").read_text()
                scene = next(s for s in listener.scenes if s["step"] == k)
                newest = lambda: max(s["step"] for s in listener.scenes)  # noqa: E731
                listener.spin_until(lambda: False, 0.5)
                assert newest() == k, "the placer did not wait for acknowledgements"
                for i in range(2):
                    listener.ack_pub.publish(Header(stamp=_time(scene["stamp"]), frame_id=f"drone_{i}"))
                listener.spin_until(lambda: False, 0.5)
                assert newest() == k, "two of three acknowledgements advanced the step"
                listener.ack_pub.publish(Header(stamp=_time(scene["stamp"]), frame_id="drone_2"))
            assert proc.wait(timeout=30) == 0, (tmp_path / "placer.log").read_text()
        assert [s["step"] for s in listener.scenes] == [0, 1, 2, 3]
    finally:
        listener.close()


def _time(stamp: dict):  # type: ignore[no-untyped-def]
    from builtin_interfaces.msg import Time

    return Time(sec=stamp["sec"], nanosec=stamp["nanosec"])


@pytest.mark.parametrize(("params", "needle"), [
    ({"strategy": "sideways"}, "strategy"),
    ({"count_min": 10, "count_max": 5}, "count_min"),
    ({"world": "atlantis"}, "world"),
    ({"fix_correlation_s": 7200.0}, "fix_correlation_s"),
])
def test_bad_parameter_stops_the_node_naming_it(domain: int, params: dict, needle: str) -> None:
    proc = run_node_once("placer", params, domain)
    assert proc.returncode == 2
    assert needle in proc.stderr + proc.stdout


def test_an_unknown_parameter_is_named_in_a_warning() -> None:
    """rclpy ignores a parameter a node does not declare; ours say so at start, naming it (a typo such as
    ``rate_hzz`` otherwise looks like a setting that does nothing)."""
    from ros_helpers import run_node_once

    proc = run_node_once("placer", {"max_steps": 1, "rate_hz": 50.0, "rate_hzz": 2.0, "use_sim_time": False})
    assert proc.returncode == 0, proc.stdout + proc.stderr
    out = proc.stdout + proc.stderr
    assert "unknown parameter(s) ignored: ['rate_hzz']" in out and "use_sim_time" not in out.split("ignored:")[1][:40]


def test_publish_animals_false_leaves_the_typed_boxes_out_of_the_outputs_and_the_wait(domain: int,
                                                                                    tmp_path: Path) -> None:
    """``publish_animals:=false``: no zebra_sim/zebras publisher, and a named node that does not subscribe it (a
    recorder that leaves it out) starts the run all the same."""
    recorder = Listener(domain, "picky_recorder", animals=False)
    try:
        params = dict(SMALL, mode="rate", rate_hz=4.0, max_steps=2, seed=9, wait_for_subscribers=1,
                      wait_for_nodes=["picky_recorder"], publish_animals=False)
        seen: dict[str, int] = {}  # publishers per topic, looked at while the placer runs

        def done() -> bool:
            for topic in ("/zebra_sim/scene", "/zebra_sim/zebras"):
                seen[topic] = max(seen.get(topic, 0), len(recorder.node.get_publishers_info_by_topic(topic)))
            return len(recorder.scenes) >= 2
        with node_process("placer", params, domain, tmp_path / "placer.log") as proc:
            assert recorder.spin_until(done, 60), (tmp_path / "placer.log").read_text()
            assert proc.wait(timeout=20) == 0
        assert seen == {"/zebra_sim/scene": 1, "/zebra_sim/zebras": 0}
        assert [s["step"] for s in recorder.scenes] == [0, 1]
    finally:
        recorder.close()
