"""Label filters and the labeller node's parameters."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from zebra_sim_ros.params import ParamSpec, in_range, one_of, validate

LABELLER_PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec("drones", ["drone_0", "drone_1", "drone_2"], "cameras to label (their namespaces)",
              "a non-empty list of names", lambda v: len(v) > 0 and all(isinstance(x, str) and x for x in v)),
    ParamSpec("hfov_deg", 80.0, "horizontal field of view of the cameras, deg (as the camera nodes)", "20..150",
              in_range(20.0, 150.0)),
    ParamSpec("zebra_detail_distance_m", 35.0, "distance beyond which cameras draw the low-detail zebra, m "
              "(as the renderer)", "0..10000", in_range(0.0, 10000.0)),
    ParamSpec("min_visible_pixels", 10, "keep a zebra only with at least this many visible pixels", "0..100000",
              in_range(0, 100000)),
    ParamSpec("min_visible_fraction", 0.0, "keep a zebra only with at least this visible fraction", "0..1",
              in_range(0.0, 1.0)),
    ParamSpec("min_box_px", 3.0, "keep a zebra only if its tight box is at least this wide and high, px "
              "(the paper's converter: 3)", "0..10000", in_range(0.0, 10000.0)),
    ParamSpec("max_aspect_ratio", 100.0, "keep a zebra only if its tight box's long/short side ratio is at most "
              "this (the paper's converter: 100)", "1..100000", in_range(1.0, 100000.0)),
    ParamSpec("keypoint_depth_tolerance_m", 0.35, "a keypoint is occluded when the depth image is nearer than it "
              "by more than this times the zebra's scale, m", "0..10", in_range(0.0, 10.0)),
    ParamSpec("sync_window", 20, "frames kept while waiting for a stamp's missing inputs", "1..1000",
              in_range(1, 1000)),
    ParamSpec("ack_name", "", "if set, acknowledge a step on /zebra_sim/frame_done under this name once every drone "
              "of it is labelled (for the placer's lockstep)", "a name or empty", lambda v: isinstance(v, str)),
    ParamSpec("qos_reliability", "reliable", "QoS reliability of subscriptions and outputs", "reliable or best_effort",
              one_of("reliable", "best_effort")),
    ParamSpec("qos_depth", 10, "history depth", "1..1000", in_range(1, 1000)),
)


@dataclass(frozen=True)
class LabelFilters:
    """Which labelled zebras are kept for training (all are reported, each with ``kept`` and a reason)."""

    min_visible_pixels: int = 10
    min_visible_fraction: float = 0.0
    min_box_px: float = 3.0
    max_aspect_ratio: float = 100.0
    keypoint_depth_tolerance_m: float = 0.35

    def to_dict(self) -> dict[str, float]:
        """JSON-ready."""
        return dict(self.__dict__)


@dataclass(frozen=True)
class LabellerConfig:
    """Validated labeller node parameters."""

    drones: tuple[str, ...] = ("drone_0", "drone_1", "drone_2")
    hfov_deg: float = 80.0
    zebra_detail_distance_m: float = 35.0
    min_visible_pixels: int = 10
    min_visible_fraction: float = 0.0
    min_box_px: float = 3.0
    max_aspect_ratio: float = 100.0
    keypoint_depth_tolerance_m: float = 0.35
    sync_window: int = 20
    ack_name: str = ""
    qos_reliability: str = "reliable"
    qos_depth: int = 10

    @classmethod
    def from_params(cls, values: dict[str, Any]) -> LabellerConfig:
        """Validate raw parameter values."""
        v = validate(LABELLER_PARAMS, values)
        v["drones"] = tuple(v["drones"])
        return cls(**v)

    def filters(self) -> LabelFilters:
        """The filters part."""
        return LabelFilters(self.min_visible_pixels, self.min_visible_fraction, self.min_box_px,
                            self.max_aspect_ratio, self.keypoint_depth_tolerance_m)
