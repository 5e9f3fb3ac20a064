"""The ``camera`` node: one drone's RGB, metric depth and instance mask per scene.

Run one per drone, in the graph's namespace (topic names are relative, so a namespace moves the whole graph)::

    ros2 run zebra_sim_ros camera --ros-args -r __node:=drone_1_camera -p drone_index:=1

Subscribes ``zebra_sim/scene`` (std_msgs/String, reliable, transient local) and publishes, all four with
the scene's stamp and frame_id ``drone_{i}/camera_optical`` (z forward, x right, y down):

- ``drone_{i}/image_raw`` (sensor_msgs/Image ``rgb8``), gamma-encoded sRGB;
- ``drone_{i}/depth`` (sensor_msgs/Image ``32FC1``): metres along the optical axis; +inf where only sky (REP 118);
- ``drone_{i}/instances`` (sensor_msgs/Image ``mono16``): 0 = not a zebra, else the zebra's scene id + 1;
- ``drone_{i}/camera_info`` (sensor_msgs/CameraInfo): K and P of the pinhole, and ``d`` the lens's plumb_bob
  distortion (``lens_k1`` .. ``lens_k3``; zeros by default: an ideal pinhole, whose images need no rectification);
- with ``compressed`` jpeg or png, ``drone_{i}/image_raw/compressed`` (sensor_msgs/CompressedImage): the same
  image as ``image_transport``'s compressed transport sends it (format ``rgb8; jpeg compressed bgr8``): at 1280x720
  jpeg 90 is 5% of the raw bytes, png 35% (``benchmarks/bench_compressed.py``), to record or send over a network;
- with ``points_stride`` N > 0, ``drone_{i}/points`` (sensor_msgs/PointCloud2, what ``depth_image_proc``'s
  ``point_cloud_xyzrgb`` makes, without a ROS install): the point of every Nth pixel of each row and column, its
  ray through the lens times the depth, and its colour; organised (ceil(H / N) x ceil(W / N)), NaN where only sky.

The compressed image and the points are made only while something subscribes them.

Then, with ``ack`` true, it acknowledges the step on ``zebra_sim/frame_done`` (std_msgs/Header, stamp = the
scene's, frame_id = ``drone_{i}``) so a lockstep placer can go on. A scene it cannot read is logged, counted
and skipped; a repeated scene (same stamp) is published again but rendered once.
"""

from __future__ import annotations

import time

import numpy as np
from sensor_msgs.msg import CameraInfo, CompressedImage, Image, PointCloud2
from std_msgs.msg import Header, String

from zebra_sim_ros.errors import ZebraSimError
from zebra_sim_ros.geometry.camera import depth_points
from zebra_sim_ros.geometry.frames import optical_frame
from zebra_sim_ros.geometry.lens import PLUMB_BOB
from zebra_sim_ros.health import Activity
from zebra_sim_ros.messages import Scene
from zebra_sim_ros.nodes.ros_adapter import (
    ACK_TOPIC,
    ZebraNode,
    describe_qos,
    help_text,
    image_msg,
    point_cloud_msg,
    qos,
    run_node,
    stamp,
)
from zebra_sim_ros.placement.config import SCENE_TOPIC
from zebra_sim_ros.recording.images import compress_rgb
from zebra_sim_ros.rendering.config import CAMERA_PARAMS, CameraConfig
from zebra_sim_ros.rendering.renderer import RenderedView
from zebra_sim_ros.simulation import Simulator
from zebra_sim_ros.world.world import load_world
from zebra_sim_ros.zebra.asset import load_library


def camera_info_msg(header: Header, K: np.ndarray, width: int, height: int,  # noqa: N803
                    D: tuple[float, ...] = (0.0,) * 5) -> CameraInfo:  # noqa: N803
    """CameraInfo of a pinhole with intrinsics K (OpenCV convention) and plumb_bob distortion D (P = K: the
    rectified image keeps K)."""
    p = np.zeros((3, 4))
    p[:, :3] = K
    return CameraInfo(header=header, width=width, height=height, distortion_model=PLUMB_BOB,
                      d=[float(v) for v in D],
                      k=[float(v) for v in K.ravel()], r=[1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0],
                      p=[float(v) for v in p.ravel()])


