"""Drone camera poses: the paper's ``far`` and ``closeby`` strategies around the zebras' pivot.

Pivot = mean zebra position (x, y, and the ground height z under them). Every camera is drawn as:

- height ``z = pivot_z + U(height_min, height_max)``;
- ``far``: ``x, y = pivot + U(-far_radius, far_radius)`` each; ``closeby``: x, y uniform in the zebras'
  bounding box grown by ``closeby_margin``;
- yaw = bearing from camera to pivot + U(-j, j) (j = 30 deg far, 15 deg closeby);
- pitch = atan2(pivot_z - cam_z, d_xy) + ``pitch_offset_deg`` (the pivot's elevation, raised 15 deg);
- roll = U(-roll_max, roll_max).

Angles follow :mod:`zebra_sim_ros.geometry.camera`: pitch is the elevation of the optical axis (negative
looks down), yaw counter-clockwise from east. A draw is kept only if the camera is at least
``min_camera_clearance`` above the ground below it, ``min_camera_separation`` from the cameras already
drawn, and the pivot projects inside its image; otherwise it is drawn again (at most ``max_tries`` times).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.errors import ZebraSimError
from zebra_sim_ros.geometry.camera import PinholeCamera, map_to_optical, optical_rotation
from zebra_sim_ros.geometry.rotations import matrix_to_quat
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
        w, x, y, z = matrix_to_quat(self.r_optical)
        return (float(x), float(y), float(z), float(w))

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dictionary (see the scene schema)."""
        return {"name": self.name, "strategy": self.strategy, "position": list(self.position),
                "orientation_xyzw": list(self.quaternion_xyzw()), "yaw_deg": self.yaw_deg,
                "pitch_deg": self.pitch_deg, "roll_deg": self.roll_deg, "frame_id": f"{self.name}_camera_optical"}


def sample_cameras(rng: np.random.Generator, zebra_xyz: FloatArray, strategy: str, names: list[str],
                   ranges: CameraRanges, terrain: Heightfield, camera: PinholeCamera) -> list[CameraPose]:
    """Draw one pose per name around the zebras at ``zebra_xyz`` (N, 3), N >= 1."""
    if len(zebra_xyz) == 0:
        raise CameraPlacementError("no zebra was placed, so there is no pivot to look at")
    if strategy not in ("far", "closeby"):
        raise CameraPlacementError(f"strategy {strategy!r} is not far or closeby")
    pivot = zebra_xyz.mean(axis=0)
    lo, hi = zebra_xyz[:, :2].min(axis=0), zebra_xyz[:, :2].max(axis=0)
    jitter = np.radians(ranges.far_yaw_jitter_deg if strategy == "far" else ranges.closeby_yaw_jitter_deg)
    poses: list[CameraPose] = []
    for name in names:
        for _ in range(ranges.max_tries):
            if strategy == "far":
                xy = pivot[:2] + rng.uniform(-ranges.far_radius, ranges.far_radius, size=2)
            else:
                xy = rng.uniform(lo - ranges.closeby_margin, hi + ranges.closeby_margin)
            z = pivot[2] + rng.uniform(ranges.height_min, ranges.height_max)
            d = pivot[:2] - xy
            d_xy = float(np.hypot(d[0], d[1]))
            yaw = float(np.arctan2(d[1], d[0])) + rng.uniform(-jitter, jitter)
            pitch = float(np.arctan2(pivot[2] - z, d_xy)) + np.radians(ranges.pitch_offset_deg)
            roll = rng.uniform(-np.radians(ranges.roll_max_deg), np.radians(ranges.roll_max_deg))
            pos = np.array([xy[0], xy[1], z])
            if z < float(terrain.height_at(xy[0], xy[1])) + ranges.min_clearance:
                continue
            if any(np.linalg.norm(pos - np.array(p.position)) < ranges.min_separation for p in poses):
                continue
            r = optical_rotation(yaw, pitch, roll)
            if not camera.in_image(map_to_optical(pivot[None], pos, r))[0]:
                continue
            poses.append(CameraPose(name=name, strategy=strategy, position=(float(pos[0]), float(pos[1]), float(z)),
                                    yaw_deg=float(np.degrees(yaw)), pitch_deg=float(np.degrees(pitch)),
                                    roll_deg=float(np.degrees(roll)), r_optical=r))
            break
        else:
            raise CameraPlacementError(
                f"no valid pose for {name} ({strategy}) in {ranges.max_tries} draws: the ground may be higher than "
                f"{ranges.height_max} m above the zebras, or the field of view too narrow ({camera.hfov_deg} deg)")
    return poses
