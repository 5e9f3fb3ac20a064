"""Where a detected animal is: a box in a camera's image, that image's metric depth and the camera's pose give the
box's position in ``map``.

An aerial survey counts and maps animals, and three drones that see one herd see each animal up to three times: a
position on the map is what lets their detections be told apart, joined or compared with the placed animals
(``zebra_sim/zebras``). Boxes are in pixel-edge coordinates (the labeller's and the detector's: the left edge of
the first pixel is 0); the intrinsic matrix in pixel-centre ones, as ``sensor_msgs/CameraInfo`` has it; depth is
metres along the optical axis (REP 118: +inf, NaN or 0 where nothing is measured). Pure numpy, no ROS.
"""

from __future__ import annotations

import bisect
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.geometry.frames import slerp_xyzw, xyzw_to_matrix
from zebra_sim_ros.geometry.lens import Distortion

FloatArray = NDArray[np.float64]
DEPTH_WINDOW_M = 1.5  # how deep a span of a box's depths is taken as its animal (about a zebra's length and a half)
CORE = 1.0  # the share of a box's width and height, about its centre, whose depths place it: the whole box
# a zebra's body centre above the ground: its 3D box's centre over the ground under it is 0.62 m in the default
# world's herds (median; 0.36-1.02 m from the 5th to the 95th percentile: foals to adults, grazing to standing)
CENTRE_HEIGHT_M = 0.6
GROUND_MAX_RANGE_M = 1000.0  # a ray that meets the ground farther than this is too near the horizon to place by it


@dataclass(frozen=True)
class Located:
    """Boxes placed in ``map``: per box its point (the box centre's ray at the box's depth; NaN where no depth was
    measured in it), that depth along the optical axis, and the box's width and height in metres at that depth."""

    points: FloatArray  # (N, 3) map coordinates, m
    depth: FloatArray  # (N,) m along the optical axis; NaN: none
    size: FloatArray  # (N, 2) width, height, m

    @property
    def valid(self) -> NDArray[np.bool_]:
        """Boxes with a depth (and so a point)."""
        return np.isfinite(self.depth)


def _densest(values: FloatArray, window: float) -> float:
    """The median of the most values that lie within ``window`` of each other (the densest span of that width)."""
    srt = np.sort(values)
    ends = np.searchsorted(srt, srt + window, side="right")
    first = int(np.argmax(ends - np.arange(len(srt))))
    return float(np.median(srt[first:ends[first]]))


def box_depths(depth: NDArray[np.floating], boxes: FloatArray, core: float = CORE,
               window_m: float = DEPTH_WINDOW_M) -> FloatArray:
    """Each box's depth: of the measured depths (finite, above 0) in its central ``core`` share (1: the whole box;
    0.5: the middle half of its width and of its height), clipped to the image and at least one pixel, the median
    of the densest span ``window_m`` deep (0: of them all); NaN for a box with no measured pixel there. ``boxes``:
    (N, 4) xyxy in pixel-edge coordinates.

    The animal is the largest thing at one depth in its box: seen at a slant, the ground behind its back and
    between its legs spreads over metres of depth, another animal in front of a partly hidden one sits at its own
    depth, and either can hold half the box's pixels, which moves a plain median metres along the ray
    (BENCHMARKS.md, "The locator")."""
    if not 0.0 < core <= 1.0:
        raise ParameterError("core", core, "0 < core <= 1")
    if not (np.isfinite(window_m) and window_m >= 0):
        raise ParameterError("window_m", window_m, "0 (a plain median) or more, in metres")
    depth = np.asarray(depth)
    if depth.ndim != 2:
        raise ValueError(f"a depth image of H x W, not {depth.shape}")
    h, w = depth.shape
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    out = np.full(len(boxes), np.nan)
    for i, (x0, y0, x1, y1) in enumerate(boxes):
        if not np.all(np.isfinite((x0, y0, x1, y1))):
            continue
        cx, cy, hw, hh = (x0 + x1) / 2, (y0 + y1) / 2, abs(x1 - x0) * core / 2, abs(y1 - y0) * core / 2
        if cx + hw < 0 or cx - hw > w or cy + hh < 0 or cy - hh > h:  # the core is outside the image: no depth
            continue
        c0 = int(np.clip(np.floor(cx - hw), 0, w - 1))
        r0 = int(np.clip(np.floor(cy - hh), 0, h - 1))
        c1 = int(np.clip(np.ceil(cx + hw), c0 + 1, w))
        r1 = int(np.clip(np.ceil(cy + hh), r0 + 1, h))
        patch = depth[r0:r1, c0:c1]
        measured = patch[np.isfinite(patch) & (patch > 0)]
        if measured.size:
            out[i] = _densest(measured.astype(np.float64), window_m) if window_m > 0 else float(np.median(measured))
    return out


