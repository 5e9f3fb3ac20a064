"""The ``labeller`` node: exact ground truth for every drone frame (``ros2 run zebra_sim_ros labeller``).

Subscribes ``zebra_sim/scene`` and, per drone in ``drones``, ``<drone>/instances``, ``<drone>/depth`` and
``<drone>/camera_info``; matches them by stamp (frames whose inputs do not all arrive before ``sync_window``
other stamps have arrived after theirs are dropped and counted; a stamp older than those seen, from a restarted
placer or a looping replay, is a new one) and publishes per drone, with the image's stamp:

- ``<drone>/labels`` (std_msgs/String): the label JSON (schema in ``zebra_sim_ros.labels.labeller``);
- ``<drone>/labels/markers`` (visualization_msgs/ImageMarker): one LINE_LIST with every zebra's visible box
  (green) and full box (orange), frame_id of the image, for Foxglove's image panel;
- ``<drone>/labels/boxes3d`` (visualization_msgs/MarkerArray): the zebras' oriented 3D boxes in ``map``;
- ``<drone>/labels/boxes2d`` (Detection2DArray, the detector's type): the ground truth as detections of score 1,
  each ``id`` the scene's zebra id: the labelled zebras' visible boxes, and the other species seen, named by their
  species (:meth:`zebra_sim_ros.messages.Labels.ground_truth`), to compare with ``<drone>/detections`` live.
"""

from __future__ import annotations

import time
from typing import Any

from geometry_msgs.msg import Vector3
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import ColorRGBA, Header, String
from visualization_msgs.msg import ImageMarker, Marker, MarkerArray

from zebra_sim_ros.errors import ZebraSimError
from zebra_sim_ros.geometry.camera import PinholeCamera
from zebra_sim_ros.geometry.lens import Distortion
from zebra_sim_ros.geometry.locate import intrinsics
from zebra_sim_ros.health import Activity
from zebra_sim_ros.labels.config import LABELLER_PARAMS, LabellerConfig
from zebra_sim_ros.labels.labeller import Labeller
from zebra_sim_ros.messages import Labels, Scene
from zebra_sim_ros.nodes.ros_adapter import (
    FrameParts,
    RecentStamps,
    StepAcks,
    ZebraNode,
    box_marker,
    describe_qos,
    detection_array_msg,
    detection_array_type,
    help_text,
    image_array,
    message_class,
    pose_msg,
    qos,
    run_node,
    stamp_ns,
)
from zebra_sim_ros.placement.config import SCENE_TOPIC
from zebra_sim_ros.rendering.gl import create_context
from zebra_sim_ros.zebra.asset import load_library


def box_markers(header: Header, labels: Labels) -> ImageMarker:
    """One LINE_LIST ImageMarker with every zebra's full (orange) and visible (green) box."""
    green, orange = ColorRGBA(r=0.1, g=1.0, b=0.2, a=1.0), ColorRGBA(r=1.0, g=0.6, b=0.0, a=1.0)
    boxes = ((box, col) for z in labels.zebras for box, col in ((z.box_full, orange), (z.box_visible, green)))
    return box_marker(header, "zebra_boxes", boxes)


def boxes3d(header: Header, labels: Labels) -> MarkerArray:
    """The labelled zebras' 3D boxes in ``map`` as CUBE markers (after a DELETEALL)."""
    h = Header(stamp=header.stamp, frame_id="map")
    out = [Marker(header=h, ns="zebra_boxes3d", action=Marker.DELETEALL)]
    for z in labels.zebras:
        b = z.box3d_map
        sx, sy, sz = b.size
        out.append(Marker(header=h, ns="zebra_boxes3d", id=z.id, type=Marker.CUBE, action=Marker.ADD,
                          pose=pose_msg(b.center, b.orientation_xyzw), scale=Vector3(x=sx, y=sy, z=sz),
                          color=ColorRGBA(r=0.1, g=1.0, b=0.2, a=0.35 if z.kept else 0.1)))
    return MarkerArray(markers=out)


