"""The placer's parameters: one frozen dataclass, validated once.

Defaults are the paper's randomisation (Bonetto & Ahmad 2023, section III-B): rectangles with sides
U(40, 120) m, 2..250 of a pool of 250 zebras, scale U(0.4, 1.0), 90% of frames between 5 and 20 h,
three cameras re-randomised three times per placement, 5..20 m above the zebras, roll U(-10, 10) deg,
``far`` within +-100 m of the pivot with yaw jitter +-30 deg, ``closeby`` within 5 m of the zebras' box with
+-15 deg, pitch = atan2(pivot_z - cam_z, d_xy) + 15 deg.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.geometry.camera import MAX_CAMERAS, Intrinsics, PinholeCamera
from zebra_sim_ros.geometry.geodesy import ATTITUDE_STREAM, GNSS_MAX_CORRELATION_STEPS, NavNoise
from zebra_sim_ros.geometry.lens import Lens, lens_distortion, lens_named, lens_names
from zebra_sim_ros.params import (
    ROS_NAME,
    ParamSpec,
    StageConfig,
    diagnostics_param,
    names_list,
    param,
    reliability_param,
    same_as,
)
from zebra_sim_ros.placement.cameras import STRATEGIES
from zebra_sim_ros.placement.sun import DAY_WINDOWS
from zebra_sim_ros.zebra.skeleton import OTHER_SPECIES

# the placer's poses of each camera's optical frame in map, under the camera (geometry_msgs/PoseStamped): exact,
# and as the drone's navigation gives it (at its GNSS fix's position, turned by its attitude error)
CAMERA_POSE = "camera/pose"
NAV_POSE = "camera/pose_nav"
FIX_TOPIC = "fix"  # sensor_msgs/NavSatFix of the camera's position, as its GNSS reports it
PLACER_CAMERA_TOPICS = (CAMERA_POSE, NAV_POSE, FIX_TOPIC)  # the placer's, under each camera
SCENE_TOPIC = "zebra_sim/scene"  # the placer's own topics, in the graph's namespace
ANIMALS_TOPIC = "zebra_sim/zebras"
MARKER_TOPIC = "zebra_sim/zebras/markers"
PLACER_TOPICS = (SCENE_TOPIC, ANIMALS_TOPIC, MARKER_TOPIC)

_LENS_HELP = ("the cameras' lens distortion {k}, their lens_{k} (up and the launch file set it to the first camera's, "
              "generate and render to --lens'): the pivot is kept in the image the lens gives")
STRATEGY_CHOICES = (*STRATEGIES, "mixed", "any")
"""The placer's ``strategy`` values: one strategy for every step, or a draw per step (``mixed``: far or closeby;
``any``: each of the four)."""


def _nonneg_list(n: int) -> Any:
    return lambda v: len(v) == n and all(isinstance(x, int | float) and x >= 0 for x in v) and sum(v) > 0


def _node_names(v: Any) -> bool:
    """Check: [''] (none) or a list of ROS node names, each relative or absolute (``recorder``, ``/g1/recorder``)."""
    return tuple(v) == ("",) or (len(v) > 0 and all(isinstance(x, str) and ROS_NAME.fullmatch(x) for x in v))


@dataclass(frozen=True)
class PlacerConfig(StageConfig):
    """Validated placer parameters, each declared here once (meaning, unit and range). The camera intrinsics are
    declared here and the camera node's parameters repeat these declarations (``same_as``)."""

    seed: int = param(0, "seed of every random draw; recorded in each scene", lo=0, hi=2**63 - 1)
    world: str = param("savanna", "built-in world preset name, or path to a USD stage",
                       allowed="a preset name or a .usd* path", check=lambda v: len(v) > 0)
    terrain_prim: str = param("/World/Terrain", "USD prim path of the terrain mesh (USD worlds only)",
                              allowed="an absolute prim path", check=lambda v: v.startswith("/"))
    world_seed: int = param(0, "seed of the procedural world (presets only)", lo=0, hi=2**31 - 1)
    strategy: str = param("far", "camera strategy: far, closeby (the paper's drones 5-20 m up), low (ground level, "
                          "zebras 4-40 m away), nadir (survey drone 20-120 m up looking down), mixed (each step far "
                          "or closeby, 50/50) or any (each step one of the four, 25% each)",
                          choices=STRATEGY_CHOICES)
    pool_size: int = param(250, "zebras preloaded per experiment", lo=1, hi=1000)
    count_min: int = param(2, "fewest zebras asked for per placement", lo=1, hi=1000, allowed="1..pool_size")
    count_max: int = param(250, "most zebras asked for per placement", lo=1, hi=1000,
                           allowed="count_min..pool_size")
    scale_min: float = param(0.4, "smallest zebra scale factor", lo=0.05, hi=3.0)
    scale_max: float = param(1.0, "largest zebra scale factor", lo=0.05, hi=3.0, allowed="scale_min..3")
    rect_min: float = param(40.0, "shortest side of the placement rectangle", "m", lo=1.0, hi=1000.0)
    rect_max: float = param(120.0, "longest side of the placement rectangle", "m", lo=1.0, hi=1000.0,
                            allowed="rect_min..1000 m")
    morph_weights: tuple[float, float, float] = param(
        (0.6, 0.25, 0.15), "pool share of plains, Grevy's and foals", allowed="three non-negative numbers, not all "
        "zero", check=_nonneg_list(3))
    clips: tuple[str, ...] = param(("all",), "animation clips to draw from, or [all]",
                                   allowed="clip names of the asset, or [all]",
                                   check=lambda v: len(v) > 0 and all(isinstance(x, str) for x in v))
    other_animals_max: int = param(0, "animals of other species per placement, U{0..this} (wildebeest, impala, "
                                   "giraffe, buffalo, cattle, donkey, elephant, rhino), placed around the zebras by "
                                   "the same rules; never labelled as zebra (0 = zebras only, the paper's setting)",
                                   lo=0, hi=500)
    other_species: tuple[str, ...] = param(("all",), "species the other animals are drawn from, or [all]",
                                           allowed=f"names among {list(OTHER_SPECIES)}, or [all]",
                                           check=lambda v: len(v) > 0 and all(
                                               x in (*OTHER_SPECIES, "all") for x in v))
    max_attempts: int = param(100, "candidate positions tried per zebra before it is dropped", lo=1, hi=10000)
    max_slope_deg: float = param(-1.0, "steepest ground a zebra stands on (-1: the world's own)", "deg", lo=-1.0,
                                 hi=89.0, allowed="-1 or 0..89 deg", check=lambda v: v == -1.0 or v >= 0.0)
    num_cameras: int = param(3, "drones per step", lo=1, hi=MAX_CAMERAS)
    camera_rerolls: int = param(3, "camera and time-of-day draws per placement", lo=1, hi=100)
    camera_height_min: float = param(5.0, "camera height over the mean zebra height, minimum", "m", lo=0.5, hi=500.0)
    camera_height_max: float = param(20.0, "camera height over the mean zebra height, maximum", "m", lo=0.5,
                                     hi=500.0, allowed="camera_height_min..500 m")
    far_radius: float = param(100.0, "far: camera x and y within +- this of the pivot", "m", lo=1.0, hi=2000.0)
    closeby_margin: float = param(5.0, "closeby: camera x and y within this of the zebras' box", "m", lo=0.0,
                                  hi=500.0)
    roll_max_deg: float = param(10.0, "camera roll U(-r, r)", "deg", lo=0.0, hi=45.0)
    far_yaw_jitter_deg: float = param(30.0, "far: yaw = bearing to pivot + U(-j, j)", "deg", lo=0.0, hi=90.0)
    closeby_yaw_jitter_deg: float = param(15.0, "closeby: yaw jitter", "deg", lo=0.0, hi=90.0)
    pitch_offset_deg: float = param(15.0, "added to the elevation angle of the pivot", "deg", lo=-45.0, hi=45.0)
    low_height_min: float = param(1.0, "low: camera height above the ground below it, minimum", "m", lo=0.2,
                                  hi=20.0)
    low_height_max: float = param(3.0, "low: camera height above the ground below it, maximum", "m", lo=0.2,
                                  hi=20.0, allowed="low_height_min..20 m")
    low_distance_min: float = param(4.0, "low: horizontal distance to the target zebra, minimum (log-uniform)", "m",
                                    lo=2.5, hi=500.0)
    low_distance_max: float = param(40.0, "low: horizontal distance to the target zebra, maximum", "m", lo=2.5,
                                    hi=500.0, allowed="low_distance_min..500 m")
    low_yaw_jitter_deg: float = param(20.0, "low: yaw = bearing to the target + U(-j, j)", "deg", lo=0.0, hi=60.0)
    low_roll_max_deg: float = param(3.0, "low: camera roll U(-r, r)", "deg", lo=0.0, hi=45.0)
    low_other_target: float = param(0.0, "low: probability that a camera aims at an animal of another species "
                                    "(where the placement has one; see other_animals_max) instead of a zebra: close "
                                    "views of animals that are not zebras", lo=0.0, hi=1.0)
    nadir_height_min: float = param(20.0, "nadir: camera height above the zebras' ground, minimum", "m", lo=2.0,
                                    hi=1000.0)
    nadir_height_max: float = param(120.0, "nadir: camera height above the zebras' ground, maximum", "m", lo=2.0,
                                    hi=1000.0, allowed="nadir_height_min..1000 m")
    nadir_tilt_max_deg: float = param(10.0, "nadir: pitch = -90 + U(0, t), in a uniform direction", "deg", lo=0.0,
                                      hi=45.0)
    min_camera_separation: float = param(0.5, "least distance between two cameras", "m", lo=0.0, hi=100.0)
    min_camera_clearance: float = param(2.0, "least height of a camera above the ground below it", "m", lo=0.0,
                                        hi=100.0)
    camera_width: int = same_as(Intrinsics, "width", help="image width the cameras render (the pivot must be in view)")
    camera_height: int = same_as(Intrinsics, "height", help="image height the cameras render")
    camera_hfov_deg: float = same_as(Intrinsics, "hfov_deg", help="horizontal field of view of the cameras, their "
                                     "hfov_deg (up and the launch file set it to the first camera's)")
    camera_lens_k1: float = same_as(Lens, "lens_k1", help=_LENS_HELP.format(k="k1"))
    camera_lens_k2: float = same_as(Lens, "lens_k2", help=_LENS_HELP.format(k="k2"))
    camera_lens_p1: float = same_as(Lens, "lens_p1", help=_LENS_HELP.format(k="p1"))
    camera_lens_p2: float = same_as(Lens, "lens_p2", help=_LENS_HELP.format(k="p2"))
    camera_lens_k3: float = same_as(Lens, "lens_k3", help=_LENS_HELP.format(k="k3"))
    night_fraction: float = param(0.1, "share of frames outside the day window", lo=0.0, hi=1.0)
    day_window: str = param("sun", "the day window: sun = each frame's sunrise..sunset at latitude_deg (the paper's "
                            "90% of frames in good light); clock = day_start_h..day_end_h literally",
                            choices=DAY_WINDOWS)
    day_start_h: float = param(5.0, "start of the day window with day_window clock", "h", lo=0.0, hi=24.0)
    day_end_h: float = param(20.0, "end of the day window with day_window clock", "h", lo=0.0, hi=24.0,
                             allowed="day_start_h..24 h")
    ground_recolor: float = param(0.0, "share of steps whose terrain colour is randomised (brightness x0.5..x4, "
                                  "desaturation, tint; domain randomisation for training sets; 0 = every world as "
                                  "authored)", lo=0.0, hi=1.0)
    cloud_cover_max: float = param(1.0, "largest cloud cover of a step's sky: 45% of steps clear, 35% broken, 20% "
                                   "overcast, scaled by this (0 = always a clear sky); clouds shade the ground",
                                   lo=0.0, hi=1.0)
    look_randomise: float = param(0.0, "share of steps with a randomised look: sky and light tints, recoloured "
                                  "plants, the sun turned to another azimuth (structured domain randomisation for "
                                  "training sets; 0 = as authored)", lo=0.0, hi=1.0)
    latitude_deg: float = param(-2.3, "latitude of map's origin (WGS84): the sun's path, and where the scene's datum "
                                "puts the map on the Earth (Serengeti: -2.3)", "deg", lo=-90.0, hi=90.0)
    longitude_deg: float = param(34.8, "longitude of map's origin (WGS84), east positive: the scene's datum, with "
                                 "latitude_deg and origin_altitude_m (Serengeti: 34.8; the sun follows local solar "
                                 "time)", "deg", lo=-180.0, hi=180.0)
    origin_altitude_m: float = param(1550.0, "height of map's origin above the WGS84 ellipsoid: the scene's datum "
                                     "(the Serengeti plains: about 1550; not a flight height)", "m", lo=-500.0,
                                     hi=9000.0)
    fix_sigma_m: float = param(0.0, "standard deviation of each drone's GNSS fix (drone_{i}/fix, and the position of "
                               "its camera/pose_nav) about its camera's position, per horizontal axis, drawn per step "
                               "from the scene's seed and step; the "
                               "fix's covariance says it (0 with fix_vertical_sigma_m 0: the exact position, its "
                               "covariance unknown)", "m", lo=0.0, hi=100.0)
    fix_vertical_sigma_m: float = param(0.0, "the same, up (a receiver's height is about twice as uncertain as its "
                                        "horizontal position)", "m", lo=0.0, hi=100.0)
    fix_correlation_s: float = param(0.0, "time constant of the fixes' error in simulated time: > 0 makes it wander "
                                     "as a receiver's does (first-order Gauss-Markov, each axis correlated "
                                     "exp(-dt / this) between fixes dt apart, its spread still fix_sigma_m); 0: "
                                     "drawn anew each step", "s", lo=0.0, hi=3.6e6,
                                     allowed="0..3600 steps' time (3600 / rate_hz s)")
    fix_common_fraction: float = param(0.0, "share of the fixes' error variance common to every drone (receivers a "
                                       "few km apart see much the same atmosphere and satellites: their errors "
                                       "correlate by this); 0: independent", lo=0.0, hi=1.0)
    nav_tilt_sigma_deg: float = param(0.0, "standard deviation of the tilt error of each camera's navigated pose "
                                      "(drone_{i}/camera/pose_nav, at its GNSS fix): a rotation about east and one "
                                      "about north, drawn per step from the scene's seed and step (a gimbal's IMU: "
                                      "about 0.1-0.5; 0: its orientation exact)", "deg", lo=0.0, hi=10.0)
    nav_heading_sigma_deg: float = param(0.0, "the same about up: the heading's error (a magnetometer's: about "
                                         "0.5-2; a dual-antenna GNSS's: about 0.1-0.2)", "deg", lo=0.0, hi=30.0)
    mode: str = param("rate", "rate: publish at rate_hz; lockstep: next step when every acker acknowledged; "
                      "service: one step per call of the ~/step service (std_srvs/Trigger)",
                      choices=("rate", "lockstep", "service"))
    rate_hz: float = param(1.0, "steps per second in rate mode (a step also advances simulated time by 1/rate_hz)",
                           "Hz", lo=0.001, hi=1000.0)
    lockstep_ack_from: tuple[str, ...] = param(
        ("drone_0", "drone_1", "drone_2"), "names whose acknowledgement on zebra_sim/frame_done completes a step",
        allowed="a non-empty list of names", check=names_list)
    lockstep_timeout_s: float = param(30.0, "warn and re-publish when a step is not acknowledged within this", "s",
                                      lo=0.1, hi=3600.0)
    wait_for_subscribers: int = param(0, "publish the first step only when each output topic (scene, animals, "
                                      "markers, camera poses and fixes, /tf) has at least this many subscribers, "
                                      "e.g. 1 so a recorder misses nothing (0: start at once)", lo=0, hi=1000)
    wait_for_nodes: tuple[str, ...] = param(
        ("",), "publish the first step only when each of these nodes subscribes to every output topic (scene, "
        "animals, markers, camera poses and fixes, /tf), e.g. [recorder], so that another subscriber (RViz) cannot "
        "start the run early; a name without a leading / is in the placer's namespace ([''] (empty): none)",
        allowed="[''] or a list of node names", check=_node_names)
    publish_animals: bool = param(True, "publish zebra_sim/zebras, every placed animal's species, pose and 3D box "
                                  "(a Detection3DArray); false: neither published nor waited on (a recorder that "
                                  "leaves it out, or cannot load its type)")
    max_steps: int = param(0, "stop after this many steps (0: never)", lo=0, hi=2**31)
    start_step: int = param(0, "first step index (to resume or reproduce a step alone)", lo=0, hi=2**31)
    qos_depth: int = param(10, "history depth of the published topics", lo=1, hi=1000)
    qos_reliability: str = reliability_param("QoS reliability of the animals' 3D boxes, the markers and the poses "
                                             "(the scene, /clock and /tf are always reliable)")
    diagnostics_period_s: float = diagnostics_param()

    def gnss_noise(self) -> NavNoise:
        """The drones' GNSS error that the ``fix_*`` parameters give (its time constant in steps of 1/rate_hz s)."""
        steps = min(self.fix_correlation_s * self.rate_hz, GNSS_MAX_CORRELATION_STEPS)  # check() allows a rounding
        return NavNoise(self.fix_sigma_m, self.fix_vertical_sigma_m, steps, self.fix_common_fraction)

    def attitude_noise(self) -> NavNoise:
        """The drones' navigated attitude error that the ``nav_*`` parameters give: degrees about east, north and up
        (tilt, tilt, heading), white and independent, from a stream of its own."""
        return NavNoise(self.nav_tilt_sigma_deg, self.nav_heading_sigma_deg, stream=ATTITUDE_STREAM)

    def navigation_text(self) -> str:
        """The navigation errors asked for, in words (its diagnostics): "exact" without any."""
        parts = []
        if self.fix_sigma_m or self.fix_vertical_sigma_m:
            gnss = f"GNSS {self.fix_sigma_m:g} m horizontal, {self.fix_vertical_sigma_m:g} m up"
            if self.fix_correlation_s:
                gnss += f", wandering over {self.fix_correlation_s:g} s"
            if self.fix_common_fraction:
                gnss += f", {self.fix_common_fraction:.0%} common to the drones"
            parts.append(gnss)
        if self.nav_tilt_sigma_deg or self.nav_heading_sigma_deg:
            parts.append(f"attitude {self.nav_tilt_sigma_deg:g} deg tilt, {self.nav_heading_sigma_deg:g} deg heading")
        return "; ".join(parts) or "exact"

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
        for lo_name, hi_name in (("low_height_min", "low_height_max"), ("low_distance_min", "low_distance_max"),
                                 ("nadir_height_min", "nadir_height_max")):
            if getattr(self, lo_name) > getattr(self, hi_name):
                raise ParameterError(lo_name, getattr(self, lo_name), f"<= {hi_name} ({getattr(self, hi_name)})")
        if self.day_start_h >= self.day_end_h:
            raise ParameterError("day_start_h", self.day_start_h, f"< day_end_h ({self.day_end_h})")
        if self.fix_correlation_s * self.rate_hz > GNSS_MAX_CORRELATION_STEPS * (1.0 + 1e-9):  # the bound itself ok
            raise ParameterError("fix_correlation_s", self.fix_correlation_s,
                                 f"<= {GNSS_MAX_CORRELATION_STEPS / self.rate_hz:g} s at rate_hz {self.rate_hz:g} "
                                 f"({GNSS_MAX_CORRELATION_STEPS:g} steps: a step alone sums about 28 time "
                                 "constants of draws)")
        if len(set(self.lockstep_ack_from)) != len(self.lockstep_ack_from):
            raise ParameterError("lockstep_ack_from", list(self.lockstep_ack_from), "distinct names")
        with lens_named(lens_names("camera_lens_")):  # a lens the cameras could not render, refused by name here
            _ = self.camera.canvas

    @property
    def camera(self) -> PinholeCamera:
        """The cameras the placer aims: their image size, field of view and lens."""
        return PinholeCamera(self.camera_width, self.camera_height, self.camera_hfov_deg,
                             lens_distortion(self, "camera_lens_"))


PLACER_PARAMS: tuple[ParamSpec, ...] = PlacerConfig.specs()