def intrinsics(k: ArrayLike) -> FloatArray:
    """``k`` (CameraInfo ``k``: 9 values, row-major) as a 3x3 intrinsic matrix; ValueError naming its values unless
    they are finite with positive focal lengths (a calibrated camera)."""
    k = np.asarray(k, dtype=np.float64).reshape(3, 3)
    if not (k[0, 0] > 0 and k[1, 1] > 0 and np.all(np.isfinite(k))):
        raise ValueError(f"K = {k.ravel().tolist()}: want a calibrated camera (finite, positive focal lengths)")
    return k


def _pose(position: ArrayLike, orientation_xyzw: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """A camera pose as (position (3,), optical-to-map rotation); ValueError for one that is not finite or a zero
    quaternion (others are normalised)."""
    position = np.asarray(position, dtype=np.float64).reshape(3)
    quat = np.asarray(orientation_xyzw, dtype=np.float64).reshape(4)
    if not (np.all(np.isfinite(position)) and np.all(np.isfinite(quat)) and np.linalg.norm(quat) > 1e-6):
        raise ValueError(f"a camera pose with a finite position and a finite, non-zero quaternion, not "
                         f"{position.tolist()} {quat.tolist()}")
    return position, xyzw_to_matrix(quat)


def _box_rays(boxes: FloatArray, k: FloatArray, distortion: Distortion | None) -> tuple[FloatArray, FloatArray]:
    """(5, N) ideal normalised x and y of each box's centre and its left, right, top and bottom edges' midpoints
    (pixel centres), the lens undone: NaN where it cannot be."""
    u = (boxes[:, 0] + boxes[:, 2]) / 2 - 0.5  # pixel-edge to pixel-centre coordinates
    v = (boxes[:, 1] + boxes[:, 3]) / 2 - 0.5
    us = np.concatenate([u, boxes[:, 0] - 0.5, boxes[:, 2] - 0.5, u, u])
    vs = np.concatenate([v, v, v, boxes[:, 1] - 0.5, boxes[:, 3] - 0.5])
    xs, ys = (us - k[0, 2]) / k[0, 0], (vs - k[1, 2]) / k[1, 1]
    if distortion is not None:
        xs, ys = distortion.remove(xs, ys)
    return xs.reshape(5, -1), ys.reshape(5, -1)


def _located(boxes: FloatArray, k: FloatArray, xs: FloatArray, ys: FloatArray, d: FloatArray,
             position: FloatArray, r: FloatArray) -> Located:
    """Each box's point on its centre's ray at depth ``d`` (along the optical axis; NaN: none), and its size there:
    from its edges' rays where the lens lets them be undone, else its pixel size at the centre's scale."""
    (x, xl, xr, _, _), (y, _, _, yt, yb) = xs, ys
    d = np.where(np.isfinite(x) & np.isfinite(y), d, np.nan)
    points = np.stack([x * d, y * d, d], axis=-1) @ r.T + position.reshape(1, 3)
    plain = np.stack([np.abs(boxes[:, 2] - boxes[:, 0]) / k[0, 0], np.abs(boxes[:, 3] - boxes[:, 1]) / k[1, 1]],
                     axis=-1)
    through = np.stack([np.abs(xr - xl), np.abs(yb - yt)], axis=-1)  # NaN for an edge the lens cannot undo
    size = np.where(np.isfinite(through), through, plain) * d[:, None]
    return Located(points.reshape(-1, 3), d, size.reshape(-1, 2))


def locate_boxes(boxes: FloatArray, depth: NDArray[np.floating], k: FloatArray, position: FloatArray,
                 orientation_xyzw: FloatArray, core: float = CORE, window_m: float = DEPTH_WINDOW_M,
                 distortion: Distortion | None = None) -> Located:
    """Each box's point in ``map``: the ray through its centre, at its depth (:func:`box_depths`), from a camera
    whose optical frame (z forward, x right, y down) is at ``position`` with ``orientation_xyzw`` in ``map`` (the
    placer's ``<drone>/camera/pose``), ``k`` its 3x3 intrinsic matrix (CameraInfo ``k``; skew is not modelled) and
    ``distortion`` its lens's (CameraInfo ``d``; None: an ideal pinhole). The lens is undone for the centre's ray
    (a box whose centre it cannot undo, where its polynomial folds over, gets no point) and for its edges'
    midpoints, which give its size (else its pixel size at the centre's scale). ValueError for a K that
    :func:`intrinsics` refuses, a pose that is not finite or a zero quaternion (others are normalised)."""
    k = intrinsics(k)
    position, r = _pose(position, orientation_xyzw)
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    d = box_depths(depth, boxes, core, window_m)
    xs, ys = _box_rays(boxes, k, distortion)
    return _located(boxes, k, xs, ys, d, position, r)


def locate_on_ground(boxes: FloatArray, k: FloatArray, position: FloatArray, orientation_xyzw: FloatArray,
                     ground_z: ArrayLike, centre_height: ArrayLike = CENTRE_HEIGHT_M,
                     distortion: Distortion | None = None, max_range: float = GROUND_MAX_RANGE_M) -> Located:
    """Each box's point in ``map`` for a camera without depth (a drone's colour camera): where the ray through its
    centre meets the level plane ``centre_height`` above the ground at height ``ground_z`` (an animal's body centre
    over flat ground: the flat-ground georeferencing of an aerial survey; either may also be given per box), the
    camera, lens and ValueErrors as :func:`locate_boxes`'. A box whose ray does not reach that plane in front of
    the camera (at or above the horizon, for a camera above it), or reaches it farther than ``max_range`` from the
    camera (just below the horizon, where a pixel is metres of ground), gets no point. The error grows as the ground
    departs from the plane: a metre of height moves the point a metre over the tangent of the ray's depression (2.7 m
    at 20 deg)."""
    k = intrinsics(k)
    position, r = _pose(position, orientation_xyzw)
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    try:
        level = np.broadcast_to(np.asarray(ground_z, np.float64) + np.asarray(centre_height, np.float64), len(boxes))
    except ValueError:
        raise ValueError(f"a ground height and a centre height, each one number or one per box ({len(boxes)}), not "
                         f"{np.shape(ground_z)} and {np.shape(centre_height)}") from None
    if not np.all(np.isfinite(level)):
        raise ValueError(f"a finite ground height and centre height, not {ground_z!r} and {centre_height!r}")
    xs, ys = _box_rays(boxes, k, distortion)
    rise = (np.stack([xs[0], ys[0], np.ones(len(boxes))], axis=-1) @ r.T)[:, 2]  # map z per unit of optical depth
    with np.errstate(divide="ignore", invalid="ignore"):
        d = (level - position[2]) / rise
        reach = d * np.sqrt(xs[0] ** 2 + ys[0] ** 2 + 1.0)  # along the ray
    return _located(boxes, k, xs, ys, np.where(np.isfinite(d) & (d > 0) & (reach <= max_range), d, np.nan),
                    position, r)


@dataclass(frozen=True)
class StampedPose:
    """A camera's pose at a stamp: its optical frame's position and orientation ([x, y, z, w]) in ``frame``."""

    stamp_ns: int
    position: tuple[float, float, float]
    orientation_xyzw: tuple[float, float, float, float]
    frame: str


def bracket(stamps: Sequence[int], t: int, max_gap_ns: int) -> tuple[int, float] | bool | None:
    """Where stamp ``t`` falls among sorted ``stamps``, to interpolate at it: ``(i, f)``, ``t`` a share ``f`` of the
    way from ``stamps[i]`` to ``stamps[i + 1]`` (``f`` 0 and the next index unused where ``t`` is ``stamps[i]``),
    the two at most ``max_gap_ns`` apart; True where later stamps may still bracket it (``t`` after every stamp, or
    none yet: wait, as a lagging source's may); None where none can (``t`` before the first, or between two farther
    apart than ``max_gap_ns``)."""
    i = bisect.bisect_left(stamps, t)
    if i < len(stamps) and stamps[i] == t:
        return i, 0.0
    if i == len(stamps):  # after every stamp (or none yet): later ones may come
        return True
    if i == 0 or stamps[i] - stamps[i - 1] > max_gap_ns:
        return None
    return i - 1, (t - stamps[i - 1]) / (stamps[i] - stamps[i - 1])


JUMP_BACK_NS = 10**9  # a pose this much older than the newest held: the clock went back (a restart, another bag)


class PoseTrack:
    """One camera's latest poses from a source at its own rate (a drone's odometry, not one pose per image), to
    give the pose at an image's stamp: interpolated (:func:`bracket`) between the latest pose at or before it and
    the earliest after it (position linearly, orientation by :func:`~zebra_sim_ros.geometry.frames.slerp_xyzw`)
    where those two are at most ``max_gap_ns`` apart. Keeps the ``keep`` latest poses by stamp (None: all); a pose
    over :data:`JUMP_BACK_NS` older than the newest starts the track again, as tf2's buffer does when time jumps
    back (a looping replay, a restarted source)."""

    def __init__(self, max_gap_ns: int, keep: int | None = 2000) -> None:
        self.max_gap_ns, self.keep = max_gap_ns, keep
        self.stamps: list[int] = []
        self.poses: list[StampedPose] = []

    def add(self, pose: StampedPose) -> None:
        """Hold ``pose`` in stamp order (one of a stamp already held replaces it)."""
        if self.stamps and pose.stamp_ns < self.stamps[-1] - JUMP_BACK_NS:
            self.stamps, self.poses = [], []
        i = bisect.bisect_left(self.stamps, pose.stamp_ns)
        if i < len(self.stamps) and self.stamps[i] == pose.stamp_ns:
            self.poses[i] = pose
            return
        self.stamps.insert(i, pose.stamp_ns)
        self.poses.insert(i, pose)
        if self.keep is not None and len(self.stamps) > self.keep:
            del self.stamps[0], self.poses[0]

    def at(self, t: int) -> StampedPose | bool | None:
        """The pose at stamp ``t``; True to wait for a later pose, None where none can be had (:func:`bracket`)."""
        where = bracket(self.stamps, t, self.max_gap_ns)
        if not isinstance(where, tuple):
            return where
        i, f = where
        a = self.poses[i]
        if f == 0.0:
            return a
        b = self.poses[i + 1]
        x, y, z = (float(u + f * (v - u)) for u, v in zip(a.position, b.position, strict=True))
        qx, qy, qz, qw = (float(v) for v in slerp_xyzw(a.orientation_xyzw, b.orientation_xyzw, f))
        return StampedPose(t, (x, y, z), (qx, qy, qz, qw), b.frame)


def positions_at(stamps: Sequence[int], positions: FloatArray, at: Sequence[int], max_gap_ns: int) -> FloatArray:
    """(N, 3) positions at each stamp of ``at``, interpolated linearly between the two of sorted ``stamps`` (their
    ``positions``) about it where :func:`bracket` finds them; NaN where it does not (a recording: nothing more to
    wait for)."""
    out = np.full((len(at), 3), np.nan)
    for k, t in enumerate(at):
        where = bracket(stamps, t, max_gap_ns)
        if isinstance(where, tuple):
            i, f = where
            out[k] = positions[i] if f == 0.0 else positions[i] + f * (positions[i + 1] - positions[i])
    return out


def nearest_distances(points: FloatArray, targets: FloatArray) -> FloatArray:
    """Each point's distance to the nearest of ``targets`` ((N, 3) and (M, 3)); inf where there is no target."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    targets = np.asarray(targets, dtype=np.float64).reshape(-1, 3)
    if not len(targets):
        return np.full(len(points), np.inf)
    if not len(points):
        return np.zeros(0)
    return np.asarray(np.linalg.norm(points[:, None] - targets[None], axis=2).min(axis=1))


def placing_figures(distances: FloatArray, within_m: float = 1.0) -> dict[str, float | int | None]:
    """How far placed detections are from the nearest placed animal: how many were scored, the median and 90th
    percentile distance (m; None where it is no finite distance: no animal to compare with) and the share within
    ``within_m`` (None with no detection)."""
    d = np.asarray(distances, dtype=np.float64)
    if not len(d):
        return {"scored": 0, "median_m": None, "p90_m": None, f"within_{within_m:g}_m": None}

    def finite(v: float) -> float | None:
        return round(v, 3) if np.isfinite(v) else None

    return {"scored": int(len(d)), "median_m": finite(float(np.median(d))),
            "p90_m": finite(float(np.percentile(d, 90, method="higher"))),
            f"within_{within_m:g}_m": round(float(np.mean(d <= within_m)), 4)}