class LabellerNode(ZebraNode[LabellerConfig]):
    """Synchronises scene, masks, depth and camera info by stamp; thin adapter around ``label_view`` (no parameter
    changes while running)."""

    def __init__(self) -> None:
        super().__init__("labeller", LabellerConfig)

    def start(self) -> None:
        """Load the zebras; subscribe every drone's inputs and publish its labels."""
        c = self.cfg
        self.library = load_library()
        self.filters = c.filters()
        self.labellers: dict[tuple[int, int, float, Distortion], Labeller] = {}  # per camera model
        self.ctx: Any = None  # one GL context for them all (made with the first)
        q = qos(c.qos_reliability, c.qos_depth)
        image_q = qos(c.image_reliability, c.qos_depth)
        scene_qos = qos("reliable", 1, transient_local=True)
        # the last sync_window stamps to arrive (a restarted placer or a looping replay sends older ones again)
        self.scenes: RecentStamps[Scene] = RecentStamps(c.sync_window)
        self.frames = FrameParts(c.sync_window, ("instances", "depth", "info"))
        self.stats = {"labelled": 0, "unmatched": 0, "bad_messages": 0}
        self.create_subscription(String, SCENE_TOPIC, self._on_scene, scene_qos)
        self.pubs: dict[str, tuple[Any, Any, Any, Any]] = {}
        self.det_type = detection_array_type()
        det_class = message_class(self.det_type)
        for d in c.drones:
            for topic, kind, typ in (("instances", "instances", Image), ("depth", "depth", Image),
                                     ("camera_info", "info", CameraInfo)):
                self.create_subscription(typ, f"{d}/{topic}", self._handler(d, kind), image_q)
            self.pubs[d] = (self.create_publisher(String, f"{d}/labels", q),
                            self.create_publisher(ImageMarker, f"{d}/labels/markers", q),
                            self.create_publisher(MarkerArray, f"{d}/labels/boxes3d", q),
                            self.create_publisher(det_class, f"{d}/labels/boxes2d", q))
        self.acks = StepAcks(self, c.ack_name, c.drones, window=c.sync_window)
        self.get_logger().info(f"labelling {list(c.drones)}; QoS images: {describe_qos(image_q)}, outputs: "
                               f"{describe_qos(q)}; "
                               f"scene: {describe_qos(scene_qos)}; filters {self.filters.to_dict()}")
        self.seconds = 0.0

    def _handler(self, drone: str, kind: str) -> Any:
        def on_message(msg: Any) -> None:
            self._on_input(drone, kind, msg)
        return on_message

    def _on_scene(self, msg: String) -> None:
        try:
            scene = Scene.from_json(msg.data)
        except ZebraSimError as exc:
            self.skip_bad(self.stats, "a scene", exc)
            return
        t = scene.stamp.ns
        self.scenes.put(t, scene)
        for d in self.cfg.drones:
            self._try(d, t)

    def _on_input(self, drone: str, kind: str, msg: Any) -> None:
        t = stamp_ns(msg.header.stamp)
        self.skip_unmatched(self.stats, self.frames.put(t, drone, kind, msg))
        self._try(drone, t)

    def _labeller(self, info: CameraInfo) -> Labeller:
        """The labeller of ``info``'s camera model, its lens too (made once per model); ValueError for a K that
        :func:`~zebra_sim_ros.geometry.locate.intrinsics` refuses, a distortion other than plumb_bob, or an empty
        image."""
        width, height, fx = int(info.width), int(info.height), float(intrinsics(info.k)[0, 0])
        if width <= 0 or height <= 0:
            raise ValueError(f"camera_info of {width}x{height} px: want a non-empty image")
        camera = PinholeCamera.with_focal(width, height, fx, Distortion.from_d(info.d, info.distortion_model))
        key = (width, height, round(camera.hfov_deg, 6), camera.distortion)
        if key not in self.labellers:
            if self.ctx is None:
                self.ctx = create_context()[0]
            # ParameterError for a lens that folds over in the image (lens_canvas remembers it: not solved again)
            self.labellers[key] = Labeller(self.library, camera, self.filters, self.cfg.zebra_detail_distance_m,
                                           ctx=self.ctx)
        return self.labellers[key]

    def _try(self, drone: str, t: int) -> None:
        if (scene := self.scenes.get(t)) is None or (got := self.frames.take(t, drone)) is None:
            return
        t0 = time.perf_counter()
        try:
            info: CameraInfo = got["info"]
            labeller = self._labeller(info)
            labels = labeller.label(scene, drone, image_array(got["instances"]), image_array(got["depth"]))
        except (ZebraSimError, KeyError, ValueError, TypeError, IndexError, ArithmeticError) as exc:
            self.skip_bad(self.stats, f"{drone} stamp {t}: a frame", exc)  # an instance image with inf (32FC1), say
            return
        header = got["instances"].header
        labels_pub, markers_pub, boxes_pub, truth_pub = self.pubs[drone]
        labels_pub.publish(String(data=labels.to_json()))
        markers_pub.publish(box_markers(header, labels))
        boxes_pub.publish(boxes3d(header, labels))
        if truth_pub.get_subscription_count():  # built for a reader only
            truth_pub.publish(detection_array_msg(self.det_type, header, *labels.ground_truth()))
        self.stats["labelled"] += 1
        self.seconds += time.perf_counter() - t0
        self.acks.part_done(header.stamp, drone)
        if self.stats["labelled"] % 30 == 1:
            self.get_logger().info(f"{self.stats}; {self.seconds / self.stats['labelled']:.3f} s per frame")

    def activity(self) -> Activity:
        """Frames labelled; frames whose inputs never all arrived (unmatched) and bad messages skipped."""
        counts = {"frames": self.stats["labelled"], "unmatched": self.stats["unmatched"],
                  "bad_messages": self.stats["bad_messages"]}
        return Activity(counts, "frames", ("unmatched", "bad_messages"), busy_s=self.seconds,
                        info={"drones": ", ".join(self.cfg.drones)})

    def stop(self) -> None:
        """Release GL resources."""
        for labeller in self.labellers.values():
            labeller.release()
        if self.ctx is not None:
            self.ctx.release()
        print(f"[labeller] stopping: {self.stats}", flush=True)  # plain: the ROS context may be shut down already


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ros2 run zebra_sim_ros labeller``; returns the exit status."""
    return run_node("labeller", LabellerNode, argv, help_text("labeller", __doc__ or "", LABELLER_PARAMS))


if __name__ == "__main__":
    raise SystemExit(main())
