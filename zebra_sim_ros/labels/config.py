"""Label filters and the labeller node's parameters, each declared once."""

from __future__ import annotations

from dataclasses import dataclass, fields

from zebra_sim_ros.params import (
    ParamSpec,
    StageConfig,
    diagnostics_param,
    image_reliability_param,
    names_list,
    param,
    reliability_param,
    same_as,
)
from zebra_sim_ros.zebra.lod import DETAIL_DISTANCE_M


@dataclass(frozen=True)
class LabelFilters:
    """Which labelled zebras are kept for training (all are reported, each with ``kept`` and a reason).

    The defaults here are the labeller node's parameters too (its config declares the same fields with
    :func:`~zebra_sim_ros.params.same_as`).
    """

    min_visible_pixels: int = param(10, "keep a zebra only with at least this many visible pixels", lo=0, hi=100000)
    min_visible_fraction: float = param(0.0, "keep a zebra only with at least this visible fraction", lo=0.0, hi=1.0)
    min_box_px: float = param(3.0, "keep a zebra only if its tight box is at least this wide and high (the paper's "
                              "converter: 3)", "px", lo=0.0, hi=10000.0)
    max_aspect_ratio: float = param(100.0, "keep a zebra only if its tight box's long/short side ratio is at most "
                                    "this (the paper's converter: 100)", lo=1.0, hi=100000.0)
    keypoint_depth_tolerance_m: float = param(0.35, "a keypoint is occluded when the depth image is nearer than it "
                                              "by more than this times the zebra's scale", "m", lo=0.0, hi=10.0)

    def to_dict(self) -> dict[str, float]:
        """JSON-ready."""
        return dict(self.__dict__)


@dataclass(frozen=True)
class LabellerConfig(StageConfig):
    """Validated labeller node parameters (the cameras' intrinsics come with each frame's CameraInfo)."""

    drones: tuple[str, ...] = param(("drone_0", "drone_1", "drone_2"), "cameras to label (their namespaces)",
                                    allowed="a non-empty list of names", check=names_list)
    zebra_detail_distance_m: float = param(DETAIL_DISTANCE_M, "distance beyond which cameras draw the low-detail "
                                           "zebra (as the renderer)", "m", lo=0.0, hi=10000.0)
    min_visible_pixels: int = same_as(LabelFilters, "min_visible_pixels")
    min_visible_fraction: float = same_as(LabelFilters, "min_visible_fraction")
    min_box_px: float = same_as(LabelFilters, "min_box_px")
    max_aspect_ratio: float = same_as(LabelFilters, "max_aspect_ratio")
    keypoint_depth_tolerance_m: float = same_as(LabelFilters, "keypoint_depth_tolerance_m")
    sync_window: int = param(20, "frames kept while waiting for a stamp's missing inputs", lo=1, hi=1000)
    ack_name: str = param("", "if set, acknowledge a step on zebra_sim/frame_done under this name once every drone "
                          "of it is labelled (for the placer's lockstep)", allowed="a name or empty")
    qos_reliability: str = reliability_param("QoS reliability of the outputs (the scene is subscribed reliable)")
    image_reliability: str = image_reliability_param()
    qos_depth: int = param(10, "history depth", lo=1, hi=1000)
    diagnostics_period_s: float = diagnostics_param()

    def filters(self) -> LabelFilters:
        """The filters part."""
        return LabelFilters(**{f.name: getattr(self, f.name) for f in fields(LabelFilters)})


LABELLER_PARAMS: tuple[ParamSpec, ...] = LabellerConfig.specs()
