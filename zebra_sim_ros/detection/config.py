"""The detector's settings: the node's parameters, the model's sizes, and the training augmentation's strengths
(:class:`Augment`). Nothing here imports torch, so the command line builds its options without it."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

from zebra_sim_ros.detection.metrics import MAX_DETECTIONS
from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.geometry.census import (
    CENSUS_ACROSS_M,
    CENSUS_ALONG_M,
    CENSUS_GATE,
    CENSUS_SEPARATION_M,
    Census,
    FloatArray,
    join_views,
)
from zebra_sim_ros.geometry.locate import CENTRE_HEIGHT_M, CORE, DEPTH_WINDOW_M, GROUND_MAX_RANGE_M
from zebra_sim_ros.params import (
    RELATIVE_NAME,
    ParamSpec,
    StageConfig,
    diagnostics_param,
    image_reliability_param,
    names_list,
    param,
    reliability_param,
    same_as,
)
from zebra_sim_ros.placement.config import CAMERA_POSE, FIX_TOPIC, NAV_POSE, PLACER_CAMERA_TOPICS, PLACER_TOPICS

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
        "sensor_msgs/Image topics to detect on (a name ending in /compressed: sensor_msgs/CompressedImage, jpeg or "
        "png); outputs go beside each (…/detections; image_raw/compressed's where image_raw's would)",
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
    diagnostics_period_s: float = diagnostics_param()

    def check(self) -> None:
        """Two image topics may not publish to the same outputs (``x/image_raw`` and ``x/image_raw/compressed``)."""
        for topic in self.image_topics:
            if topic.endswith("/"):
                raise ParameterError("image_topics", list(self.image_topics), f"topic names without a trailing / "
                                     f"({topic!r})")
        distinct_outputs(self.image_topics)



DETECTOR_PARAMS: tuple[ParamSpec, ...] = DetectorConfig.specs()


@dataclass(frozen=True)
class ScorerConfig(StageConfig):
    """Validated scorer node parameters: which cameras' labels and detections it scores, over how many frames."""

    drones: tuple[str, ...] = param(("drone_0", "drone_1", "drone_2"), "cameras to score (their namespaces: "
                                    "<drone>/labels against <drone>/<detections>)",
                                    allowed="a non-empty list of names", check=names_list)
    detections: str = param("detections", "the detection topic beside each camera's labels (a Detection2DArray, "
                            "e.g. another detector's remapped output)",
                            allowed="a topic name relative to the drone (letters, digits, _ and /)",
                            check=lambda v: bool(RELATIVE_NAME.fullmatch(v)))
    window: int = param(300, "score the last this many frames of each camera (a report over 3 cameras' 300 frames "
                        "takes about 80 ms, over 2000 about 0.6 s: BENCHMARKS.md)", lo=1, hi=2000, runtime=True)
    count_conf: float = same_as(DetectorConfig, "conf", help="count the zebras with the detections at this confidence "
                                "or above (the detector's default threshold; it publishes none under its own conf, so "
                                "a lower count_conf counts at that)")
    qos_reliability: str = reliability_param("QoS reliability of the subscriptions (reliable matches the graph's "
                                             "publishers and loses nothing; best_effort matches any)")
    qos_depth: int = param(10, "history depth", lo=1, hi=1000)
    diagnostics_period_s: float = same_as(DetectorConfig, "diagnostics_period_s", lo=0.05,
                                          help="how often the scores (and the node's health) are published on "
                                          "/diagnostics (diagnostic_msgs/DiagnosticArray)")


    def check(self) -> None:
        """Each camera once (a camera named twice would count every frame twice)."""
        if len({d.strip("/") for d in self.drones}) != len(self.drones):
            raise ParameterError("drones", list(self.drones), "each camera once")


SCORER_PARAMS: tuple[ParamSpec, ...] = ScorerConfig.specs()


PLACE_BY = ("depth", "ground")  # how the locator finds a box's distance along its ray


