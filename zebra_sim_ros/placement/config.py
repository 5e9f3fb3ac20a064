"""The placer's parameters: one frozen dataclass, validated once.

Defaults are the paper's randomisation (Bonetto & Ahmad 2023, section III-B): rectangles with sides
U(40, 120) m, 2..250 of a pool of 250 zebras, scale U(0.4, 1.0), 90% of frames between 5 and 20 h,
three cameras re-randomised three times per placement, 5..20 m above the zebras, roll U(-10, 10) deg,
``far`` within +-100 m of the pivot with yaw jitter +-30 deg, ``closeby`` within 5 m of the zebras' box with
+-15 deg, pitch = atan2(pivot_z - cam_z, d_xy) + 15 deg.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.params import ParamSpec, in_range, one_of, validate
from zebra_sim_ros.placement.sun import DAY_WINDOWS

_MORPHS = ("plains", "grevy", "foal")


def _nonneg_list(n: int) -> Any:
    return lambda v: len(v) == n and all(isinstance(x, int | float) and x >= 0 for x in v) and sum(v) > 0


PLACER_PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec("seed", 0, "seed of every random draw; recorded in each scene", "0..2^63-1", in_range(0, 2**63 - 1)),
    ParamSpec("world", "savanna", "built-in world preset name, or path to a USD stage", "a preset name or a .usd* path",
              lambda v: isinstance(v, str) and len(v) > 0),
    ParamSpec("terrain_prim", "/World/Terrain", "USD prim path of the terrain mesh (USD worlds only)",
              "an absolute prim path", lambda v: isinstance(v, str) and v.startswith("/")),
    ParamSpec("world_seed", 0, "seed of the procedural world (presets only)", "0..2^31-1", in_range(0, 2**31 - 1)),
    ParamSpec("strategy", "far", "camera strategy: far, closeby, or mixed (each step picks one, 50/50)",
              "far, closeby or mixed", one_of("far", "closeby", "mixed")),
    ParamSpec("pool_size", 250, "zebras preloaded per experiment", "1..1000", in_range(1, 1000)),
    ParamSpec("count_min", 2, "fewest zebras asked for per placement", "1..pool_size", in_range(1, 1000)),
    ParamSpec("count_max", 250, "most zebras asked for per placement", "count_min..pool_size", in_range(1, 1000)),
    ParamSpec("scale_min", 0.4, "smallest zebra scale factor", "0.05..3", in_range(0.05, 3.0)),
    ParamSpec("scale_max", 1.0, "largest zebra scale factor", "scale_min..3", in_range(0.05, 3.0)),
    ParamSpec("rect_min", 40.0, "shortest side of the placement rectangle, m", "1..1000 m", in_range(1.0, 1000.0)),
    ParamSpec("rect_max", 120.0, "longest side of the placement rectangle, m", "rect_min..1000 m",
              in_range(1.0, 1000.0)),
    ParamSpec("morph_weights", [0.6, 0.25, 0.15], "pool share of plains, Grevy's and foals",
              "three non-negative numbers, not all zero", _nonneg_list(3)),
    ParamSpec("clips", ["all"], "animation clips to draw from, or [all]", "clip names of the asset, or [all]",
              lambda v: len(v) > 0 and all(isinstance(x, str) for x in v)),
    ParamSpec("max_attempts", 100, "candidate positions tried per zebra before it is dropped", "1..10000",
              in_range(1, 10000)),
    ParamSpec("max_slope_deg", -1.0, "steepest ground a zebra stands on, deg (-1: the world's own)", "-1 or 0..89",
              lambda v: v == -1.0 or 0.0 <= v <= 89.0),
    ParamSpec("num_cameras", 3, "drones per step", "1..16", in_range(1, 16)),
    ParamSpec("camera_rerolls", 3, "camera and time-of-day draws per placement", "1..100", in_range(1, 100)),
    ParamSpec("camera_height_min", 5.0, "camera height over the mean zebra height, minimum, m", "0.5..500 m",
              in_range(0.5, 500.0)),
    ParamSpec("camera_height_max", 20.0, "camera height over the mean zebra height, maximum, m",
              "camera_height_min..500 m", in_range(0.5, 500.0)),
    ParamSpec("far_radius", 100.0, "far: camera x and y within +- this of the pivot, m", "1..2000 m",
              in_range(1.0, 2000.0)),
    ParamSpec("closeby_margin", 5.0, "closeby: camera x and y within this of the zebras' box, m", "0..500 m",
              in_range(0.0, 500.0)),
    ParamSpec("roll_max_deg", 10.0, "camera roll U(-r, r), deg", "0..45", in_range(0.0, 45.0)),
    ParamSpec("far_yaw_jitter_deg", 30.0, "far: yaw = bearing to pivot + U(-j, j), deg", "0..90", in_range(0.0, 90.0)),
    ParamSpec("closeby_yaw_jitter_deg", 15.0, "closeby: yaw jitter, deg", "0..90", in_range(0.0, 90.0)),
    ParamSpec("pitch_offset_deg", 15.0, "added to the elevation angle of the pivot, deg", "-45..45",
              in_range(-45.0, 45.0)),
    ParamSpec("min_camera_separation", 0.5, "least distance between two cameras, m", "0..100 m", in_range(0.0, 100.0)),
    ParamSpec("min_camera_clearance", 2.0, "least height of a camera above the ground below it, m", "0..100 m",
              in_range(0.0, 100.0)),
    ParamSpec("camera_width", 1280, "image width the cameras render, px (the pivot must be in view)", "16..16384",
              in_range(16, 16384)),
    ParamSpec("camera_height", 720, "image height, px", "16..16384", in_range(16, 16384)),
    ParamSpec("camera_hfov_deg", 80.0, "horizontal field of view, deg", "20..150", in_range(20.0, 150.0)),
    ParamSpec("night_fraction", 0.1, "share of frames outside the day window", "0..1", in_range(0.0, 1.0)),
    ParamSpec("day_window", "sun", "the day window: sun = each frame's sunrise..sunset at latitude_deg (the "
              "paper's 90% of frames in good light); clock = day_start_h..day_end_h literally", "sun or clock",
              one_of(*DAY_WINDOWS)),
    ParamSpec("day_start_h", 5.0, "start of the day window with day_window clock, h", "0..24", in_range(0.0, 24.0)),
    ParamSpec("day_end_h", 20.0, "end of the day window with day_window clock, h", "day_start_h..24",
              in_range(0.0, 24.0)),
    ParamSpec("ground_recolor", 0.0, "share of steps whose terrain colour is randomised (brightness x0.5..x4, "
              "desaturation, tint; domain randomisation for training sets; 0 = every world as authored)", "0..1",
              in_range(0.0, 1.0)),
    ParamSpec("latitude_deg", -2.3, "latitude for the sun's path (Serengeti: -2.3)", "-90..90", in_range(-90.0, 90.0)),
    ParamSpec("mode", "rate", "rate: publish at rate_hz; lockstep: next step when every acker acknowledged",
              "rate or lockstep", one_of("rate", "lockstep")),
    ParamSpec("rate_hz", 1.0, "steps per second (rate mode) and simulated seconds per step = 1/rate_hz",
              "0.001..1000 Hz", in_range(0.001, 1000.0)),
    ParamSpec("lockstep_ack_from", ["drone_0", "drone_1", "drone_2"],
              "names whose acknowledgement on /zebra_sim/frame_done completes a step", "a non-empty list of names",
              lambda v: len(v) > 0 and all(isinstance(x, str) and x for x in v)),
    ParamSpec("lockstep_timeout_s", 30.0, "warn and re-publish when a step is not acknowledged within this, s",
              "0.1..3600 s", in_range(0.1, 3600.0)),
    ParamSpec("wait_for_subscribers", 0, "publish the first step only when each output topic (scene, markers, "
              "camera poses) has at least this many subscribers, e.g. 1 so a recorder misses nothing (0: start at "
              "once)", "0..1000", in_range(0, 1000)),
    ParamSpec("max_steps", 0, "stop after this many steps (0: never)", "0..2^31", in_range(0, 2**31)),
    ParamSpec("start_step", 0, "first step index (to resume or reproduce a step alone)", "0..2^31",
              in_range(0, 2**31)),
    ParamSpec("qos_depth", 10, "history depth of the published topics", "1..1000", in_range(1, 1000)),
    ParamSpec("qos_reliability", "reliable", "QoS reliability of the published topics", "reliable or best_effort",
              one_of("reliable", "best_effort")),
)


@dataclass(frozen=True)
class PlacerConfig:
    """Validated placer parameters (see ``PLACER_PARAMS`` for meaning, unit and range of each)."""

    seed: int = 0
    world: str = "savanna"
    terrain_prim: str = "/World/Terrain"
    world_seed: int = 0
    strategy: str = "far"
    pool_size: int = 250
    count_min: int = 2
    count_max: int = 250
    scale_min: float = 0.4
    scale_max: float = 1.0
    rect_min: float = 40.0
    rect_max: float = 120.0
    morph_weights: tuple[float, float, float] = (0.6, 0.25, 0.15)
    clips: tuple[str, ...] = ("all",)
    max_attempts: int = 100
    max_slope_deg: float = -1.0
    num_cameras: int = 3
    camera_rerolls: int = 3
    camera_height_min: float = 5.0
    camera_height_max: float = 20.0
    far_radius: float = 100.0
    closeby_margin: float = 5.0
    roll_max_deg: float = 10.0
    far_yaw_jitter_deg: float = 30.0
    closeby_yaw_jitter_deg: float = 15.0
    pitch_offset_deg: float = 15.0
    min_camera_separation: float = 0.5
    min_camera_clearance: float = 2.0
    camera_width: int = 1280
    camera_height: int = 720
    camera_hfov_deg: float = 80.0
    night_fraction: float = 0.1
    day_window: str = "sun"
    day_start_h: float = 5.0
    day_end_h: float = 20.0
    ground_recolor: float = 0.0
    latitude_deg: float = -2.3
    mode: str = "rate"
    rate_hz: float = 1.0
    lockstep_ack_from: tuple[str, ...] = ("drone_0", "drone_1", "drone_2")
    lockstep_timeout_s: float = 30.0
    wait_for_subscribers: int = 0
    max_steps: int = 0
    start_step: int = 0
    qos_depth: int = 10
    qos_reliability: str = "reliable"

    @classmethod
    def from_params(cls, values: dict[str, Any]) -> PlacerConfig:
        """Validate raw parameter values (missing ones take their defaults) into a config."""
        v = validate(PLACER_PARAMS, values)
        for key in ("morph_weights", "clips", "lockstep_ack_from"):
            v[key] = tuple(v[key])
        cfg = cls(**v)
        cfg.check()
        return cfg

    def check(self) -> None:
        """Cross-parameter rules (each parameter alone was checked by its spec)."""
        if self.count_max > self.pool_size:
            raise ParameterError("count_max", self.count_max, f"<= pool_size ({self.pool_size})")
        if self.count_min > self.count_max:
            raise ParameterError("count_min", self.count_min, f"<= count_max ({self.count_max})")
        if self.scale_min > self.scale_max:
            raise ParameterError("scale_min", self.scale_min, f"<= scale_max ({self.scale_max})")
        if self.rect_min > self.rect_max:
            raise ParameterError("rect_min", self.rect_min, f"<= rect_max ({self.rect_max})")
        if self.camera_height_min > self.camera_height_max:
            raise ParameterError("camera_height_min", self.camera_height_min,
                                 f"<= camera_height_max ({self.camera_height_max})")
        if self.day_start_h >= self.day_end_h:
            raise ParameterError("day_start_h", self.day_start_h, f"< day_end_h ({self.day_end_h})")
        if len(set(self.lockstep_ack_from)) != len(self.lockstep_ack_from):
            raise ParameterError("lockstep_ack_from", list(self.lockstep_ack_from), "distinct names")

    def as_params(self) -> dict[str, Any]:
        """The config as ROS parameter values (lists for tuples)."""
        return {f.name: (list(getattr(self, f.name)) if isinstance(getattr(self, f.name), tuple)
                         else getattr(self, f.name)) for f in fields(self)}
