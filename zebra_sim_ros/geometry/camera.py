"""Pinhole cameras and the frames around them.

Frames (REP 103): a camera *body* frame is x forward, y left, z up; the camera *optical* frame is
z forward (along the optical axis), x right, y down, which is the frame of every image and of
``sensor_msgs/CameraInfo``. Pixel coordinates follow OpenCV and ROS CameraInfo: the centre of the top-left
pixel is (0, 0), so the image spans -0.5 .. width - 0.5 and the principal point of a centred camera is
((width - 1) / 2, (height - 1) / 2).

Camera attitude is given as yaw, pitch, roll of the body frame in ``map`` (ENU):
``R_body = Rz(yaw) @ Ry(-pitch) @ Rx(roll)``, where **pitch is the elevation of the optical axis above the
horizon** (negative looks down) and yaw is the heading of the optical axis, counter-clockwise from east.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property, lru_cache

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.geometry.lens import Distortion, LensCanvas, lens_canvas
from zebra_sim_ros.geometry.rotations import rot_x, rot_y, rot_z
from zebra_sim_ros.params import param

FloatArray = NDArray[np.float64]

# Columns are the optical axes (x right, y down, z forward) expressed in the body frame.
BODY_FROM_OPTICAL: FloatArray = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])

MAX_CAMERAS = 16  # drones per step at most (the placer's num_cameras; a camera node's drone_index is below it)


@dataclass(frozen=True)
class Intrinsics:
    """The declarations of a drone camera's image size and field of view, made once: the placer (which aims the
    cameras) and the camera node (which renders them) both declare these parameters with ``same_as``."""

    width: int = param(1280, "image width", "px", lo=16, hi=8192)
    height: int = param(720, "image height", "px", lo=16, hi=8192)
    hfov_deg: float = param(80.0, "horizontal field of view", "deg", lo=20.0, hi=150.0)


@dataclass(frozen=True)
class PinholeCamera:
    """A pinhole camera of ``width`` x ``height`` pixels and horizontal FOV (which sets the focal length of K), with
    the lens's ``distortion`` (:mod:`~zebra_sim_ros.geometry.lens`; none by default: an ideal pinhole)."""

    width: int
    height: int
    hfov_deg: float
    distortion: Distortion = field(default_factory=Distortion)

    def __post_init__(self) -> None:
        if not (16 <= self.width <= 16384):
            raise ParameterError("width", self.width, "16..16384 pixels")
        if not (16 <= self.height <= 16384):
            raise ParameterError("height", self.height, "16..16384 pixels")
        if not (1.0 <= self.hfov_deg <= 170.0):
            raise ParameterError("hfov_deg", self.hfov_deg, "1..170 degrees")

    @classmethod
    def with_focal(cls, width: int, height: int, fx: float, distortion: Distortion | None = None) -> PinholeCamera:
        """The camera of ``width`` x ``height`` pixels whose focal length is ``fx`` pixels (CameraInfo's K[0, 0]; its
        field of view follows, and so ``fx`` again to within an ulp)."""
        return cls(width, height, float(np.degrees(2 * np.arctan(width / 2 / fx))), distortion or Distortion())

    @property
    def fx(self) -> float:
        """Focal length in pixels (square pixels: fy == fx)."""
        return self.width / 2 / float(np.tan(np.radians(self.hfov_deg) / 2))

    @property
    def vfov_deg(self) -> float:
        """Vertical field of view in degrees."""
        return float(np.degrees(2 * np.arctan(self.height / 2 / self.fx)))

    @property
    def K(self) -> FloatArray:  # noqa: N802 - the standard name of the intrinsic matrix
        """3x3 intrinsic matrix (OpenCV / CameraInfo convention), principal point at the image centre."""
        return np.array([[self.fx, 0.0, (self.width - 1) / 2], [0.0, self.fx, (self.height - 1) / 2],
                         [0.0, 0.0, 1.0]])

    @property
    def D(self) -> tuple[float, float, float, float, float]:  # noqa: N802 - CameraInfo's name of the distortion
        """CameraInfo's ``d``: the plumb_bob coefficients (k1, k2, p1, p2, k3)."""
        return self.distortion.coefficients

    @cached_property
    def canvas(self) -> LensCanvas | None:
        """Where a distorted image is resampled from (:func:`~zebra_sim_ros.geometry.lens.lens_canvas`; made once);
        None for an ideal pinhole."""
        return None if self.distortion.none else lens_canvas(self.width, self.height, self.fx, self.distortion)

    @property
    def ideal(self) -> PinholeCamera:
        """The ideal pinhole this camera's images are rendered with: itself without distortion, else the canvas of
        the same focal length that covers everything the lens sees."""
        c = self.canvas
        if c is None:
            return self
        return PinholeCamera.with_focal(c.canvas_width, c.canvas_height, self.fx)

    def project(self, points_optical: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
        """Pixels (..., 2) of points in the optical frame (through the lens's distortion), and whether each lies in
        front of the camera.

        The distortion polynomial folds back some way outside the image (a barrel lens's r (1 + k1 r^2) turns at
        r^2 = -1 / (3 k1)): a point farther from the axis than any the image shows keeps the radial factor of the
        farthest (a corner's), which puts it outside the image, where it belongs."""
        p = np.asarray(points_optical, dtype=np.float64)
        z = p[..., 2]
        front = z > 1e-9
        zs = np.where(front, z, 1.0)
        xi, yi = p[..., 0] / zs, p[..., 1] / zs
        x, y = self.distortion.apply(xi, yi)
        if (lens := self.canvas) is not None:
            beyond = np.hypot(xi, yi) > lens.max_radius
            if np.any(beyond):
                factor = self.distortion.radial(lens.max_radius)
                x, y = np.where(beyond, xi * factor, x), np.where(beyond, yi * factor, y)
        u = self.fx * x + (self.width - 1) / 2
        v = self.fx * y + (self.height - 1) / 2
        return np.stack([u, v], axis=-1), front

    def in_image(self, points_optical: FloatArray, margin_px: float = 0.0) -> NDArray[np.bool_]:
        """Whether points project inside the image (at least ``margin_px`` from its border) and lie in front."""
        uv, front = self.project(points_optical)
        lo = margin_px - 0.5
        return np.asarray(front & (uv[..., 0] >= lo) & (uv[..., 0] <= self.width - 1 - lo)
                          & (uv[..., 1] >= lo) & (uv[..., 1] <= self.height - 1 - lo))


@lru_cache(maxsize=8)
def pixel_rays(camera: PinholeCamera, stride: int = 1) -> NDArray[np.float64]:
    """(ceil(H / stride), ceil(W / stride), 2) ideal normalised coordinates (x / z, y / z in the optical frame) of
    the rays through every ``stride``-th pixel centre of each row and column, from (0, 0), the lens undone (as the
    lens's canvas undid it, in float32: under a ten-thousandth of a pixel; the canvas refuses a lens it cannot undo
    inside the image, so each is a ray). Made once per camera model and stride in a process; read-only."""
    if stride < 1:
        raise ParameterError("stride", stride, "a whole number of pixels, 1 or more")
    if (lens := camera.canvas) is not None:  # the lens undone at every pixel once, for the canvas: its maps
        x, y = lens.normalised(lens.map_x[::stride, ::stride], lens.map_y[::stride, ::stride])
    else:
        cols = (np.arange(0, camera.width, stride, dtype=np.float64) - (camera.width - 1) / 2) / camera.fx
        rows = (np.arange(0, camera.height, stride, dtype=np.float64) - (camera.height - 1) / 2) / camera.fx
        x, y = np.meshgrid(cols, rows)
    rays = np.stack([x, y], axis=-1)
    rays.flags.writeable = False
    return rays


def depth_points(depth: NDArray[np.floating], camera: PinholeCamera, stride: int = 1) -> NDArray[np.float32]:
    """The optical-frame points (h, w, 3), float32 metres, of every ``stride``-th pixel of a depth image (metres
    along the optical axis, as the renderer writes it: :func:`pixel_rays`' ray times the depth); NaN where the
    depth is not a positive finite number (+inf: only sky). ValueError for a depth image not of the camera's size."""
    depth = np.asarray(depth)
    if depth.shape != (camera.height, camera.width):
        raise ValueError(f"a depth image of the camera's {camera.height}x{camera.width} pixels (rows x columns), "
                         f"not {depth.shape}")
    rays = pixel_rays(camera, stride)
    z = depth[::stride, ::stride].astype(np.float64)
    z = np.where(np.isfinite(z) & (z > 0), z, np.nan)
    return np.stack([rays[..., 0] * z, rays[..., 1] * z, z], axis=-1).astype(np.float32)


def body_rotation(yaw: FloatArray | float, pitch: FloatArray | float, roll: FloatArray | float) -> FloatArray:
    """Body-to-map rotation(s) from yaw, pitch (optical-axis elevation, up positive) and roll, radians."""
    return np.asarray(rot_z(yaw) @ rot_y(-np.asarray(pitch)) @ rot_x(roll))


def optical_rotation(yaw: FloatArray | float, pitch: FloatArray | float, roll: FloatArray | float) -> FloatArray:
    """Optical-to-map rotation(s): columns are the optical x (right), y (down), z (forward) axes in map."""
    return np.asarray(body_rotation(yaw, pitch, roll) @ BODY_FROM_OPTICAL)


def map_to_optical(points: FloatArray, position: FloatArray, r_optical: FloatArray) -> FloatArray:
    """Points (..., 3) from ``map`` into the optical frame of a camera at ``position`` with ``r_optical``."""
    return np.asarray((np.asarray(points, dtype=np.float64) - position) @ r_optical)