@dataclass(frozen=True)
class LocatorConfig(StageConfig):
    """Validated locator node parameters: which cameras' detections it places on the map, and how."""

    drones: tuple[str, ...] = same_as(ScorerConfig, "drones", help="cameras whose detections to place (their "
                                      "namespaces: <drone>/<detections>, depth, camera_info and <pose>)")
    detections: str = same_as(ScorerConfig, "detections")
    output: str = param("detections/located", "the placed detections' topic under each camera (a Detection3DArray "
                        "in map)", allowed="a topic name relative to the drone (letters, digits, _ and /)",
                        check=lambda v: bool(RELATIVE_NAME.fullmatch(v)))
    pose: str = param(CAMERA_POSE, "each camera's pose topic under it (geometry_msgs/PoseStamped of its optical frame "
                      f"in map): {CAMERA_POSE}, the placer's exact one, or {NAV_POSE}, at the drone's GNSS fix and "
                      "turned by its attitude error (the placer's fix_* and nav_* noise), as a real flight's "
                      "navigation places its camera",
                      allowed="a topic name relative to the drone (letters, digits, _ and /)",
                      check=lambda v: bool(RELATIVE_NAME.fullmatch(v)))
    place_by: str = param("depth", "how a box's distance along its ray is found: depth, from the camera's depth "
                          "image (<drone>/depth: a simulated or RGB-D camera); ground, where the ray through the "
                          "box's centre meets the level plane centre_height above ground_z (a drone's colour camera "
                          "over flat ground: no depth subscribed)", choices=PLACE_BY)
    ground_z: float = param(0.0, "place_by ground: the ground's height in map (the site's; map's z is the height "
                            "above the datum's origin_altitude_m)", "m", lo=-10000.0, hi=10000.0, runtime=True)
    centre_height: float = param(CENTRE_HEIGHT_M, "place_by ground: an animal's body centre above the ground (its "
                                 "box's centre is taken to be there)", "m", lo=0.0, hi=10.0, runtime=True)
    ground_max_range: float = param(GROUND_MAX_RANGE_M, "place_by ground: a box whose ray meets the plane farther "
                                    "than this from the camera is unplaced (near the horizon a pixel is metres of "
                                    "ground)", "m", lo=1.0, hi=100000.0, runtime=True)
    core: float = param(CORE, "share of each box's width and height, about its centre, whose depths place it (1: "
                        "the whole box)", lo=0.05, hi=1.0, runtime=True)
    depth_window: float = param(DEPTH_WINDOW_M, "a box's depth is the median of the densest span of its depths this "
                                "deep (the animal, not the ground behind it or another animal in front); 0: the "
                                "median of all", "m", lo=0.0, hi=100.0, runtime=True)
    census: bool = param(True, "also join the cameras' detections of each stamp into animals, each counted once "
                         "(published on census_output once every camera's frame of the stamp is placed)")
    census_output: str = param("census/animals", "the census's topic (a Detection3DArray in map: one detection per "
                               "animal)", allowed="a topic name relative to the node's namespace (letters, digits, _ "
                               "and /), outside the cameras' namespaces, that neither ends output or the placer's "
                               "topics nor is ended by one", check=lambda v: bool(RELATIVE_NAME.fullmatch(v)))
    census_along: float = param(CENSUS_ALONG_M, "how far a placed detection is taken to be off along its camera's "
                                "ray, seen from above (one standard deviation: its depth's error)", "m", lo=0.01,
                                hi=100.0, runtime=True)
    census_across: float = param(CENSUS_ACROSS_M, "how far a placed detection is taken to be off across its camera's "
                                 "ray (one standard deviation: its box's error)", "m", lo=0.01, hi=100.0, runtime=True)
    census_gate: float = param(CENSUS_GATE, "join two cameras' detections into one animal only when they are less "
                               "than this many standard deviations apart", lo=0.1, hi=20.0, runtime=True)
    census_separation: float = param(CENSUS_SEPARATION_M, "one camera's detections closer than this on the ground "
                                     "are one animal boxed twice (the higher score stands for them; 0: never)", "m",
                                     lo=0.0, hi=100.0, runtime=True)
    sync_window: int = param(20, "stamps kept while waiting for their missing inputs (all cameras' together)",
                             lo=1, hi=1000)
    pose_max_gap_s: float = param(0.0, "0: each image's pose has the image's stamp (the placer's, one per image); "
                                  "more: poses come at their own rate (a drone's odometry), and an image's is "
                                  "interpolated between the poses about its stamp where they are at most this far "
                                  "apart", "s", lo=0.0, hi=10.0)
    pose_transient_local: bool = param(False, "subscribe the poses (pose) transient local: a locator that matches its "
                                       "publisher late still gets the last qos_depth poses (the publisher must be "
                                       "transient local too, as the placer's is, or no pose arrives; zebra-sim up "
                                       "sets it)")
    qos_reliability: str = reliability_param("QoS reliability of the detections' and poses' subscriptions and the "
                                             "outputs (placed detections, census, markers)")
    image_reliability: str = image_reliability_param()
    qos_depth: int = param(10, "history depth", lo=1, hi=1000)
    diagnostics_period_s: float = diagnostics_param()

    def census_join(self, points: Sequence[FloatArray], origins: Sequence[FloatArray],
                    scores: Sequence[FloatArray]) -> Census:
        """One stamp's placed detections of one class joined across the cameras by this rule (:data:`CENSUS_RULE`;
        :func:`~zebra_sim_ros.geometry.census.join_views`): the locator's census and ``bag census``' recount."""
        return join_views(points, origins, self.census_along, self.census_across, self.census_gate,
                          self.census_separation, scores)

    @property
    def pose_max_gap_ns(self) -> int:
        """``pose_max_gap_s`` in nanoseconds, the stamps' unit (0: each image's pose has its stamp)."""
        return int(round(self.pose_max_gap_s * 1e9))

    @property
    def inputs(self) -> tuple[str, ...]:
        """The topics it reads under each camera: its detections, depth (with ``place_by`` depth), camera_info and
        camera pose (the node subscribes these, up waits for them)."""
        return self.detections, *(("depth",) if self.place_by == "depth" else ()), "camera_info", self.pose

    def check(self) -> None:
        """Each camera once; an output that is not an input; the census outside the cameras' namespaces."""
        if len({d.strip("/") for d in self.drones}) != len(self.drones):
            raise ParameterError("drones", list(self.drones), "each camera once")
        others = (self.detections, "depth", "camera_info", "image_raw", FIX_TOPIC)
        if self.pose in others:  # a topic of another type: no frame would ever be complete
            raise ParameterError("pose", self.pose, f"a pose topic, not one of the camera's other topics "
                                 f"{list(others)}")
        inputs = tuple(dict.fromkeys((*self.inputs, "image_raw", *PLACER_CAMERA_TOPICS)))
        if self.output in inputs:
            raise ParameterError("output", self.output, f"another topic than the camera's inputs and poses "
                                 f"{list(inputs)}")
        out = self.census_output.strip("/")
        if any(out == ns or out.startswith(ns + "/") for ns in (d.strip("/") for d in self.drones)):
            raise ParameterError("census_output", self.census_output, "a topic outside the cameras' namespaces")
        for other, what in ((self.output.strip("/"), "the placed detections' output"),
                            *((t, "the placer's topic") for t in PLACER_TOPICS)):
            if out == other or out.endswith("/" + other) or other.endswith("/" + out):  # one read as the other
                raise ParameterError("census_output", self.census_output, f"a name that neither ends {what} "
                                     f"{other!r} nor is ended by it")


