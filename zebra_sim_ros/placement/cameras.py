"""Camera poses: the paper's ``far`` and ``closeby`` drone strategies, a ground-level ``low`` camera and a
survey drone looking straight down (``nadir``).

Pivot = mean zebra position (x, y, and the ground height z under them). ``far`` and ``closeby`` cameras are
drawn as:

- height ``z = pivot_z + U(height_min, height_max)``;
- ``far``: ``x, y = pivot + U(-far_radius, far_radius)`` each; ``closeby``: x, y uniform in the zebras'
  bounding box grown by ``closeby_margin``;
- yaw = bearing from camera to pivot + U(-j, j) (j = 30 deg far, 15 deg closeby);
- pitch = atan2(pivot_z - cam_z, d_xy) + ``pitch_offset_deg`` (the pivot's elevation, raised 15 deg);
- roll = U(-roll_max, roll_max).

``low`` (a person or camera trap on the ground; zebras fill up to most of the frame and are cut by its edges):
a target zebra is drawn; the camera stands at a horizontal distance log-U(low_distance_min, low_distance_max)
from it on a uniform bearing, ``U(low_height_min, low_height_max)`` above the ground below it, not inside a zebra
or a tree; yaw = bearing to the target + U(-low_yaw_jitter, low_yaw_jitter), pitch = elevation of the target's
centre + U(-5, 5) deg, roll U(-low_roll_max, low_roll_max). With probability ``low_other_target`` the target is
instead an animal of another species (where the placement has one): close views of the animals a detector must
not call zebras, which drones see only from afar.

``nadir`` (a survey flight): ``U(nadir_height_min, nadir_height_max)`` above the pivot's ground, x, y within
0.3 x height of the pivot, yaw uniform, pitch -90 + U(0, nadir_tilt_max) deg (the tilt's direction is uniform
through the yaw), roll as ``far``.

Angles follow :mod:`zebra_sim_ros.geometry.camera`: pitch is the elevation of the optical axis (negative
looks down), yaw counter-clockwise from east. A draw is kept only if the camera is at least
``min_camera_clearance`` above the ground below it, ``min_camera_separation`` from the cameras already
drawn, and the pivot projects inside its image; otherwise it is drawn again (at most ``max_tries`` times).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.errors import ZebraSimError
from zebra_sim_ros.geometry.camera import PinholeCamera, map_to_optical, optical_rotation
from zebra_sim_ros.geometry.frames import matrix_to_xyzw, optical_frame
from zebra_sim_ros.world.terrain import Heightfield

FloatArray = NDArray[np.float64]


class CameraPlacementError(ZebraSimError):
    """No valid camera pose was found within the allowed number of draws."""


@dataclass(frozen=True)
class CameraRanges:
    """The ranges camera poses are drawn from (see the module docstring)."""

    height_min: float = 5.0
    height_max: float = 20.0
    far_radius: float = 100.0
    closeby_margin: float = 5.0
    roll_max_deg: float = 10.0
    far_yaw_jitter_deg: float = 30.0
    closeby_yaw_jitter_deg: float = 15.0
    pitch_offset_deg: float = 15.0
    min_separation: float = 0.5
    min_clearance: float = 2.0
    max_tries: int = 1000
    low_height_min: float = 1.0
    low_height_max: float = 3.0
    low_distance_min: float = 4.0
    low_distance_max: float = 40.0
    low_yaw_jitter_deg: float = 20.0
    low_roll_max_deg: float = 3.0
    low_other_target: float = 0.0
    nadir_height_min: float = 20.0
    nadir_height_max: float = 120.0
    nadir_tilt_max_deg: float = 10.0


STRATEGIES = ("far", "closeby", "low", "nadir")
"""Every camera strategy, in the order of their stream index (see ``dataset.generate.stream_seed``)."""

LOW_ZEBRA_CLEARANCE_M = 2.0
"""A ``low`` camera stands at least this far (horizontally) from every zebra's centre: never inside an animal."""


@dataclass(frozen=True)
class Surroundings:
    """What a camera must keep out of and look at: the terrain, the zebras' ground positions and box centres
    (N, 3), the trees and rocks (centres (M, 2) and radii (M,)) and the other animals (ground positions (K, 2)
    and box centres (K, 3))."""

    terrain: Heightfield
    zebra_xyz: FloatArray
    zebra_centres: FloatArray
    obstacle_xy: FloatArray
    obstacle_radii: FloatArray
    others_xy: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))  # other species (K, 2)
    others_centres: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))  # their box centres (K, 3)


@dataclass(frozen=True)
class _Draw:
    position: FloatArray
    yaw: float
    pitch: float
    roll: float
    target: FloatArray  # must project inside the image
    clearance: float  # least height above the ground below


