"""The ``placer`` node: publishes one scene per step (``ros2 run zebra_sim_ros placer``).

Topics (all stamped with the scene's simulated time, frame ``map`` = ENU; names are relative, so a namespace moves
the whole graph, except the conventional ``/tf``, ``/tf_static`` and ``/clock``, which ``up --namespace`` remaps):

- ``zebra_sim/scene`` (std_msgs/String): the scene JSON (schema in ``zebra_sim_ros.placement.scene``);
  reliable, transient local, the last ``qos_depth`` scenes kept: a reader that falls behind (a recorder busy with
  images) or matches late still gets those steps, and a camera that starts late (history 1) usually the current one.
- ``zebra_sim/zebras`` (vision_msgs/Detection3DArray where installed, else zebra_sim_msgs/Detection3DArray, the
  same fields): every placed animal's species, pose and oriented 3D box, ``id`` its scene id (the typed ground
  truth in 3D, for trackers and counters); ``publish_animals:=false`` leaves it out.
- ``zebra_sim/zebras/markers`` (visualization_msgs/MarkerArray): the zebras' oriented 3D boxes.
- ``drone_{i}/camera/pose`` (geometry_msgs/PoseStamped): pose of ``drone_{i}/camera_optical`` in ``map``.
- ``drone_{i}/camera/pose_nav`` (geometry_msgs/PoseStamped): the same pose as the drone's own navigation gives it:
  at its GNSS fix's position (the fix's error, below, in ``map``), turned by the navigation's attitude error
  (``nav_tilt_sigma_deg`` about east and north, ``nav_heading_sigma_deg`` about up; white, from the scene's seed and
  step; 0: exact); what a locator that places detections from a real flight's poses reads (the locator's ``pose``).
- ``drone_{i}/fix`` (sensor_msgs/NavSatFix): the same camera's position on the Earth (WGS84 latitude, longitude,
  height above the ellipsoid) by the scene's datum, as a drone's GNSS receiver reports it: exact, its covariance
  unknown, or with ``fix_sigma_m`` / ``fix_vertical_sigma_m`` seeded Gaussian noise (from the scene's seed and step:
  the same fixes on a rerun, or for a step alone), white or wandering (``fix_correlation_s``), independent or
  partly shared by the drones (``fix_common_fraction``), and that diagonal covariance, known; frame
  ``drone_{i}/base_link``.
- ``/tf`` (tf2_msgs/TFMessage): ``map -> drone_{i}/base_link`` of every drone, each step (REP 105);
  ``/tf_static``: ``drone_{i}/base_link -> drone_{i}/camera_optical`` once (transient local), so RViz, Foxglove
  and tf2 place each camera's images in 3D.
- ``/clock`` (rosgraph_msgs/Clock): the simulated time of each step, published first (reliable, transient local,
  depth 1: a late reader gets the current step's time); every other node stamps with that time (their header
  stamps are the scene's), ``up`` runs them with ``use_sim_time``, and bags are written with log times equal to
  the stamps.

Modes: ``rate`` publishes a step every 1/rate_hz s; ``lockstep`` publishes step k+1 only after every name
in ``lockstep_ack_from`` has acknowledged step k on ``zebra_sim/frame_done`` (std_msgs/Header: stamp = the
scene's stamp, frame_id = the acknowledging node's name, e.g. ``drone_0``); ``service`` publishes a step each time
its ``~/step`` service (std_srvs/Trigger) is called, and answers with the step's index and stamp, the simulated
time step / rate_hz (``step 3, stamp 3.000000000: 38/40 zebras placed``), or success false and why no step was
published (subscribers still awaited, ``max_steps`` reached). In every mode a ``max_steps`` > 0 ends the node after
that many steps (in service mode 0.5 s after the last answer, its service taken down first).
"""

from __future__ import annotations

import math
import time

import numpy as np
from geometry_msgs.msg import PoseStamped, Quaternion, Transform, TransformStamped, Vector3
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import NavSatFix, NavSatStatus
from std_msgs.msg import ColorRGBA, Header, String
from std_srvs.srv import Trigger
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import Marker, MarkerArray

