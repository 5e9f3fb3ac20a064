"""A drone's frames and the rotations they are built from: ROS quaternions ([x, y, z, w]) read in their order, the
body that /tf publishes turned so that /tf_static's optical frame is the camera's, and rotation vectors (the
navigation's attitude error)."""

from __future__ import annotations

import numpy as np
import pytest

from zebra_sim_ros.geometry.camera import body_rotation, optical_rotation
from zebra_sim_ros.geometry.frames import (
    OPTICAL_IN_BASE,
    OPTICAL_IN_BASE_XYZW,
    body_orientation,
    matrix_to_xyzw,
    slerp_xyzw,
    xyzw_to_matrix,
)
from zebra_sim_ros.geometry.rotations import rot_x, rot_y, rot_z, rotvec_to_matrix


def test_the_body_on_tf_gives_the_optical_frame_back_for_any_camera() -> None:
    """For 200 random cameras (any yaw, pitch -90..90, roll -45..45): /tf's body rotation is the camera's Euler
    angles' body rotation (another path than the quaternion's), and with /tf_static's base_link -> camera_optical it
    is the camera's optical frame; the static quaternion is OPTICAL_IN_BASE; quaternions come back with w >= 0."""
    rng = np.random.default_rng(3)
    np.testing.assert_allclose(xyzw_to_matrix(OPTICAL_IN_BASE_XYZW), OPTICAL_IN_BASE, atol=1e-15)
    for yaw, pitch, roll in zip(rng.uniform(-np.pi, np.pi, 200), rng.uniform(-np.pi / 2, np.pi / 2, 200),
                                rng.uniform(-np.pi / 4, np.pi / 4, 200), strict=True):
        optical = matrix_to_xyzw(optical_rotation(yaw, pitch, roll))
        body = body_orientation(optical)
        assert body[3] >= 0.0 and np.linalg.norm(body) == pytest.approx(1.0, abs=1e-12)
        np.testing.assert_allclose(xyzw_to_matrix(body), body_rotation(yaw, pitch, roll), atol=1e-9)
        np.testing.assert_allclose(xyzw_to_matrix(body) @ xyzw_to_matrix(OPTICAL_IN_BASE_XYZW),
                                   xyzw_to_matrix(optical), atol=1e-9)


def test_a_rotation_vector_turns_about_its_axis_by_its_length() -> None:
    """About x, y and z: the axis rotations; about any axis: the axis kept, the angle in the trace, orthonormal with
    determinant 1; a batch of vectors at once; a vector of 1e-14 rad (and zero) the identity to first order."""
    for axis, rot in ((np.array([1.0, 0, 0]), rot_x), (np.array([0, 1.0, 0]), rot_y), (np.array([0, 0, 1.0]), rot_z)):
        for angle in (0.3, -1.2, 3.0):
            np.testing.assert_allclose(rotvec_to_matrix(axis * angle), rot(angle), atol=1e-12)
    rng = np.random.default_rng(5)
    vectors = rng.normal(size=(50, 3))
    many = rotvec_to_matrix(vectors)
    assert many.shape == (50, 3, 3)
    for v, r in zip(vectors, many, strict=True):
        angle = np.linalg.norm(v)
        np.testing.assert_allclose(r @ (v / angle), v / angle, atol=1e-12)
        assert np.trace(r) == pytest.approx(1.0 + 2.0 * np.cos(angle), abs=1e-12)
        np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(rotvec_to_matrix(np.zeros(3)), np.eye(3), atol=0)
    tiny = np.array([1e-14, -2e-14, 3e-14])
    np.testing.assert_allclose(rotvec_to_matrix(tiny), np.eye(3) + np.cross(np.eye(3), tiny), atol=1e-27)


def test_slerp_turns_at_a_steady_rate_along_the_shorter_arc() -> None:
    """A quarter of the way from one heading to another 120 deg away is 30 deg on, about the same axis, whichever
    sign the second quaternion has (q and -q are one rotation); equal rotations give themselves."""
    rng = np.random.default_rng(4)
    for _ in range(20):
        r0 = optical_rotation(*rng.uniform(-np.pi, np.pi, 3))
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        turn = rotvec_to_matrix(axis * np.radians(120.0))
        q0, q1 = matrix_to_xyzw(r0), np.array(matrix_to_xyzw(turn @ r0))
        for sign in (1.0, -1.0):
            got = slerp_xyzw(q0, sign * q1, 0.25)
            assert np.linalg.norm(got) == pytest.approx(1.0)
            want = rotvec_to_matrix(axis * np.radians(30.0)) @ r0
            assert np.abs(xyzw_to_matrix(got) - want).max() < 1e-9
        assert np.abs(xyzw_to_matrix(slerp_xyzw(q0, q0, 0.7)) - r0).max() < 1e-12
