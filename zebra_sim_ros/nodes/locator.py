"""The ``locator`` node: where each detected animal is on the map (``ros2 run zebra_sim_ros locator``).

Subscribes, per camera in ``drones``, ``<drone>/<detections>`` (the detector's Detection2DArray),
``<drone>/depth`` (metres along the optical axis: 32FC1, or 16UC1 in millimetres, as REP 118 has them),
``<drone>/camera_info`` and ``<drone>/<pose>`` (the optical frame's pose in ``map``: ``camera/pose``, the placer's
exact one, ``camera/pose_nav``, the placer's as the drone's navigation gives it, or a drone's own localisation);
matches them by stamp, exactly (the image's: a pose source must stamp a pose per image,
as the placer does; a stamp whose inputs do not all arrive before ``sync_window`` other stamps have arrived after
it is dropped and counted; the latest camera_info serves every frame, its size the depth image's, its ``d`` the
lens's plumb_bob distortion, undone for each ray) and publishes,
with the image's stamp:

- ``<drone>/<output>`` (Detection3DArray in the pose's frame, ``map``; vision_msgs where installed, else
  zebra_sim_msgs): per detection, its class and score at the point where the ray through its box's centre meets
  the box's depth (of the depths in its central ``core``, the median of the densest span ``depth_window`` deep:
  :func:`zebra_sim_ros.geometry.locate.locate_boxes`), and its box
  at that depth in the camera's image plane (orientation the optical frame's; size: width and height in metres,
  depth 0); ``id`` its index in the detections message. A box with no measured depth in its core (sky, outside
  the image) is left out and counted (``unplaced``). A camera's frames before its first camera_info wait for it
  (within ``sync_window``); a pose that is not finite, or a depth image of another size than camera_info's, is a
  bad message. With ``pose_max_gap_s`` above 0 poses come at their own rate (a drone's odometry) and an image's is
  interpolated between the poses about its stamp (:class:`zebra_sim_ros.geometry.locate.PoseTrack`): a frame waits
  for poses after its stamp (a camera's ``sync_window`` latest such frames are held, one pushed out unmatched), and
  one between two poses farther apart than that, or before its camera's first, is unmatched.
  With ``place_by: ground`` (a camera without depth) no depth is subscribed: the point is where the
  ray through the box's centre meets the level plane ``centre_height`` above ``ground_z``
  (:func:`zebra_sim_ros.geometry.locate.locate_on_ground`); a box whose ray does not reach it, or reaches it farther
  than ``ground_max_range``, is unplaced.

- ``<census_output>`` (with ``census``; Detection3DArray in ``map``), once every camera in ``drones`` has a frame of
  the stamp placed: the animals of that instant, each counted once. Three drones that see one herd see an animal up
  to three times; per class, the cameras' placed detections are joined view by view in ``drones``' order
  (:func:`zebra_sim_ros.geometry.census.join_views`: an optimal assignment on the ground, each detection taken to be
  off by ``census_along`` along its camera's ray and ``census_across`` across it, joined under ``census_gate``
  standard deviations; first, one camera's detections closer than ``census_separation`` on the ground are one
  animal boxed twice). Per animal: its class and the highest score of its detections, its position (where their
  rays cross, weighed), a box as wide and long as its largest detection's larger side (height 0) and ``id`` the
  detections it joins (``drone_0:3,drone_0:5,drone_2:7``: camera and index in that camera's detections message).
  Each stamp is counted once: when every camera sends a counted stamp's frame again (a placer's resent step, a
  looping replay; among the last :data:`COUNTED_KEPT` counted stamps, or ``sync_window`` if more), its census is
  published again and counted in ``census_repeated``, not in ``census``; a stamp that some camera has not completed
  when ``sync_window`` later stamps have arrived gets no census (``census_incomplete``).
- ``<census_output>/markers`` (with ``census``; visualization_msgs/MarkerArray in ``map``): the census for RViz, a
  cylinder per animal coloured by how many cameras saw it (one orange, two yellow, three green) and the count.

With the placer's ``zebra_sim/zebras`` (the placed animals, the same message type) this is what an aerial survey
compares: where the detector put each animal, and where it stood, and how many there were.
"""

