"""The detector node's parameters."""

from __future__ import annotations

import math
from dataclasses import dataclass

from zebra_sim_ros.detection.metrics import MAX_DETECTIONS
from zebra_sim_ros.params import (
    ParamSpec,
    StageConfig,
    image_reliability_param,
    names_list,
    param,
    reliability_param,
)

NATIVE = -1  # as imgsz: each batch at its frames' own resolution (predict.native_size)
STRIDE = 32  # the largest stride of the model: input sides must be multiples of it
MIN_IMGSZ, MAX_IMGSZ = 64, 4096
AMP_MODES = ("auto", "fp16", "bf16", "off")  # the detector's ``amp`` and train's ``--amp`` (checkpoint.amp_dtype)
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


@dataclass(frozen=True)
class DetectorConfig(StageConfig):
    """Validated detector parameters, each declared here once; ``conf``, ``iou``, ``imgsz`` and ``scale`` may
    change while the node runs."""

    image_topics: tuple[str, ...] = param(
        ("drone_0/image_raw", "drone_1/image_raw", "drone_2/image_raw"),
        "sensor_msgs/Image topics to detect on; outputs go beside each (…/detections)",
        allowed="a non-empty list of topic names", check=names_list)
    weights: str = param("", "checkpoint file (empty: the shipped weights)", allowed="a path or empty")
    conf: float = param(0.25, "confidence threshold", lo=0.0, hi=1.0, runtime=True)
    iou: float = param(0.7, "NMS IoU threshold", lo=0.0, hi=1.0, runtime=True)
    imgsz: int = param(
        0, "inference size for every frame (0: the checkpoint's rule, each frame at the scale the checkpoint "
        "serves at, config.imgsz over its training frames' long side; -1: each frame's long side, rounded up to a "
        f"multiple of {STRIDE})", "px", lo=NATIVE, hi=MAX_IMGSZ,
        allowed=f"{NATIVE}, 0 or a multiple of {STRIDE} in {MIN_IMGSZ}..{MAX_IMGSZ}",
        check=lambda v: v == 0 or imgsz_ok(v, native=True), runtime=True)
    scale: float = param(
        0.0, "if set, inference size as a multiple of each batch's long side (rounded up to a multiple of "
        f"{STRIDE}; overrides imgsz; 0: off, the checkpoint's rule)", lo=0.0, hi=SCALE_RANGE[1],
        allowed="0 (off) or {:g}..{:g}".format(*SCALE_RANGE), check=lambda v: v == 0 or v >= SCALE_RANGE[0],
        runtime=True)
    verifier: str = param(
        "", "a second look at the larger zebra boxes (the shipped verifier's: 24 px and 3.75% of the image's long "
        "side or more, 48 px on a 1280x720 frame): each scores conf x "
        "p(zebra) of a crop around it, and those now under conf are dropped (empty: off; shipped: the package's "
        "verifier, trained on generated crops only; or a verifier checkpoint)", allowed="empty, shipped or a path")
    device: str = param("auto", "auto, cpu, cuda or cuda:N", allowed="auto, cpu, cuda, cuda:N",
                        check=lambda v: v in ("auto", "cpu") or v.startswith("cuda"))
    amp: str = param(
        "off", "the network's features in mixed precision, the boxes in float32 (off: float32; bf16: bfloat16; "
        "fp16: float16, CUDA only; auto: float16 on CUDA, bfloat16 on a CPU with AVX512-BF16 or AMX, else "
        "float32). On such a CPU bf16 served the shipped nano 1.7x faster at the same mAP50 (BENCHMARKS.md)",
        allowed=", ".join(AMP_MODES), check=lambda v: v in AMP_MODES)
    max_det: int = param(MAX_DETECTIONS, "most detections per image", lo=1, hi=10000)
    batch_window_s: float = param(0.05, "frames arriving within this of each other are detected as one batch",
                                  "s", lo=0.001, hi=10.0)
    publish_image: bool = param(True, "publish the annotated image on …/detections/image")
    ack_name: str = param("", "if set, acknowledge each detected image on zebra_sim/frame_done as <ack_name> "
                          "(for the placer's lockstep)", allowed="a name or empty")
    qos_reliability: str = reliability_param("QoS reliability of the outputs")
    image_reliability: str = image_reliability_param()
    qos_depth: int = param(5, "history depth", lo=1, hi=1000)


DETECTOR_PARAMS: tuple[ParamSpec, ...] = DetectorConfig.specs()


def output_base(image_topic: str) -> str:
    """Where a topic's outputs go: ``drone_0/image_raw`` -> ``drone_0/detections`` (absolute names stay
    absolute: ``/drone_0/image_raw`` -> ``/drone_0/detections``; a name without a parent: ``detections``)."""
    topic = image_topic.rstrip("/")
    if "/" not in topic.lstrip("/"):
        return "/detections" if topic.startswith("/") else "detections"
    return f"{topic.rsplit('/', 1)[0]}/detections"