LOCATOR_PARAMS: tuple[ParamSpec, ...] = LocatorConfig.specs()
CENSUS_RULE = ("census_along", "census_across", "census_gate", "census_separation")  # how the census joins views
# what a bag census reads back as the locator read and wrote it: its topics, and how it matched poses to images
CENSUS_READS = ("output", "census_output", "pose", "pose_max_gap_s")


def distinct_outputs(image_topics: Sequence[str], resolve: Callable[[str], str] = lambda t: t) -> None:
    """Refuse, naming ``image_topics``, two topics whose outputs (:func:`output_base`, then ``resolve``: as written
    in the config's check, as the node resolves them at start) are the same."""
    seen: dict[str, str] = {}
    for topic in image_topics:
        base = resolve(output_base(topic))
        if base in seen:
            raise ParameterError("image_topics", list(image_topics), f"topics with outputs of their own: "
                                 f"{seen[base]!r} and {topic!r} both publish {base}")
        seen[base] = topic


def is_compressed(image_topic: str) -> bool:
    """Whether an image topic carries sensor_msgs/CompressedImage: ``image_transport``'s name for it ends in
    ``/compressed``."""
    return image_topic.rstrip("/").endswith("/compressed")


def output_base(image_topic: str) -> str:
    """Where a topic's outputs go: ``drone_0/image_raw`` -> ``drone_0/detections`` (absolute names stay
    absolute: ``/drone_0/image_raw`` -> ``/drone_0/detections``; a name without a parent: ``detections``); a
    compressed topic's outputs go where its image's would (``drone_0/image_raw/compressed`` ->
    ``drone_0/detections``)."""
    topic = image_topic.rstrip("/")
    if is_compressed(topic):
        topic = topic[: -len("/compressed")] or "/"
    if "/" not in topic.lstrip("/"):
        return "/detections" if topic.startswith("/") else "detections"
    return f"{topic.rsplit('/', 1)[0]}/detections"