from __future__ import annotations

import time
from collections import Counter
from dataclasses import dataclass
from typing import Any

import numpy as np
from geometry_msgs.msg import PoseStamped, Vector3
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

from zebra_sim_ros.detection.config import CENSUS_RULE, LOCATOR_PARAMS, LocatorConfig
from zebra_sim_ros.errors import ZebraSimError
from zebra_sim_ros.geometry.census import Census
from zebra_sim_ros.geometry.lens import Distortion
from zebra_sim_ros.geometry.locate import (
    Located,
    PoseTrack,
    StampedPose,
    intrinsics,
    locate_boxes,
    locate_on_ground,
)
from zebra_sim_ros.health import Activity
from zebra_sim_ros.messages import Detections
from zebra_sim_ros.nodes.ros_adapter import (
    FrameParts,
    RecentStamps,
    ZebraNode,
    describe_qos,
    detection3d_array_msg,
    detection3d_array_type,
    detection_array_type,
    help_text,
    image_array,
    message_class,
    pose_msg,
    qos,
    run_node,
    stamp,
    stamp_ns,
    stamped_pose,
)
from zebra_sim_ros.recording.cdr import MALFORMED, cdr_detections

_MILLIMETRES = ("16UC1", "mono16")  # depth encodings in millimetres (REP 118); 32FC1 is in metres


def located_msg(type_name: str, header: Header, dets: Detections, where: Located,
                orientation_xyzw: tuple[float, float, float, float]) -> Any:
    """The detections placed on the map as a Detection3DArray of ``type_name`` in ``header``'s frame: per placed
    detection one hypothesis (class name, score) at its point, its box in the image plane at its depth (the
    optical frame's ``orientation_xyzw``, size width x height x 0 m), ``id`` its index in ``dets``."""
    rows = []
    for i, (det, point, size, ok) in enumerate(zip(dets.detections, where.points, where.size, where.valid,
                                                   strict=True)):
        if ok:
            at = pose_msg(point, orientation_xyzw)
            rows.append((det.class_name, det.score, at, at, (size[0], size[1], 0.0), str(i)))
    return detection3d_array_msg(type_name, header, rows)


@dataclass(frozen=True)
class CountedAnimal:
    """One animal of a census: its class, position (map), how many cameras saw it, the detections it joins
    (camera, index in that camera's detections message), their highest score and their largest box side (m)."""

    class_id: str
    position: tuple[float, float, float]
    views: int
    parts: tuple[tuple[str, int], ...]
    score: float
    side: float


def counted_animals(views: dict[str, tuple[Detections, Located, np.ndarray]], names: list[str], cls: str,
                    rows: list[np.ndarray], census: Census) -> list[CountedAnimal]:
    """The animals of ``census``, one class's join over the cameras ``names``: ``rows`` per camera the indices of
    the class's placed detections in its ``views`` entry (the points ``census`` was joined from)."""
    out = []
    for a, (x, y, z) in enumerate(census.positions.tolist()):
        parts = tuple((names[v], int(rows[v][j])) for v, j in census.points_of(a))
        out.append(CountedAnimal(cls, (x, y, z), int(census.views_per_animal[a]), parts,
                                 max(float(views[d][0].detections[i].score) for d, i in parts),
                                 max(float(views[d][1].size[i].max()) for d, i in parts)))
    return out


def census_msg(type_name: str, header: Header, animals: list[CountedAnimal]) -> Any:
    """The animals of one stamp as a Detection3DArray of ``type_name`` in ``header``'s frame (``map``): per animal
    one hypothesis (its class, the highest score of its detections) at its position (identity orientation), a box
    as wide and long as its largest detection's larger side, and ``id`` the detections it joins (``camera:index``)."""
    rows = []
    for animal in animals:
        at = pose_msg(animal.position)
        rows.append((animal.class_id, animal.score, at, at, (animal.side, animal.side, 0.0),
                     ",".join(f"{d}:{i}" for d, i in animal.parts)))
    return detection3d_array_msg(type_name, header, rows)