@dataclass(frozen=True)
class CameraPose:
    """One drone camera: position in map (m) and attitude; ``r_optical`` maps optical to map."""

    name: str
    strategy: str
    position: tuple[float, float, float]
    yaw_deg: float
    pitch_deg: float
    roll_deg: float
    r_optical: FloatArray

    def quaternion_xyzw(self) -> tuple[float, float, float, float]:
        """Orientation of the optical frame in map, ROS order (x, y, z, w)."""
        return matrix_to_xyzw(self.r_optical)

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dictionary (see the scene schema)."""
        return {"name": self.name, "strategy": self.strategy, "position": list(self.position),
                "orientation_xyzw": list(self.quaternion_xyzw()), "yaw_deg": self.yaw_deg,
                "pitch_deg": self.pitch_deg, "roll_deg": self.roll_deg, "frame_id": optical_frame(self.name)}


def _draw_drone(rng: np.random.Generator, strategy: str, r: CameraRanges, env: Surroundings) -> _Draw:
    xyz = env.zebra_xyz
    pivot = xyz.mean(axis=0)
    if strategy == "far":
        xy = pivot[:2] + rng.uniform(-r.far_radius, r.far_radius, size=2)
    else:
        xy = rng.uniform(xyz[:, :2].min(axis=0) - r.closeby_margin, xyz[:, :2].max(axis=0) + r.closeby_margin)
    jitter = np.radians(r.far_yaw_jitter_deg if strategy == "far" else r.closeby_yaw_jitter_deg)
    z = pivot[2] + rng.uniform(r.height_min, r.height_max)
    d = pivot[:2] - xy
    yaw = float(np.arctan2(d[1], d[0])) + rng.uniform(-jitter, jitter)
    pitch = float(np.arctan2(pivot[2] - z, float(np.hypot(d[0], d[1])))) + np.radians(r.pitch_offset_deg)
    roll = rng.uniform(-np.radians(r.roll_max_deg), np.radians(r.roll_max_deg))
    return _Draw(np.array([xy[0], xy[1], z]), yaw, pitch, roll, pivot, r.min_clearance)


def _draw_low(rng: np.random.Generator, r: CameraRanges, env: Surroundings) -> _Draw | None:
    # drawn only when asked, so that the default keeps its random stream
    other = r.low_other_target > 0 and rng.uniform() < r.low_other_target and len(env.others_centres) > 0
    pool = env.others_centres if other else env.zebra_centres
    target = pool[rng.integers(len(pool))]
    dist = float(np.exp(rng.uniform(np.log(r.low_distance_min), np.log(r.low_distance_max))))
    bearing = rng.uniform(-np.pi, np.pi)
    xy = target[:2] + dist * np.array([np.cos(bearing), np.sin(bearing)])
    ground = float(env.terrain.height_at(xy[0], xy[1]))
    z = ground + rng.uniform(r.low_height_min, r.low_height_max)
    yaw = bearing + np.pi + rng.uniform(-np.radians(r.low_yaw_jitter_deg), np.radians(r.low_yaw_jitter_deg))
    pitch = float(np.arctan2(target[2] - z, dist)) + np.radians(rng.uniform(-5.0, 5.0))
    roll = rng.uniform(-np.radians(r.low_roll_max_deg), np.radians(r.low_roll_max_deg))
    animals = np.concatenate([env.zebra_xyz[:, :2], env.others_xy])
    if np.min(np.hypot(*(animals - xy).T)) < LOW_ZEBRA_CLEARANCE_M:
        return None
    if len(env.obstacle_radii) and np.any(np.hypot(*(env.obstacle_xy - xy).T) < env.obstacle_radii + 0.5):
        return None
    return _Draw(np.array([xy[0], xy[1], z]), float(yaw), pitch, roll, target, r.low_height_min * 0.99)


def _draw_nadir(rng: np.random.Generator, r: CameraRanges, env: Surroundings) -> _Draw:
    pivot = env.zebra_xyz.mean(axis=0)
    height = rng.uniform(r.nadir_height_min, r.nadir_height_max)
    offset = 0.3 * height * np.sqrt(rng.uniform()) * np.array([np.cos(a := rng.uniform(-np.pi, np.pi)), np.sin(a)])
    yaw = rng.uniform(-np.pi, np.pi)
    pitch = np.radians(-90.0 + rng.uniform(0.0, r.nadir_tilt_max_deg))
    roll = rng.uniform(-np.radians(r.roll_max_deg), np.radians(r.roll_max_deg))
    xy = pivot[:2] + offset
    return _Draw(np.array([xy[0], xy[1], pivot[2] + height]), yaw, pitch, roll, pivot, r.min_clearance)


def _draw(rng: np.random.Generator, strategy: str, r: CameraRanges, env: Surroundings) -> _Draw | None:
    if strategy == "low":
        return _draw_low(rng, r, env)
    if strategy == "nadir":
        return _draw_nadir(rng, r, env)
    return _draw_drone(rng, strategy, r, env)


def sample_cameras(rng: np.random.Generator, env: Surroundings, strategy: str, names: list[str],
                   ranges: CameraRanges, camera: PinholeCamera) -> list[CameraPose]:
    """Draw one pose per name around the zebras of ``env`` (at least one)."""
    if len(env.zebra_xyz) == 0:
        raise CameraPlacementError("no zebra was placed, so there is no pivot to look at")
    if strategy not in STRATEGIES:
        raise CameraPlacementError(f"strategy {strategy!r} is not one of {STRATEGIES}")
    poses: list[CameraPose] = []
    for name in names:
        for _ in range(ranges.max_tries):
            d = _draw(rng, strategy, ranges, env)
            if d is None:
                continue
            pos = d.position
            if pos[2] < float(env.terrain.height_at(pos[0], pos[1])) + d.clearance:
                continue
            if any(np.linalg.norm(pos - np.array(p.position)) < ranges.min_separation for p in poses):
                continue
            r = optical_rotation(d.yaw, d.pitch, d.roll)
            if not camera.in_image(map_to_optical(d.target[None], pos, r))[0]:
                continue
            poses.append(CameraPose(name=name, strategy=strategy, position=(float(pos[0]), float(pos[1]),
                                                                            float(pos[2])),
                                    yaw_deg=float(np.degrees(d.yaw)), pitch_deg=float(np.degrees(d.pitch)),
                                    roll_deg=float(np.degrees(d.roll)), r_optical=r))
            break
        else:
            raise CameraPlacementError(
                f"no valid pose for {name} ({strategy}) in {ranges.max_tries} draws: the ground may be higher than "
                f"the camera's height range above the zebras, or the field of view too narrow ({camera.hfov_deg} deg)")
    return poses