from zebra_sim_ros.geometry.frames import (
    OPTICAL_IN_BASE_XYZW,
    base_frame,
    body_orientation,
    matrix_to_xyzw,
    optical_frame,
    xyzw_to_matrix,
)
from zebra_sim_ros.geometry.geodesy import enu_to_geodetic
from zebra_sim_ros.health import Activity
from zebra_sim_ros.messages import Scene
from zebra_sim_ros.nodes.ros_adapter import (
    ACK_TOPIC,
    ZebraNode,
    describe_qos,
    detection3d_array_type,
    flush,
    help_text,
    message_class,
    pose_msg,
    qos,
    run_node,
    scene_animals_msg,
    stamp,
    stamp_ns,
)
from zebra_sim_ros.placement.config import (
    ANIMALS_TOPIC,
    CAMERA_POSE,
    FIX_TOPIC,
    MARKER_TOPIC,
    NAV_POSE,
    PLACER_PARAMS,
    SCENE_TOPIC,
    PlacerConfig,
)
from zebra_sim_ros.placement.placer import Placer
from zebra_sim_ros.world.world import load_world
from zebra_sim_ros.zebra.asset import load_library

CLOCK_TOPIC, TF_TOPIC, TF_STATIC_TOPIC = "/clock", "/tf", "/tf_static"
_MORPH_RGBA = {"plains": (0.95, 0.85, 0.2, 0.5), "grevy": (0.3, 0.7, 1.0, 0.5), "foal": (1.0, 0.4, 0.6, 0.5)}