COUNTED_KEPT = 100  # counted stamps remembered (or sync_window, if more): one sent again is not counted again
# an animal's marker by how many cameras saw it: one (orange), two (yellow), three or more (green)
_VIEWS_RGBA = ((1.0, 0.55, 0.0, 0.7), (0.95, 0.9, 0.1, 0.7), (0.2, 0.85, 0.3, 0.7))
MARKER_HEIGHT_M = 1.5  # an animal's cylinder, centred on its placed point (its visible back)


def count_text(animals: list[CountedAnimal]) -> str:
    """Animals per class: "12 zebra, 2 elephant" (classes in order of first appearance); "" for none."""
    counts = Counter(a.class_id for a in animals)
    return ", ".join(f"{n} {cls}" for cls, n in counts.items())


def census_markers(header: Header, animals: list[CountedAnimal]) -> MarkerArray:
    """The census for RViz (visualization_msgs/MarkerArray in ``header``'s frame): what the last one showed deleted;
    per animal a cylinder at its position, as wide as its box, coloured by how many cameras saw it
    (:data:`_VIEWS_RGBA`), ``ns`` its class, ``id`` its index in the class; and a text over the animals: the count
    per class."""
    out = [Marker(header=header, ns="", action=Marker.DELETEALL)]  # every namespace's: the classes' and the count
    index: Counter[str] = Counter()
    for animal in animals:
        r, g, b, alpha = _VIEWS_RGBA[min(animal.views, len(_VIEWS_RGBA)) - 1]
        out.append(Marker(header=header, ns=animal.class_id, id=index[animal.class_id], type=Marker.CYLINDER,
                          action=Marker.ADD, pose=pose_msg(animal.position),
                          scale=Vector3(x=animal.side, y=animal.side, z=MARKER_HEIGHT_M),
                          color=ColorRGBA(r=r, g=g, b=b, a=alpha)))
        index[animal.class_id] += 1
    points = np.array([a.position for a in animals], np.float64).reshape(-1, 3)
    above = (points.mean(axis=0) + [0.0, 0.0, 8.0]).tolist() if len(points) else (0.0, 0.0, 8.0)
    out.append(Marker(header=header, ns="census", id=0, type=Marker.TEXT_VIEW_FACING, action=Marker.ADD,
                      pose=pose_msg(above),
                      scale=Vector3(z=3.0), color=ColorRGBA(r=1.0, g=1.0, b=1.0, a=1.0),
                      text=count_text(animals) or "no animals"))
    return MarkerArray(markers=out)


def _class_rows(dets: Detections, where: Located) -> dict[str, np.ndarray]:
    """Per class (sorted), the indices of its placed detections."""
    rows: dict[str, list[int]] = {}
    for i, (d, ok) in enumerate(zip(dets.detections, where.valid, strict=True)):
        if ok:
            rows.setdefault(d.class_name, []).append(i)
    return {cls: np.array(rows[cls], np.int64) for cls in sorted(rows)}