def _aug(default: float, text: str, lo: float = 0.0, hi: float = 1.0, off: float | None = 0.0) -> Any:
    """An :class:`Augment` field: its default, help, allowed range and the value that switches it off (None: a
    setting that switches nothing off, kept at its default by :meth:`Augment.none`)."""
    return field(default=default, metadata={"help": text, "lo": lo, "hi": hi, "off": off})


@dataclass(frozen=True)
class Augment:
    """Augmentation strengths: the geometry and HSV of YOLOv5/8's defaults, and what breaks the shortcuts a
    detector learns from rendered frames (a clean sensor, one camera's colours, small far zebras only). Each field
    is a ``zebra-sim train`` option (``--aug-<name>``); :meth:`none` switches all off."""

    mosaic: float = _aug(1.0, "probability of a mosaic of four images")
    scale: float = _aug(0.5, "random scale 1 +- this", hi=10.0)
    translate: float = _aug(0.1, "random translation, share of the image side")
    fliplr: float = _aug(0.5, "probability of a horizontal flip")
    hsv_h: float = _aug(0.015, "hue jitter, share of the hue circle")
    hsv_s: float = _aug(0.7, "saturation gain 1 +- this", hi=10.0)
    hsv_v: float = _aug(0.4, "brightness gain 1 +- this", hi=10.0)
    zoom: float = _aug(0.3, "probability that a sample is a crop around one labelled zebra, enlarged (--aug-zoom-max) "
                            "until it spans 15-80%% of the side, often cut by the edges: large zebras from far ones")
    grayscale: float = _aug(0.05, "probability of a grey image")
    gamma: float = _aug(0.25, "gamma exp(U(-this, this)) on the whole image")
    white_balance: float = _aug(0.12, "per-channel gain exp(U(-this, this)): another camera's colour")
    blur: float = _aug(0.2, "probability of a Gaussian blur of sigma 0.4-1.6 px (defocus)")
    noise: float = _aug(0.25, "probability of Gaussian sensor noise of 2-10 levels")
    jpeg: float = _aug(0.3, "probability of a JPEG round trip at quality 30-90")
    cutout: float = _aug(0.15, "probability of 1-3 grey rectangles of 5-25%% of the side; a box hidden over 60%% "
                               "is dropped")
    background: float = _aug(0.0, "probability that a zoom crop (--aug-zoom) is centred on an animal of another "
                                  "species (from the set's annotations/, as generate writes them) or else on a random "
                                  "point, not on a zebra, enlarged alike: hard negatives at the size of large zebras")
    zoom_max: float = _aug(4.0, "largest enlargement of a zoom crop (--aug-zoom), 1-16: more makes larger, "
                                "blurrier animals from far ones", lo=1.0, hi=16.0, off=None)
    zoom_crop: float = _aug(0.0, "with --crop: probability that a zoom crop sizes its animal to 15-80%% of the "
                                 "--crop window the model sees (and centres the window on it) rather than of the "
                                 "--imgsz sample, where the enlargement cap keeps far animals small in the window")

    @classmethod
    def none(cls) -> Augment:
        """Letterbox only: every augmentation off."""
        return cls(**{f.name: f.metadata["off"] for f in fields(cls) if f.metadata["off"] is not None})

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> Augment:
        """From a checkpoint's record (unknown or missing names: the defaults)."""
        names = {f.name for f in fields(cls)}
        return cls(**{k: float(v) for k, v in (d or {}).items() if k in names})

    def check(self) -> None:
        """Raise :class:`ParameterError` naming the first value out of range."""
        for f in fields(self):
            v = getattr(self, f.name)
            lo, hi = f.metadata["lo"], f.metadata["hi"]
            if not lo <= v <= hi:
                raise ParameterError(f"--aug-{f.name.replace('_', '-')}", v, f"{lo:g}..{hi:g}")