class PlacerNode(ZebraNode[PlacerConfig]):
    """Thin adapter around :class:`zebra_sim_ros.placement.placer.Placer` (no parameter changes while running)."""

    def __init__(self) -> None:
        super().__init__("placer", PlacerConfig)

    def start(self) -> None:
        """Load the world and the zebras; publish steps by rate or in lockstep."""
        c = self.cfg
        t0 = time.perf_counter()
        world = load_world(c.world, c.terrain_prim, c.world_seed)
        self.placer = Placer(c, world, load_library())
        self.gnss, self.attitude = c.gnss_noise(), c.attitude_noise()
        cov = self.gnss.covariance  # the fixes' covariance, type and status: the same every step
        self.fix_covariance = cov.ravel().tolist()
        self.fix_covariance_type = (NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN if cov.any()
                                    else NavSatFix.COVARIANCE_TYPE_UNKNOWN)
        self.fix_status = NavSatStatus(status=NavSatStatus.STATUS_FIX, service=NavSatStatus.SERVICE_GPS)
        self.get_logger().info(
            f"world '{world.name}' ({world.source}), asset {self.placer.library.manifest['digest']}, seed {c.seed}, "
            f"strategy {c.strategy}, mode {c.mode}, ready in {time.perf_counter() - t0:.1f} s")
        # the scene is always reliable (as /clock and /tf): the cameras and the labeller subscribe reliable and need
        # every step; a best-effort scene would match none of them. The last qos_depth scenes are kept, as the poses:
        # kept alone, step k was lost to a reader that had not acknowledged it when step k+1 went out (a lost packet
        # is resent at the next heartbeat, after the cameras had rendered step k and the lockstep had moved on)
        latched = qos("reliable", c.qos_depth, transient_local=True)
        stream = qos(c.qos_reliability, c.qos_depth)
        # the cameras' poses kept for late readers (the last qos_depth steps): a node that subscribes as the first
        # step goes out may match the placer only after its first pose has gone; volatile readers match too
        poses = qos(c.qos_reliability, c.qos_depth, transient_local=True)
        self.get_logger().info(f"QoS {SCENE_TOPIC}: {describe_qos(latched)}; animals and markers: "
                               f"{describe_qos(stream)}; poses and fixes: {describe_qos(poses)}")
        self.scene_pub = self.create_publisher(String, SCENE_TOPIC, latched)
        self.marker_pub = self.create_publisher(MarkerArray, MARKER_TOPIC, stream)
        self.animals_type, self.animals_pub = "", None  # publish_animals:=false: neither published nor awaited
        if c.publish_animals:
            self.animals_type = detection3d_array_type()
            self.animals_pub = self.create_publisher(message_class(self.animals_type), ANIMALS_TOPIC, stream)
        self.pose_pubs = [self.create_publisher(PoseStamped, f"{n}/{CAMERA_POSE}", poses)
                          for n in self.placer.camera_names]
        self.nav_pose_pubs = [self.create_publisher(PoseStamped, f"{n}/{NAV_POSE}", poses)
                               for n in self.placer.camera_names]
        self.fix_pubs = [self.create_publisher(NavSatFix, f"{n}/{FIX_TOPIC}", poses) for n in self.placer.camera_names]
        # Transient local, depth 1: a reader that matches late (a recorder whose /clock reader matched after its /tf
        # one) still gets the current step's time. /clock cannot be waited on by count: every use_sim_time node
        # subscribes to it.
        self.clock_pub = self.create_publisher(Clock, CLOCK_TOPIC, qos("reliable", 1, transient_local=True))
        self.tf_pub = self.create_publisher(TFMessage, TF_TOPIC, qos("reliable", 100))
        latched_tf = qos("reliable", 1, transient_local=True)
        self.tf_static_pub = self.create_publisher(TFMessage, TF_STATIC_TOPIC, latched_tf)
        self.tf_static_pub.publish(TFMessage(transforms=[
            _transform(Header(frame_id=base_frame(n)), optical_frame(n), (0.0, 0.0, 0.0), OPTICAL_IN_BASE_XYZW)
            for n in self.placer.camera_names]))
        # What wait_for_subscribers waits for. /tf too: a recorder that matched the markers but not yet /tf would
        # miss the first step's transforms. /clock is latched instead (above).
        self.outputs = [p for p in (self.scene_pub, self.animals_pub, self.marker_pub, *self.pose_pubs,
                                    *self.nav_pose_pubs, *self.fix_pubs, self.tf_pub) if p is not None]
        self.step = c.start_step
        self.published = 0
        self.resent = 0  # lockstep steps published again for want of an acknowledgement
        self.pending: Scene | None = None
        self.acked: set[str] = set()
        self.sent_at = 0.0
        ns = self.get_namespace().rstrip("/")
        self.wait_nodes = [n if n.startswith("/") else f"{ns}/{n}" for n in c.wait_for_nodes if n]
        self.started = c.wait_for_subscribers == 0 and not self.wait_nodes
        self.waiting_since = -math.inf  # says what it waits for at once, then every 5 s
        self.answered_at = -math.inf  # service mode: when the last step was answered
        if c.mode == "rate":
            self.timer = self.wall_timer(1.0 / c.rate_hz, self._publish_next)
        elif c.mode == "service":
            self.service = self.create_service(Trigger, "~/step", self._on_step_request)
            self.get_logger().info(f"service: one step per call of {self.service.srv_name} (std_srvs/Trigger)")
            self.timer = self.wall_timer(0.1, self._service_tick)
        else:
            ack_qos = qos("reliable", 100)
            self.get_logger().info(f"lockstep: waiting for {list(c.lockstep_ack_from)} on {ACK_TOPIC} "
                                   f"({describe_qos(ack_qos)})")
            self.create_subscription(Header, ACK_TOPIC, self._on_ack, ack_qos)
            self.timer = self.wall_timer(0.05, self._lockstep_tick)

    def _finished(self) -> bool:
        return self.cfg.max_steps > 0 and self.published >= self.cfg.max_steps

    def _subscribers(self, topic: str) -> set[str]:
        """The fully qualified names of the nodes subscribed to ``topic``."""
        return {f"{i.node_namespace.rstrip('/')}/{i.node_name}" for i in self.get_subscriptions_info_by_topic(topic)}

    def _first_step_wait(self) -> str:
        """What the first step still waits for: subscribers on which outputs, which named nodes."""
        short = [p.topic_name for p in self.outputs if p.get_subscription_count() < self.cfg.wait_for_subscribers]
        readers = {p.topic_name: self._subscribers(p.topic_name) for p in self.outputs} if self.wait_nodes else {}
        lacking = {n: [t for t, subs in readers.items() if n not in subs] for n in self.wait_nodes}
        parts = ([f"{self.cfg.wait_for_subscribers} subscribers on {short}"] if short else []) + [
            f"{n} to subscribe to {topics}" for n, topics in sorted(lacking.items()) if topics]
        return "waiting for " + " and for ".join(parts) if parts else ""

    def _start_wait(self, how: str = "") -> str:
        """What the first step still waits for (:meth:`_first_step_wait`), "" once it may start: then ``started``
        is set and the start logged, once (``how``: " on request" in service mode)."""
        if self.started:
            return ""
        waiting = self._first_step_wait()
        if not waiting:
            self.started = True
            named = f", {', '.join(self.wait_nodes)} among them" if self.wait_nodes else ""
            self.get_logger().info(f"every output has {self.cfg.wait_for_subscribers}+ subscribers{named}: "
                                   f"starting{how}")
        return waiting

    def _subscribed(self) -> bool:
        """True once every output topic has ``wait_for_subscribers`` subscribers and a subscription of each of
        ``wait_for_nodes`` (logs what it waits for, every 5 s)."""
        waiting = self._start_wait()
        if waiting and time.monotonic() - self.waiting_since > 5.0:
            self.waiting_since = time.monotonic()
            self.get_logger().info(waiting)
        return self.started

    def _publish_next(self) -> None:
        if not self._subscribed():
            return
        if self._finished():
            flush(self, [*self.outputs, self.clock_pub])
            self.get_logger().info(f"published {self.published} steps; stopping")
            self.done = True
            return
        scene = self.placer.scene(self.step)
        self._publish(scene)
        self.step += 1
        self.published += 1

    def _publish(self, scene: Scene) -> None:
        header = Header(stamp=stamp(scene.stamp.ns), frame_id="map")
        self.clock_pub.publish(Clock(clock=header.stamp))  # first: the step's time, before anything stamped with it
        self.tf_pub.publish(TFMessage(transforms=[
            _transform(header, base_frame(cam.name), cam.position, body_orientation(cam.orientation_xyzw))
            for cam in scene.cameras]))
        self.scene_pub.publish(String(data=scene.to_json()))
        if self.animals_pub is not None:
            self.animals_pub.publish(scene_animals_msg(self.animals_type, header, scene.zebras))
        self.marker_pub.publish(self._markers(scene, header))
        assert scene.datum is not None  # the placer's scenes always carry theirs
        exact = np.array([cam.position for cam in scene.cameras], np.float64).reshape(-1, 3)
        navigated = exact + self.gnss.errors(len(exact), scene.seed, scene.step)  # where each drone's GNSS puts it
        turned = [cam.orientation_xyzw for cam in scene.cameras]  # exact without an attitude error, bit for bit
        if self.attitude.sigmas.any():  # as its navigation has it turned (a small rotation about east, north and up)
            turned = [matrix_to_xyzw(r @ xyzw_to_matrix(q)) for r, q in zip(
                self.attitude.rotations(len(exact), scene.seed, scene.step), turned,
                strict=True)]
        where = enu_to_geodetic(navigated, scene.datum)
        for pose_pub, nav_pub, fix_pub, cam, nav, nav_xyzw, (lat, lon, height) in zip(
                self.pose_pubs, self.nav_pose_pubs, self.fix_pubs, scene.cameras, navigated.tolist(), turned,
                where.tolist(), strict=True):
            pose_pub.publish(PoseStamped(header=header, pose=pose_msg(cam.position, cam.orientation_xyzw)))
            nav_pub.publish(PoseStamped(header=header, pose=pose_msg(nav, nav_xyzw)))
            fix_pub.publish(NavSatFix(header=Header(stamp=header.stamp, frame_id=base_frame(cam.name)),
                                      status=self.fix_status, latitude=lat, longitude=lon, altitude=height,
                                      position_covariance=self.fix_covariance,
                                      position_covariance_type=self.fix_covariance_type))
        self.sent_at = time.monotonic()
        self.get_logger().debug(f"step {scene.step}: {scene.placed}/{scene.requested} zebras placed")

    def _markers(self, scene: Scene, header: Header) -> MarkerArray:
        markers = [Marker(header=header, ns="zebras", action=Marker.DELETEALL)]
        for z in scene.zebras:
            sx, sy, sz = z.box.size
            r, g, b, a = _MORPH_RGBA.get(z.morph, (1.0, 1.0, 1.0, 0.5))
            markers.append(Marker(
                header=header, ns="zebras", id=z.id, type=Marker.CUBE, action=Marker.ADD,
                pose=pose_msg(z.box.center, z.box.orientation_xyzw), scale=Vector3(x=sx, y=sy, z=sz),
                color=ColorRGBA(r=r, g=g, b=b, a=a)))
        return MarkerArray(markers=markers)

    # -- service ----------------------------------------------------------------------------------
    def _on_step_request(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        """Publish the next step and say which, or say why not (``success`` false)."""
        if self._finished():
            response.success, response.message = False, f"max_steps ({self.cfg.max_steps}) reached: no more steps"
        elif waiting := self._start_wait(" on request"):
            response.success, response.message = False, f"{waiting}: call again"
        else:
            scene = self.placer.scene(self.step)
            self._publish(scene)
            self.step += 1
            self.published += 1
            self.answered_at = time.monotonic()
            response.success = True
            response.message = (f"step {scene.step}, stamp {scene.stamp.sec}.{scene.stamp.nanosec:09d}: "
                                f"{scene.placed}/{scene.requested} zebras placed")
        return response

    def _service_tick(self) -> None:
        """Say what the first step waits for; after ``max_steps`` steps end, once the last answer has had time to
        reach its caller."""
        if not self.started:
            self._subscribed()
        elif self._finished() and time.monotonic() - self.answered_at > 0.5:
            # no more calls: a caller now finds no service (and waits for one, or times out) instead of no answer
            self.destroy_service(self.service)
            flush(self, [*self.outputs, self.clock_pub])
            self.get_logger().info(f"published {self.published} steps on request; stopping")
            self.done = True

    # -- lockstep ---------------------------------------------------------------------------------
    def _lockstep_tick(self) -> None:
        c = self.cfg
        if self.pending is None:
            if self._finished():
                flush(self, [*self.outputs, self.clock_pub])
                self.get_logger().info(f"all {self.published} steps acknowledged; stopping")
                self.done = True
                return
            # Start once an acknowledger is on the graph; later ones still get the step (transient local).
            if self.published == 0 and (self.count_publishers(ACK_TOPIC) == 0 or not self._subscribed()):
                return
            self.pending = self.placer.scene(self.step)
            self.acked = set()
            self._publish(self.pending)
        elif time.monotonic() - self.sent_at > c.lockstep_timeout_s:
            missing = sorted(set(c.lockstep_ack_from) - self.acked)
            self.get_logger().warning(f"step {self.pending.step}: no acknowledgement from {missing} after "
                                      f"{c.lockstep_timeout_s:.1f} s; publishing it again")
            self.resent += 1
            self._publish(self.pending)

    def _on_ack(self, msg: Header) -> None:
        if self.pending is None or stamp_ns(msg.stamp) != self.pending.stamp.ns:
            return  # a late or duplicate acknowledgement of an earlier step
        if msg.frame_id in self.cfg.lockstep_ack_from:
            self.acked.add(msg.frame_id)
        if self.acked >= set(self.cfg.lockstep_ack_from):
            self.pending = None
            self.step += 1
            self.published += 1
            self._lockstep_tick()

    def activity(self) -> Activity:
        """Steps published (in lockstep: acknowledged by all); steps published again for want of an
        acknowledgement; what it waits for: subscribers or an acknowledger before the first step (or, in service
        mode, the first call), or the acknowledgements of a step pending for over half ``lockstep_timeout_s``
        (before that: its rate)."""
        c = self.cfg
        waiting = ""
        lockstep = c.mode == "lockstep"
        if self._finished():
            waiting = f"done: {self.published} steps"
        elif lockstep and self.published == 0 and self.pending is None and self.count_publishers(ACK_TOPIC) == 0:
            waiting = f"waiting for an acknowledger on {ACK_TOPIC} before the first step"
        elif not self.started:
            waiting = "waiting for subscribers before the first step"
        elif c.mode == "service" and self.published == 0:
            waiting = f"waiting for the first call of {self.service.srv_name}"
        elif lockstep and self.pending is not None and time.monotonic() - self.sent_at > c.lockstep_timeout_s / 2:
            missing = sorted(set(c.lockstep_ack_from) - self.acked)
            waiting = (f"step {self.pending.step}: waiting {time.monotonic() - self.sent_at:.1f} s for "
                       f"{', '.join(missing)} to acknowledge")
        return Activity({"steps": self.published, "resent": self.resent}, "steps", ("resent",), waiting=waiting,
                        info={"world": c.world, "seed": str(c.seed), "strategy": c.strategy, "mode": c.mode,
                              "next step": str(self.step), "navigation": c.navigation_text()})


def _transform(header: Header, child: str, xyz: tuple[float, float, float],
               xyzw: tuple[float, float, float, float]) -> TransformStamped:
    """A TransformStamped: ``child`` in ``header.frame_id`` at ``xyz`` (m) turned by ``xyzw``."""
    return TransformStamped(header=header, child_frame_id=child, transform=Transform(
        translation=Vector3(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2])),
        rotation=Quaternion(x=xyzw[0], y=xyzw[1], z=xyzw[2], w=xyzw[3])))


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ros2 run zebra_sim_ros placer``; returns the exit status."""
    return run_node("placer", PlacerNode, argv, help_text("placer", __doc__ or "", PLACER_PARAMS))


if __name__ == "__main__":
    raise SystemExit(main())
