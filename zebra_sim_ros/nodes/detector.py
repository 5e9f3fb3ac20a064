"""The ``detector`` node: our YOLO on live images (``ros2 run zebra_sim_ros detector``).

Subscribes every topic in ``image_topics`` (sensor_msgs/Image; rgb8, bgr8, rgba8, bgra8 and mono8 are
converted, other encodings are logged, counted and skipped; a topic ending in ``/compressed`` is read as
sensor_msgs/CompressedImage, jpeg or png, as ``image_transport``'s compressed transport and camera drivers send
it), detects frames that arrive within ``batch_window_s`` of each other as one batch, and publishes beside each
input topic (``drone_0/image_raw`` or ``drone_0/image_raw/compressed`` -> ``drone_0/detections...``; names are
relative, so a namespace moves them), keeping the image's header:

- ``detections`` (vision_msgs/Detection2DArray where vision_msgs can be imported, else
  zebra_sim_msgs/Detection2DArray, the same fields): per box one ``results`` hypothesis (``class_id`` "zebra",
  ``score``) and ``bbox`` (centre and size in pixels, pixel-edge coordinates), ``id`` its rank by score;
- ``detections/image`` (sensor_msgs/Image rgb8): the image with the boxes drawn;
- ``detections/markers`` (visualization_msgs/ImageMarker): one LINE_LIST with every box.

With ``ack_name`` set it acknowledges a stamp on ``zebra_sim/frame_done`` once every input topic of that stamp
is detected, so the placer's lockstep can wait for detections too.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import torch
from sensor_msgs.msg import CompressedImage, Image
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import ImageMarker

from zebra_sim_ros.detection.checkpoint import load_model, select_device
from zebra_sim_ros.detection.config import (
    DETECTOR_PARAMS,
    DetectorConfig,
    distinct_outputs,
    is_compressed,
    output_base,
)
from zebra_sim_ros.detection.draw import OTHER_COLOUR, draw_boxes
from zebra_sim_ros.detection.predict import describe_size, detect, detections_message
from zebra_sim_ros.detection.verify import load_verifier
from zebra_sim_ros.health import Activity
from zebra_sim_ros.messages import Stamp
from zebra_sim_ros.nodes.ros_adapter import (
    StepAcks,
    ZebraNode,
    box_marker,
    describe_qos,
    detection_array_msg,
    detection_array_type,
    help_text,
    image_msg,
    message_class,
    qos,
    run_node,
)
from zebra_sim_ros.recording.images import decompress_rgb

_CHANNELS = {"rgb8": (3, None), "bgr8": (3, [2, 1, 0]), "rgba8": (4, [0, 1, 2]), "bgra8": (4, [2, 1, 0]),
             "mono8": (1, [0, 0, 0])}


def to_rgb(msg: Image | CompressedImage) -> np.ndarray:
    """An image message as an RGB uint8 array; ValueError for an encoding or compressed format we do not convert."""
    if isinstance(msg, CompressedImage):
        return decompress_rgb(msg.format, bytes(msg.data))
    spec = _CHANNELS.get(msg.encoding)
    if spec is None:
        raise ValueError(f"unsupported encoding {msg.encoding!r} (converted: {sorted(_CHANNELS)})")
    ch, order = spec
    if msg.width == 0 or msg.height == 0:
        raise ValueError(f"an empty image ({msg.width}x{msg.height})")
    buf = np.frombuffer(bytes(msg.data), dtype=np.uint8)
    if msg.step < msg.width * ch or len(buf) < msg.step * msg.height:
        raise ValueError(f"image data of {len(buf)} bytes does not fit {msg.width}x{msg.height} {msg.encoding}")
    img = buf[: msg.step * msg.height].reshape(msg.height, msg.step)[:, : msg.width * ch].reshape(
        msg.height, msg.width, ch)
    return np.ascontiguousarray(img if order is None else img[..., order])


class DetectorNode(ZebraNode[DetectorConfig]):
    """Thin adapter around :func:`zebra_sim_ros.detection.predict.detect`; ``conf``, ``iou``, ``imgsz`` and
    ``scale`` may change while it runs (the next batch uses them)."""

    def __init__(self) -> None:
        super().__init__("detector", DetectorConfig)

    def start(self) -> None:
        """Load the model; subscribe every image topic and publish beside each."""
        c = self.cfg
        distinct_outputs(c.image_topics, self.resolve_topic_name)  # the config checked them as written
        torch.set_num_threads(max(1, torch.get_num_threads()))
        self.device = select_device(c.device)
        self.model, ckpt = load_model(c.weights or None, self.device, amp=c.amp, amp_name="amp")
        self.verifier = load_verifier(c.verifier, self.device, "verifier")[0] if c.verifier else None
        q = qos(c.qos_reliability, c.qos_depth)
        image_q = qos(c.image_reliability, c.qos_depth)
        self.pending: dict[str, Image | CompressedImage] = {}
        self.pubs: dict[str, tuple[Any, Any, Any]] = {}
        self.det_type = detection_array_type()
        det_class = message_class(self.det_type)
        for topic in c.image_topics:
            base = output_base(topic)
            self.pubs[topic] = (self.create_publisher(det_class, base, q),
                                self.create_publisher(Image, f"{base}/image", q),
                                self.create_publisher(ImageMarker, f"{base}/markers", q))
            kind = CompressedImage if is_compressed(topic) else Image
            self.create_subscription(kind, topic, self._handler(topic), image_q)
        self.acks = StepAcks(self, c.ack_name, c.image_topics, window=50)
        self.timer = self.wall_timer(c.batch_window_s, self._flush)
        self.stats = {"images": 0, "batches": 0, "skipped": 0}
        self.seconds = 0.0
        self.get_logger().info(
            f"weights {c.weights or 'shipped'} ({self.model.cfg.size}, epoch {ckpt.get('epoch')}), device "
            f"{self.device}, inference size {describe_size(self.model.cfg, c.imgsz, c.scale)}, conf {c.conf}, "
            f"iou {c.iou}, verifier {c.verifier or 'off'}, features in {self.model.serve_precision}; "
            f"topics {list(c.image_topics)} -> {self.det_type}; "
            f"QoS images: {describe_qos(image_q)}, outputs: {describe_qos(q)}")

    def on_config(self, cfg: DetectorConfig) -> None:
        """Detect the next batch with the new thresholds and inference size."""
        self.cfg = cfg
        self.get_logger().info(f"now conf {cfg.conf}, iou {cfg.iou}, inference size "
                               f"{describe_size(self.model.cfg, cfg.imgsz, cfg.scale)}")

    def _handler(self, topic: str) -> Any:
        def on_image(msg: Image | CompressedImage) -> None:
            if topic in self.pending:  # a newer frame on the same topic before the batch ran: keep the newest
                self.stats["skipped"] += 1
            self.pending[topic] = msg
        return on_image

    def _flush(self) -> None:
        if not self.pending:
            return
        batch, self.pending = self.pending, {}
        topics, images, msgs = [], [], []
        for topic, msg in batch.items():
            try:
                images.append(to_rgb(msg))
            except ValueError as exc:
                self.stats["skipped"] += 1
                self.get_logger().error(f"{topic}: image skipped ({self.stats['skipped']} so far): {exc}")
                continue
            topics.append(topic)
            msgs.append(msg)
        if not images:
            return
        t0 = time.perf_counter()
        dets = detect(self.model, images, self.cfg.imgsz, self.cfg.conf, self.cfg.iou, self.cfg.max_det,
                      scale=self.cfg.scale, verifier=self.verifier)
        self.seconds += time.perf_counter() - t0
        self.stats["batches"] += 1
        for topic, msg, img, d in zip(topics, msgs, images, dets, strict=True):
            self._publish(topic, msg, img, d)
        if self.stats["batches"] % 50 == 1:
            self.get_logger().info(f"{self.stats}; {self.seconds / self.stats['batches']:.3f} s per batch")

    def activity(self) -> Activity:
        """Images detected; images skipped (unreadable, or replaced by a newer frame of their topic before their
        batch ran: the detector is behind its cameras); the time in detection."""
        c = self.cfg
        return Activity(dict(self.stats), "images", ("skipped",), busy_s=self.seconds, hardware=str(self.device),
                        info={"weights": c.weights or "shipped", "verifier": c.verifier or "off",
                              "conf": f"{c.conf:g}", "topics": ", ".join(c.image_topics)})

    def stop(self) -> None:
        """Say what was detected and what was skipped."""
        print(f"[detector] stopping: {self.stats}", flush=True)  # plain: the ROS context may be shut down already

    def _publish(self, topic: str, msg: Image | CompressedImage, img: np.ndarray, dets: np.ndarray) -> None:
        header = msg.header
        payload = detections_message(Stamp(header.stamp.sec, header.stamp.nanosec), header.frame_id, img.shape[1],
                                     img.shape[0], dets, self.model.cfg.names)
        det_pub, img_pub, mark_pub = self.pubs[topic]
        det_pub.publish(detection_array_msg(self.det_type, header, payload))
        if self.cfg.publish_image:
            img_pub.publish(image_msg(header, draw_boxes(img, dets), "rgb8"))
        mark_pub.publish(box_marker(header, "zebra_detections", ((d, _marker_colour(d)) for d in dets)))
        self.stats["images"] += 1
        self.acks.part_done(header.stamp, topic)


ZEBRA_COLOUR = ColorRGBA(r=1.0, g=0.25, b=0.0, a=1.0)
OTHER_MARKER_COLOUR = ColorRGBA(r=OTHER_COLOUR[0] / 255, g=OTHER_COLOUR[1] / 255, b=OTHER_COLOUR[2] / 255, a=1.0)


def _marker_colour(det: np.ndarray) -> ColorRGBA:
    """A detection's marker colour: zebras (class 0) as before, any other class as the image overlay draws it."""
    return OTHER_MARKER_COLOUR if len(det) > 5 and int(det[5]) != 0 else ZEBRA_COLOUR


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ros2 run zebra_sim_ros detector``; returns the exit status."""
    return run_node("detector", DetectorNode, argv, help_text("detector", __doc__ or "", DETECTOR_PARAMS))


if __name__ == "__main__":
    raise SystemExit(main())