MAX_MEMBERS = 8  # each member costs one network's time on every judged crop: 8 is already 8x the served cost
SPLITS = ("crop", "frame")  # how train-verifier holds crops out: a share of the crops, or of the frames


@dataclass(frozen=True)
class VerifierConfig:
    """What the verifier sees: ``crop`` px squares around boxes of at least ``min_side`` px, ``context`` times the
    box's long side.

    ``min_side_fraction``, ``contexts``, ``mirror``, ``power`` and ``power_from`` are for serving only. A box is
    judged when its long side is also at least ``min_side_fraction`` of the image's long side (0.0375: 24 px on a
    640 px photo, 48 px on a 1280x720 frame); training crops animals by ``min_side`` alone. Its p(zebra) is the mean
    over one crop at each of ``contexts`` (empty: ``context`` alone) and, with ``mirror``, each crop's mirror image
    too. A judged box's score s becomes s·p, or s·p^``power`` where its long side is ``power_from`` or more of the
    image's long side (the verifier weighed more where a box fills much of its image, as an animal does a
    photograph, than on a drone frame's small animals; power 1: s·p for all). ``members`` > 1 makes
    the verifier an ensemble of that many networks of this shape, trained apart: p(zebra) of a crop is the mean of
    theirs (:func:`~zebra_sim_ros.detection.verify.ensemble_verifiers`)."""

    crop: int = 96
    context: float = 1.2
    min_side: float = 24.0
    widths: tuple[int, ...] = (32, 64, 96, 128, 192)
    min_side_fraction: float = 0.0
    contexts: tuple[float, ...] = ()
    mirror: bool = False
    members: int = 1
    power: float = 1.0
    power_from: float = 0.0

    def check(self) -> None:
        if not 32 <= self.crop <= 256:
            raise ParameterError("verifier crop", self.crop, "32..256 px")
        if not 1.0 <= self.context <= 3.0:
            raise ParameterError("verifier context", self.context, "1.0..3.0 (times the box's long side)")
        if not self.min_side >= 1.0:
            raise ParameterError("verifier min_side", self.min_side, ">= 1 px")
        if not 0.0 <= self.min_side_fraction <= 0.5:
            raise ParameterError("verifier min_side_fraction", self.min_side_fraction,
                                 "0..0.5 (of the image's long side; 0: min_side alone)")
        if not self.widths or any(w < 1 for w in self.widths):
            raise ParameterError("verifier widths", self.widths, "a non-empty list of channel counts >= 1")
        if any(not 1.0 <= c <= 3.0 for c in self.contexts) or len(set(self.contexts)) != len(self.contexts):
            raise ParameterError("verifier contexts", self.contexts,
                                 "distinct values in 1.0..3.0 (times the box's long side; empty: context alone)")
        if not 1 <= self.members <= MAX_MEMBERS:
            raise ParameterError("verifier members", self.members, f"1..{MAX_MEMBERS} (networks averaged)")
        if not 1.0 <= self.power <= 10.0:  # also refuses NaN
            raise ParameterError("verifier power", self.power, "1..10 (the power of p(zebra) in a large box's score)")
        if not 0.0 <= self.power_from <= 1.0:
            raise ParameterError("verifier power_from", self.power_from,
                                 "0..1 (of the image's long side: the boxes scored s·p^power; 0: every judged box)")

    def views(self) -> list[tuple[float, bool]]:
        """The (context, mirrored) crops whose p(zebra) a served box averages."""
        return [(c, m) for c in self.contexts or (self.context,) for m in ((False, True) if self.mirror else (False,))]

    def to_dict(self) -> dict[str, Any]:
        """The config as a checkpoint stores it (lists, not tuples); :meth:`from_dict` reads it back."""
        return {**asdict(self), "widths": list(self.widths), "contexts": list(self.contexts)}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> VerifierConfig:
        cfg = cls(int(d["crop"]), float(d["context"]), float(d["min_side"]), tuple(int(w) for w in d["widths"]),
                  float(d.get("min_side_fraction", 0.0)),  # checkpoints before the fraction judged by min_side alone
                  tuple(float(c) for c in d.get("contexts", ())), bool(d.get("mirror", False)),  # and by one crop
                  int(d.get("members", 1)), float(d.get("power", 1.0)), float(d.get("power_from", 0.0)))  # s·p
        cfg.check()
        return cfg