class CameraNode(ZebraNode[CameraConfig]):
    """Thin adapter around :class:`zebra_sim_ros.rendering.renderer.Renderer` (no parameter changes while running)."""

    def __init__(self) -> None:
        super().__init__("camera", CameraConfig)

    def start(self) -> None:
        """Load the zebras; render each scene that arrives (the world's renderer is made with the first)."""
        c = self.cfg
        self.library = load_library()
        self.sim: Simulator | None = None  # the renderer of the scene's world (its labels are the labeller's)
        self.world_key: tuple[str, str, int] | None = None
        self.effects = c.effects()
        self.camera = c.render_options().camera  # what it renders; the points' rays
        distortion = self.camera.distortion
        self.lens = "ideal" if distortion.none else f"plumb_bob {list(distortion.coefficients)}"
        self.points = f"every {c.points_stride} px" if c.points_stride else "off"
        self.frame_id = optical_frame(c.name)
        out_qos = qos(c.qos_reliability, c.qos_depth)
        scene_qos = qos("reliable", 1, transient_local=True)
        self.pub_rgb = self.create_publisher(Image, f"{c.name}/image_raw", out_qos)
        self.pub_depth = self.create_publisher(Image, f"{c.name}/depth", out_qos)
        self.pub_ids = self.create_publisher(Image, f"{c.name}/instances", out_qos)
        self.pub_info = self.create_publisher(CameraInfo, f"{c.name}/camera_info", out_qos)
        self.pub_compressed = self.create_publisher(CompressedImage, f"{c.name}/image_raw/compressed", out_qos) \
            if c.compressed != "off" else None
        self.pub_points = self.create_publisher(PointCloud2, f"{c.name}/points", out_qos) if c.points_stride else None
        # only when it acknowledges: a lockstep placer starts once an acknowledger publishes on the topic
        self.pub_ack = self.create_publisher(Header, ACK_TOPIC, qos("reliable", 100)) if c.ack else None
        self.create_subscription(String, SCENE_TOPIC, self._on_scene, scene_qos)
        self.get_logger().info(
            f"{c.name}: {c.width}x{c.height}, hfov {c.hfov_deg} deg, lens {self.lens}, points {self.points}, "
            f"shadows {c.shadows}, effects "
            f"{self.effects if self.effects.active else 'off'}; QoS images: {describe_qos(out_qos)}; "
            f"scene: {describe_qos(scene_qos)}; publishing in namespace '{self.get_namespace()}'")
        self.last: tuple[int, Header, RenderedView] | None = None
        self.frames = 0  # published, a re-sent step's again
        self.rendered = 0
        self.skipped = 0
        self.render_seconds = 0.0
        self.store_error: str | None = None

    def _ensure_simulator(self, scene: Scene) -> Simulator:
        key = scene.world.load_args()
        if self.sim is None or key != self.world_key:
            t0 = time.perf_counter()
            world = load_world(*key)
            if self.sim is not None:
                old, self.sim, self.world_key = self.sim, None, None  # a failed build below leaves no released one
                old.release()
            self.sim = Simulator(world, self.library, self.cfg.render_options(), sensor=self.cfg.sensor_model())
            self.world_key = key
            info = self.sim.renderer.info
            store = self.sim.renderer.coat_store
            self.get_logger().info(f"world '{world.name}' loaded; OpenGL {info['GL_RENDERER']} ({info['device']}) "
                                   f"in {time.perf_counter() - t0:.1f} s; coats: "
                                   f"{store.dir if store.on else 'baked in memory'}")
        return self.sim

    def _on_scene(self, msg: String) -> None:
        try:
            scene = Scene.from_json(msg.data)
            t = scene.stamp.ns
            if self.last is not None and self.last[0] == t:
                self._publish(self.last[1], self.last[2], scene)  # a re-sent step: same images again
                return
            scene.camera(self.cfg.name)  # refuses a scene without this drone before any rendering
            sim = self._ensure_simulator(scene)
            t0 = time.perf_counter()
            view = sim.render(scene, [self.cfg.name])[0]
            error = sim.renderer.coat_store.error
            if error and error != self.store_error:  # said once, when the store is found unusable
                self.store_error = error
                self.get_logger().warning(error)
            if self.effects.active:
                rng = np.random.default_rng([scene.seed, scene.step, self.cfg.drone_index])
                view.rgb = self.effects.apply(view.rgb, rng)
            self.render_seconds += time.perf_counter() - t0
            self.rendered += 1
        except (ZebraSimError, KeyError, TypeError, ValueError) as exc:
            self.skipped += 1
            self.get_logger().error(f"scene skipped ({self.skipped} so far): {exc}")
            return
        header = Header(stamp=stamp(t), frame_id=self.frame_id)
        self.last = (t, header, view)
        self._publish(header, view, scene)

    def _publish(self, header: Header, view: RenderedView, scene: Scene) -> None:
        c = self.cfg
        self.pub_rgb.publish(image_msg(header, view.rgb, "rgb8"))
        self.pub_depth.publish(image_msg(header, view.depth.astype("<f4"), "32FC1"))
        self.pub_ids.publish(image_msg(header, view.instances.astype("<u2"), "mono16"))
        self.pub_info.publish(camera_info_msg(header, view.K, c.width, c.height, view.D))
        if self.pub_compressed is not None and self.pub_compressed.get_subscription_count():  # encode for a reader
            fmt, data = compress_rgb(view.rgb, c.compressed, c.compressed_quality)
            self.pub_compressed.publish(CompressedImage(header=header, format=fmt, data=data))
        if self.pub_points is not None and self.pub_points.get_subscription_count():
            s = c.points_stride
            self.pub_points.publish(point_cloud_msg(header, depth_points(view.depth, self.camera, s),
                                                    view.rgb[::s, ::s]))
        self.frames += 1
        if self.pub_ack is not None:
            self.pub_ack.publish(Header(stamp=header.stamp, frame_id=c.name))
        if self.frames % 20 == 1:
            store = self.sim.renderer.coat_store if self.sim is not None else None
            coats = f", coats baked {store.baked} / read {store.read}" if store is not None else ""
            self.get_logger().info(f"step {scene.step}: frame {self.frames}, "
                                   f"{self.render_seconds / max(self.rendered, 1):.2f} s/frame render, "
                                   f"{self.skipped} scenes skipped{coats}")

    def activity(self) -> Activity:
        """Frames rendered (and the seconds that took), frames published again for a re-sent step, scenes
        skipped."""
        c = self.cfg
        world = self.world_key[0] if self.world_key else "none loaded yet"
        counts = {"frames": self.rendered, "republished": self.frames - self.rendered, "skipped": self.skipped}
        return Activity(counts, "frames", ("skipped",),
                        busy_s=self.render_seconds, hardware=c.name,
                        info={"world": str(world), "image size": f"{c.width}x{c.height}", "lens": self.lens,
                              "points": self.points})

    def stop(self) -> None:
        """Say what the coats cost, release the GL context."""
        if self.sim is not None:
            store = self.sim.renderer.coat_store
            self.get_logger().info(f"{self.frames} frames, {self.skipped} scenes skipped; coats baked {store.baked}, "
                                   f"read from the store {store.read}")
            self.sim.release()
            self.sim = None
        else:
            self.get_logger().info(f"{self.frames} frames, {self.skipped} scenes skipped")


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ros2 run zebra_sim_ros camera``; returns the exit status."""
    return run_node("camera", CameraNode, argv, help_text("camera", __doc__ or "", CAMERA_PARAMS))


if __name__ == "__main__":
    raise SystemExit(main())
