"""The coordinate frames of a drone (REP 103 / REP 105), as the placer publishes them on ``/tf``:
``map -> <drone>/base_link -> <drone>/camera_optical``.

``map`` is ENU. ``base_link`` is the drone body (here: the camera's mount): x forward along the optical axis, y
left, z up, so a level camera has a level body, and the camera's pitch and roll are the body's.
``camera_optical`` is z forward, x right, y down. The body-to-optical rotation is fixed (``/tf_static``); the body
moves each step (``/tf``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zebra_sim_ros.geometry.rotations import matrix_to_quat, quat_to_matrix

FloatArray = NDArray[np.float64]

# Columns: the optical frame's x, y, z axes in base_link (x_opt = -y_base, y_opt = -z_base, z_opt = x_base).
OPTICAL_IN_BASE = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
OPTICAL_IN_BASE_XYZW = (-0.5, 0.5, -0.5, 0.5)  # the same rotation as a quaternion [x, y, z, w]


def base_frame(drone: str) -> str:
    """``<drone>/base_link``."""
    return f"{drone}/base_link"


def optical_frame(drone: str) -> str:
    """``<drone>/camera_optical``: the frame of the drone's images, camera_info and labels."""
    return f"{drone}/camera_optical"


def xyzw_to_matrix(xyzw: tuple[float, float, float, float] | FloatArray) -> FloatArray:
    """The rotation of a ROS quaternion ([x, y, z, w], a message's order; :mod:`rotations` orders (w, x, y, z))."""
    x, y, z, w = (float(v) for v in xyzw)
    return quat_to_matrix(np.array([w, x, y, z]))


def matrix_to_xyzw(r: FloatArray) -> tuple[float, float, float, float]:
    """A rotation matrix as a ROS quaternion [x, y, z, w], w >= 0."""
    w, x, y, z = matrix_to_quat(r)
    return float(x), float(y), float(z), float(w)


def body_orientation(optical_xyzw: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
    """The body's orientation in ``map`` ([x, y, z, w]) of a camera whose optical frame has ``optical_xyzw``: the
    body with ``/tf_static``'s OPTICAL_IN_BASE gives the optical frame back."""
    return matrix_to_xyzw(xyzw_to_matrix(optical_xyzw) @ OPTICAL_IN_BASE.T)


def slerp_xyzw(q0: ArrayLike, q1: ArrayLike, f: float) -> FloatArray:
    """The rotation ``f`` of the way from ROS quaternion ``q0`` to ``q1`` ([x, y, z, w]; normalised first) along
    the shorter arc: spherical linear interpolation, a unit quaternion."""
    a = np.asarray(q0, dtype=np.float64) / np.linalg.norm(q0)
    b = np.asarray(q1, dtype=np.float64) / np.linalg.norm(q1)
    dot = float(a @ b)
    if dot < 0.0:  # q and -q are one rotation: the shorter way round
        b, dot = -b, -dot
    if dot > 1.0 - 1e-9:  # (nearly) the same rotation: a straight line is as good and has no 0 / 0
        q = a + f * (b - a)
    else:
        theta = float(np.arccos(dot))
        q = (np.sin((1.0 - f) * theta) * a + np.sin(f * theta) * b) / np.sin(theta)
    return np.asarray(q / np.linalg.norm(q))