@dataclass(frozen=True)
class TrainVerifierConfig:
    """``zebra-sim train-verifier``: crops of the generated datasets in ``data`` (folders with ``annotations/``)."""

    data: tuple[str, ...]
    out: str
    epochs: int = 10
    batch: int = 128
    lr: float = 2e-3
    seed: int = 25
    val_fraction: float = 0.1
    # how the held-out crops are drawn: "crop" (a random share of the crops: an animal's two jittered crops can fall
    # on both sides, so the held-out figures are optimistic) or "frame" (every crop of a random share of the frames)
    split: str = "crop"
    min_visible_pixels: int = 300  # animals with fewer visible pixels are not cropped
    min_visible_fraction: float = 0.3
    background_per_frame: int = 2
    # hard negatives: a detector's boxes on the frames ('shipped' or a checkpoint; '' = none) at mine_imgsz and
    # mine_conf that overlap no zebra become crops of kind "detector's false boxes"
    detector: str = ""
    mine_imgsz: int = 640
    mine_conf: float = 0.1
    # off: the detector's boxes on animals of other species (centre in one or IoU >= 0.1) are not hard negatives
    # either, only those on background are (the animals have crops of their own)
    mine_on_animals: bool = True
    # parts: this many squares per cropped animal of 40-75% of its box's long side, centred in the middle half of
    # the box (a zebra's part is a zebra, another species' part is not); clutter: this many drawn squares per
    # frame (draw_clutter), never a zebra. Both drawn from streams of their own: the other crops stay the same.
    parts_per_animal: int = 0
    clutter_per_frame: int = 0
    model: VerifierConfig = field(default_factory=VerifierConfig)

    def check(self) -> None:
        if not self.data:
            raise ParameterError("--data", list(self.data), "one or more generated dataset folders")
        for d in self.data:
            if not (Path(d) / "annotations").is_dir():
                raise ParameterError("--data", d, "a folder written by zebra-sim generate (with annotations/)")
        for name, value, lo in (("--epochs", self.epochs, 1), ("--batch", self.batch, 2), ("--seed", self.seed, 0),
                                ("--background-per-frame", self.background_per_frame, 0),
                                ("--parts-per-animal", self.parts_per_animal, 0),
                                ("--clutter-per-frame", self.clutter_per_frame, 0)):
            if value < lo:
                raise ParameterError(name, value, f">= {lo}")
        if not 0 < self.lr <= 1:
            raise ParameterError("--lr", self.lr, "in (0, 1]")
        if not 0 < self.val_fraction < 0.5:
            raise ParameterError("--val-fraction", self.val_fraction, "in (0, 0.5)")
        if self.split not in SPLITS:
            raise ParameterError("--split", self.split, " or ".join(SPLITS))
        if not imgsz_ok(self.mine_imgsz):
            raise ParameterError("--mine-imgsz", self.mine_imgsz, "a multiple of 32 in 64..4096")
        if not 0 < self.mine_conf < 1:
            raise ParameterError("--mine-conf", self.mine_conf, "in (0, 1)")
        if self.detector not in ("", "shipped") and not Path(self.detector).is_file():
            raise ParameterError("--detector", self.detector, "empty, shipped or an existing detector checkpoint")
        self.model.check()
        if self.model.members != 1:
            raise ParameterError("verifier members", self.model.members,
                                 "1 to train (members are trained apart; zebra-sim verifier-ensemble joins them)")

    def to_dict(self) -> dict[str, Any]:
        return {**asdict(self), "data": list(self.data), "model": self.model.to_dict()}
