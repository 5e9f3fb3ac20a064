"""The detector node's parameters."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from zebra_sim_ros.params import ParamSpec, in_range, one_of, validate

NATIVE = -1  # as imgsz: each batch at its frames' own resolution (predict.native_size)
STRIDE = 32  # the largest stride of the model: input sides must be multiples of it
MIN_IMGSZ, MAX_IMGSZ = 64, 4096
SCALE_RANGE = (0.25, 4.0)  # of the detector's ``scale`` (and up's --detect-scale)


def clamp_size(size: int) -> int:
    """``size`` within the model's 64..4096."""
    return min(max(size, MIN_IMGSZ), MAX_IMGSZ)


def scaled_size(long_side: int, scale: float = 1.0) -> int:
    """The inference size for frames whose longest side is ``long_side``: times ``scale``, rounded up to a
    multiple of :data:`STRIDE`, within 64..4096. The product is rounded to 1e-6 strides first, so that a scale
    such as 1.7 (not exact in binary) gives 1088 for 640, not 1120."""
    return clamp_size(math.ceil(round(long_side * scale / STRIDE, 6)) * STRIDE)


def imgsz_ok(value: object, native: bool = False) -> bool:
    """An inference or training size: a multiple of 32 (the largest stride) in 64..4096, or, where ``native``
    is allowed, :data:`NATIVE`."""
    return isinstance(value, int) and not isinstance(value, bool) and (
        (native and value == NATIVE) or (MIN_IMGSZ <= value <= MAX_IMGSZ and value % STRIDE == 0))


DETECTOR_PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec("image_topics", ["/drone_0/image_raw", "/drone_1/image_raw", "/drone_2/image_raw"],
              "sensor_msgs/Image topics to detect on; outputs go beside each (…/detections)",
              "a non-empty list of topic names", lambda v: len(v) > 0 and all(isinstance(x, str) and x for x in v)),
    ParamSpec("weights", "", "checkpoint file (empty: the shipped weights)", "a path or empty",
              lambda v: isinstance(v, str)),
    ParamSpec("conf", 0.25, "confidence threshold", "0..1", in_range(0.0, 1.0)),
    ParamSpec("iou", 0.7, "NMS IoU threshold", "0..1", in_range(0.0, 1.0)),
    ParamSpec("imgsz", 0, "inference size, px, for every frame (0: the checkpoint's rule, each frame at the scale "
              "the checkpoint serves at, config.imgsz over its training frames' long side; -1: each frame's long "
              "side, rounded up to a multiple of 32)", "-1, 0 or a multiple of 32 in 64..4096",
              lambda v: v == 0 or imgsz_ok(v, native=True)),
    ParamSpec("scale", 0.0, "if set, inference size as a multiple of each batch's long side (rounded up to a multiple "
              "of 32; overrides imgsz; 0: off, the checkpoint's rule)", "0 (off) or 0.25..4",
              lambda v: in_range(0.0, 0.0)(v) or in_range(*SCALE_RANGE)(v)),
    ParamSpec("device", "auto", "auto, cpu, cuda or cuda:N", "auto, cpu, cuda, cuda:N",
              lambda v: isinstance(v, str) and (v in ("auto", "cpu") or v.startswith("cuda"))),
    ParamSpec("max_det", 300, "most detections per image", "1..10000", in_range(1, 10000)),
    ParamSpec("batch_window_s", 0.05, "frames arriving within this of each other are detected as one batch, s",
              "0.001..10", in_range(0.001, 10.0)),
    ParamSpec("publish_image", True, "publish the annotated image on …/detections/image", "true or false",
              lambda v: isinstance(v, bool)),
    ParamSpec("ack_name", "", "if set, acknowledge each detected image on /zebra_sim/frame_done as "
              "<ack_name> (for the placer's lockstep)", "a name or empty", lambda v: isinstance(v, str)),
    ParamSpec("qos_reliability", "reliable", "QoS reliability of subscriptions and outputs", "reliable or best_effort",
              one_of("reliable", "best_effort")),
    ParamSpec("qos_depth", 5, "history depth", "1..1000", in_range(1, 1000)),
)


@dataclass(frozen=True)
class DetectorConfig:
    """Validated detector parameters."""

    image_topics: tuple[str, ...] = ("/drone_0/image_raw", "/drone_1/image_raw", "/drone_2/image_raw")
    weights: str = ""
    conf: float = 0.25
    iou: float = 0.7
    imgsz: int = 0
    scale: float = 0.0
    device: str = "auto"
    max_det: int = 300
    batch_window_s: float = 0.05
    publish_image: bool = True
    ack_name: str = ""
    qos_reliability: str = "reliable"
    qos_depth: int = 5

    @classmethod
    def from_params(cls, values: dict[str, Any]) -> DetectorConfig:
        """Validate raw parameter values."""
        v = validate(DETECTOR_PARAMS, values)
        v["image_topics"] = tuple(v["image_topics"])
        return cls(**v)


def output_base(image_topic: str) -> str:
    """Where a topic's outputs go: ``/drone_0/image_raw`` -> ``/drone_0/detections``."""
    parent = image_topic.rstrip("/").rsplit("/", 1)[0]
    return f"{parent}/detections" if parent else "/detections"