class LocatorNode(ZebraNode[LocatorConfig]):
    """Synchronises each camera's detections, depth and pose by stamp; thin adapter around ``locate_boxes`` and
    ``join_views``."""

    def __init__(self) -> None:
        super().__init__("locator", LocatorConfig)

    def start(self) -> None:
        """Subscribe every camera's inputs and publish its placed detections, and the census."""
        c = self.cfg
        q = qos(c.qos_reliability, c.qos_depth)
        image_q = qos(c.image_reliability, c.qos_depth)
        pose_q = qos(c.qos_reliability, c.qos_depth, transient_local=c.pose_transient_local)
        self.out_type = detection3d_array_type()
        out_class = message_class(self.out_type)
        # what each stamp of a camera needs: its inputs but camera_info (the latest serves), and but the pose where
        # poses come at their own rate (one interpolated from the camera's track, the frame held until it can be)
        self.tracks = {d: PoseTrack(c.pose_max_gap_ns) for d in c.drones} if c.pose_max_gap_ns else {}
        self.awaiting: dict[str, RecentStamps[dict[str, Any]]] = {d: RecentStamps(c.sync_window) for d in c.drones}
        self.frames = FrameParts(c.sync_window, ["detections", *(("depth",) if c.place_by == "depth" else ()),
                                                 *(() if self.tracks else ("pose",))])
        self.info: dict[str, tuple[np.ndarray, int, int, Distortion | None]] = {}  # drone: its latest K (3x3),
        # width, height and lens (None: an ideal pinhole)
        self.stats = {"frames": 0, "placed": 0, "unplaced": 0, "unmatched": 0, "bad_messages": 0, "census": 0,
                      "animals": 0, "census_incomplete": 0, "census_repeated": 0}
        self.last_count = ""  # the latest census: animals per class
        # stamp: camera: (its detections, placed, the camera's position) until every camera's frame is placed
        self.census_pending: RecentStamps[dict[str, tuple[Detections, Located, np.ndarray]]] = RecentStamps(
            c.sync_window)
        # stamps counted: the cameras whose frames came again since (a resent step, a looping replay)
        self.census_done: RecentStamps[dict[str, tuple[Detections, Located, np.ndarray]]] = RecentStamps(
            max(c.sync_window, COUNTED_KEPT))
        self.seconds = 0.0
        self.pubs: dict[str, Any] = {}
        det_class = message_class(detection_array_type())
        for d in c.drones:
            # what it reads under each camera (LocatorConfig.inputs: the depth only where it places by it): type,
            # callback, QoS, raw (the detections as CDR bytes, read by the scorer's and bag eval's reader)
            handlers = {c.detections: (det_class, self._on_detections(d), q, True),
                        "depth": (Image, self._on_part(d, "depth"), image_q, False),
                        "camera_info": (CameraInfo, self._on_info(d), image_q, False),
                        c.pose: (PoseStamped, self._on_track(d) if self.tracks else self._on_part(d, "pose"), pose_q,
                                 False)}
            for topic in c.inputs:
                kind, callback, profile, raw = handlers[topic]
                self.create_subscription(kind, f"{d}/{topic}", callback, profile, raw=raw)
            self.pubs[d] = self.create_publisher(out_class, f"{d}/{c.output}", q)
        self.census_pub = self.create_publisher(out_class, c.census_output, q) if c.census else None
        self.marker_pub = self.create_publisher(MarkerArray, f"{c.census_output}/markers", q) if c.census else None
        self.get_logger().info(f"placing {list(c.drones)}' <drone>/{c.detections} in map as <drone>/{c.output} "
                               f"({self.out_type}); QoS images: {describe_qos(image_q)}, poses: "
                               f"{describe_qos(pose_q)}, others: {describe_qos(q)}")

    def _on_info(self, drone: str) -> Any:
        def on_info(msg: CameraInfo) -> None:
            try:
                k = intrinsics(msg.k)
                distortion = Distortion.from_d(msg.d, msg.distortion_model)
            except ValueError as exc:
                self.skip_bad(self.stats, f"{drone}/camera_info", exc)
                return
            first = drone not in self.info
            self.info[drone] = (k, int(msg.width), int(msg.height), None if distortion.none else distortion)
            if first:  # the frames that waited for it
                for t in self.frames.waiting():
                    self._try(drone, t)
        return on_info

    def _on_detections(self, drone: str) -> Any:
        def on_detections(data: bytes) -> None:
            try:
                dets = cdr_detections(data)
            except (ZebraSimError, *MALFORMED) as exc:
                self.skip_bad(self.stats, f"{drone}/{self.cfg.detections}", exc)
                return
            self._put(drone, "detections", dets.stamp.ns, dets)
        return on_detections

    def _on_part(self, drone: str, part: str) -> Any:
        def on_part(msg: Any) -> None:
            self._put(drone, part, stamp_ns(msg.header.stamp), msg)
        return on_part

    def _on_track(self, drone: str) -> Any:
        def on_pose(msg: PoseStamped) -> None:
            self.tracks[drone].add(stamped_pose(msg))
            held = self.awaiting[drone]
            for t in sorted(held.items):  # the frames that waited for a pose after their stamp
                got = held.pop(t)
                if got is not None:
                    self._posed(drone, t, got)
        return on_pose

    def _put(self, drone: str, part: str, t: int, value: Any) -> None:
        self.skip_unmatched(self.stats, self.frames.put(t, drone, part, value))
        self._try(drone, t)

    def _try(self, drone: str, t: int) -> None:
        got = self.frames.take(t, drone) if drone in self.info else None
        if got is None:
            return
        if not self.tracks:  # the pose of the image's own stamp
            self._place(drone, t, got, stamped_pose(got["pose"]))
            return
        self._posed(drone, t, got)

    def _posed(self, drone: str, t: int, got: dict[str, Any]) -> None:
        """Place a frame at its pose interpolated from the camera's track, or hold it until later poses come (the
        camera's ``sync_window`` latest held: one pushed out is unmatched); one no pose can be given (before the
        track, or between two poses too far apart) is unmatched."""
        at = self.tracks[drone].at(t)
        if at is True:
            self.skip_unmatched(self.stats, [(old, drone) for old, _ in self.awaiting[drone].put(t, got)])
        if isinstance(at, StampedPose):
            self._place(drone, t, got, at)
        elif at is None:
            self.stats["unmatched"] += 1
            self.get_logger().warning(f"{drone}: no poses within pose_max_gap_s ({self.cfg.pose_max_gap_s:g} s) about "
                                      f"stamp {t}: not placed ({self.stats['unmatched']} unmatched so far)")

    def _place(self, drone: str, t: int, got: dict[str, Any], pose: StampedPose) -> None:
        """Place a camera's frame of stamp ``t`` (its parts ``got``) from ``pose``; publish it and hold it for the
        census; a frame it cannot place is a bad message."""
        t0 = time.perf_counter()
        dets: Detections = got["detections"]
        orientation = pose.orientation_xyzw
        position = np.array(pose.position)
        try:
            k, width, height, distortion = self.info[drone]
            boxes = np.array([x.box_xyxy for x in dets.detections], np.float64).reshape(-1, 4)
            c = self.cfg
            if c.place_by == "ground":
                where = locate_on_ground(boxes, k, position, np.array(orientation), c.ground_z, c.centre_height,
                                         distortion, c.ground_max_range)
            else:
                depth = image_array(got["depth"])
                if depth.shape != (height, width):
                    raise ValueError(f"a depth image of {depth.shape[1]}x{depth.shape[0]} px with camera_info of "
                                     f"{width}x{height}")
                if got["depth"].encoding in _MILLIMETRES:  # REP 118: 16-bit depth in millimetres, 0 unmeasured
                    depth = depth.astype(np.float32) / 1000.0
                where = locate_boxes(boxes, depth, k, position, np.array(orientation), c.core, c.depth_window,
                                     distortion)
        except (ZebraSimError, ValueError, TypeError, IndexError, ArithmeticError) as exc:
            self.skip_bad(self.stats, f"{drone} stamp {t}", exc)
            return
        self.pubs[drone].publish(located_msg(self.out_type, Header(stamp=stamp(t), frame_id=pose.frame),
                                             dets, where, orientation))
        if self.census_pub is not None:
            self._census(t, drone, dets, where, position, pose.frame)
        placed = int(where.valid.sum())
        self.stats["frames"] += 1
        self.stats["placed"] += placed
        self.stats["unplaced"] += len(dets.detections) - placed
        self.seconds += time.perf_counter() - t0

    def _census(self, t: int, drone: str, dets: Detections, where: Located, origin: np.ndarray, frame: str) -> None:
        """Hold this camera's placed frame; with every camera's frame of stamp ``t``, count its animals once. A
        counted stamp whose every camera sends its frame again (a placer's resent step, a looping replay) is
        published again, not counted again (``census_repeated``); a partial repeat is not a missing census."""
        if (again := self.census_done.get(t)) is not None:
            again[drone] = (dets, where, origin)
            if all(d in again for d in self.cfg.drones):
                self.census_done.put(t, {})
                self.stats["census_repeated"] += 1
                self._publish_census(t, again, frame)
            return
        views, dropped = self.census_pending.touch(t, dict)
        views[drone] = (dets, where, origin)
        for old, got in dropped:
            self.stats["census_incomplete"] += 1
            self.get_logger().warning(f"census of stamp {old}: only {', '.join(got)} of {len(self.cfg.drones)} "
                                      f"cameras placed; not counted ({self.stats['census_incomplete']} so far)")
        if any(d not in views for d in self.cfg.drones):
            return
        self.census_pending.pop(t)
        self.census_done.put(t, {})
        animals = self._publish_census(t, views, frame)
        self.stats["census"] += 1
        self.stats["animals"] += len(animals)
        self.last_count = count_text(animals) or "none"

    def _publish_census(self, t: int, views: dict[str, tuple[Detections, Located, np.ndarray]],
                        frame: str) -> list[CountedAnimal]:
        """Join every camera's placed frame of stamp ``t`` per class and publish the census and its markers."""
        c = self.cfg
        names = list(c.drones)
        by_camera = [_class_rows(views[d][0], views[d][1]) for d in names]
        empty = np.zeros(0, np.int64)
        animals: list[CountedAnimal] = []
        for cls in sorted({cls for rows in by_camera for cls in rows}):
            rows = [r.get(cls, empty) for r in by_camera]
            census = c.census_join([views[d][1].points[r] for d, r in zip(names, rows, strict=True)],
                                   [views[d][2] for d in names],
                                   [np.array([views[d][0].detections[i].score for i in r], np.float64)
                                    for d, r in zip(names, rows, strict=True)])
            animals += counted_animals(views, names, cls, rows, census)
        header = Header(stamp=stamp(t), frame_id=frame)
        assert self.census_pub is not None and self.marker_pub is not None
        self.census_pub.publish(census_msg(self.out_type, header, animals))
        self.marker_pub.publish(census_markers(header, animals))
        return animals

    def activity(self) -> Activity:
        """Frames placed; detections placed and not (no depth in the box); frames whose inputs never all arrived
        (unmatched) and bad messages skipped; stamps counted (census), the animals in them, stamps some camera
        never completed (census_incomplete) and counted stamps published again (census_repeated). Waits for a
        camera's camera_info before it places its frames, and with poses at their own rate for a pose after a
        frame's stamp."""
        missing = [d for d in self.cfg.drones if d not in self.info]
        held = sum(len(h.items) for h in self.awaiting.values())
        waiting = "; ".join(([f"waiting for camera_info of {', '.join(missing)}"] if missing else [])
                            + ([f"{held} frames waiting for a pose after their stamp"] if held else []))
        c = self.cfg
        info = {"drones": ", ".join(c.drones), "output": c.output, "pose": c.pose,
                "pose_max_gap_s": repr(c.pose_max_gap_s),
                "place_by": c.place_by if c.place_by == "depth" else
                f"ground at z {c.ground_z:g} m, centres {c.centre_height:g} m above it, within "
                f"{c.ground_max_range:g} m"}
        if c.census:  # what a bag census follows (recording.census.bag_census): names as the parameters'
            info.update({"census_output": c.census_output, **{k: repr(getattr(c, k)) for k in CENSUS_RULE},
                         "last census": self.last_count or "none yet"})
        return Activity(dict(self.stats), "frames", ("unmatched", "bad_messages", "census_incomplete"),
                        busy_s=self.seconds, waiting=waiting, info=info)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ros2 run zebra_sim_ros locator``; returns the exit status."""
    return run_node("locator", LocatorNode, argv, help_text("locator", __doc__ or "", LOCATOR_PARAMS))


if __name__ == "__main__":
    raise SystemExit(main())
