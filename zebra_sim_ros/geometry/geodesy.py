"""The map on the Earth: points of ``map`` (ENU, metres, REP 105) as WGS84 latitude, longitude and height, and back.

``map`` is the local tangent plane at the scene's :class:`~zebra_sim_ros.messages.Datum`: its origin at the datum's
latitude, longitude and height above the WGS84 ellipsoid, x east, y north, z up along the ellipsoid's normal there.
The conversions are exact (through Earth-centred, Earth-fixed coordinates; the inverse by Bowring's method,
iterated to well under a millimetre), not a flat-Earth approximation, so a survey hundreds of kilometres wide stays
right. :class:`NavNoise` gives GNSS receivers' (and the navigation's attitude) seeded errors. Pure numpy.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zebra_sim_ros.geometry.rotations import rotvec_to_matrix
from zebra_sim_ros.messages import Datum

FloatArray = NDArray[np.float64]

WGS84_A = 6_378_137.0  # semi-major axis, m
WGS84_F = 1.0 / 298.257_223_563  # flattening
WGS84_B = WGS84_A * (1.0 - WGS84_F)  # semi-minor axis, m
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)  # first eccentricity squared
_EP2 = WGS84_E2 / (1.0 - WGS84_E2)  # second eccentricity squared


def geodetic_to_ecef(lla: ArrayLike) -> FloatArray:
    """(N, 3) latitude (deg), longitude (deg), height above the ellipsoid (m) as Earth-centred, Earth-fixed x, y, z."""
    lla = np.asarray(lla, dtype=np.float64).reshape(-1, 3)
    lat, lon = np.radians(lla[:, 0]), np.radians(lla[:, 1])
    h = lla[:, 2]
    n = WGS84_A / np.sqrt(1.0 - WGS84_E2 * np.sin(lat) ** 2)  # prime vertical radius of curvature
    return np.stack([(n + h) * np.cos(lat) * np.cos(lon), (n + h) * np.cos(lat) * np.sin(lon),
                     (n * (1.0 - WGS84_E2) + h) * np.sin(lat)], axis=-1)


def ecef_to_geodetic(xyz: ArrayLike) -> FloatArray:
    """(N, 3) Earth-centred, Earth-fixed x, y, z (m) as latitude (deg), longitude (deg), height (m): Bowring's
    parametric-latitude iteration, three rounds (each gains orders of magnitude; one is micrometres on the
    Earth's surface)."""
    xyz = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
    x, y, z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    p = np.hypot(x, y)
    lon = np.arctan2(y, x)
    beta = np.arctan2(z, (1.0 - WGS84_F) * p)  # parametric latitude, first guess
    for _ in range(3):
        lat = np.arctan2(z + _EP2 * WGS84_B * np.sin(beta) ** 3, p - WGS84_E2 * WGS84_A * np.cos(beta) ** 3)
        beta = np.arctan2((1.0 - WGS84_F) * np.sin(lat), np.cos(lat))
    sin_lat, cos_lat = np.sin(lat), np.cos(lat)
    n = WGS84_A / np.sqrt(1.0 - WGS84_E2 * sin_lat ** 2)
    # the height along the normal, well conditioned at every latitude (p cos + z sin - a^2/n)
    h = p * cos_lat + z * sin_lat - WGS84_A ** 2 / n
    return np.stack([np.degrees(lat), np.degrees(lon), h], axis=-1)


def _enu_basis(datum: Datum) -> FloatArray:
    """Rows: the datum's east, north and up unit vectors in ECEF."""
    lat, lon = np.radians(datum.latitude_deg), np.radians(datum.longitude_deg)
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    return np.array([[-so, co, 0.0], [-sl * co, -sl * so, cl], [cl * co, cl * so, sl]])


def _origin(datum: Datum) -> FloatArray:
    return geodetic_to_ecef([datum.latitude_deg, datum.longitude_deg, datum.altitude_m])[0]


def enu_to_geodetic(points: ArrayLike, datum: Datum) -> FloatArray:
    """(N, 3) points of ``map`` (east, north, up in m from ``datum``) as latitude, longitude (deg) and height above
    the WGS84 ellipsoid (m)."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return ecef_to_geodetic(_origin(datum) + points @ _enu_basis(datum))


def geodetic_to_enu(lla: ArrayLike, datum: Datum) -> FloatArray:
    """(N, 3) latitude, longitude (deg) and height (m) as points of ``map`` (east, north, up in m from ``datum``)."""
    return (geodetic_to_ecef(lla) - _origin(datum)) @ _enu_basis(datum).T


GNSS_STREAM = 0x6E55  # the fixes' noise: a stream of its own beside the placement's, drawn from (seed, step, this)
ATTITUDE_STREAM = 0x6A77  # the navigation's attitude error: another stream of its own
GNSS_MAX_CORRELATION_STEPS = 3600.0  # the longest time constant, in steps, whose error a step alone can recompute
_NEGLIGIBLE = 1e-12  # a past step's draw whose weight in the error has fallen under this is left out


@dataclass(frozen=True)
class NavNoise:
    """A navigation sensor's error on each of N drones, per axis of ``map`` (east, north, up), as a function of
    (seed, step) alone. For a GNSS receiver's fix (``stream`` GNSS_STREAM) the errors are metres; for the attitude
    of the drones' navigation (ATTITUDE_STREAM) they are degrees of a small rotation about each axis (tilt about east
    and north, heading about up). ``sigma_h_m``
    per horizontal axis and ``sigma_v_m`` up (the spread at every step), correlated in time as a first-order
    Gauss-Markov process of time constant ``correlation_steps`` steps (each axis's error ``e_k = a e_(k-1) + sqrt(1 -
    a²) w_k``, a = exp(-1 / correlation_steps), started stationary at step 0: the slow wander of a receiver's
    multipath and atmospheric error; 0: drawn anew each step, white), and ``common_fraction`` of its variance
    shared by every receiver (the part of the atmosphere's and the satellites' error that receivers a few km apart
    see alike: the receivers' errors correlate by this; 0: independent).

    The draw ``w_j`` of step j is ``numpy.random.default_rng([seed, j, stream])``: N x 3 standard normals
    (the receivers in order), then 3 for the common part where ``common_fraction`` > 0, so a white, independent
    error is those normals times the sigmas, bit for bit. A correlated error follows the recursion from one step to
    the next (one draw a step); a step reached otherwise (the first, ``start_step``, a jump) sums the draws of the
    steps whose weight ``a^(k-j)`` is 1e-12 or more (at most 28 time constants of them: 2.6 s of draws at the bound
    of 3,600 steps, once), so a step's errors are the same, to about 1e-12 of the sigmas, whether it is reached from
    step 0 or computed alone."""

    sigma_h_m: float = 0.0
    sigma_v_m: float = 0.0
    correlation_steps: float = 0.0
    common_fraction: float = 0.0
    stream: int = GNSS_STREAM
    # the last error computed, unit variance: (n, seed, step, own (n, 3), common (3,) or None)
    _last: list[tuple[int, int, int, FloatArray, FloatArray | None]] = field(
        default_factory=list, init=False, repr=False, compare=False)  # a copy (dataclasses.replace) starts its own

    def __post_init__(self) -> None:
        s_h, s_v = self.sigma_h_m, self.sigma_v_m
        what = "GNSS" if self.stream == GNSS_STREAM else "attitude" if self.stream == ATTITUDE_STREAM else "error"
        if not (np.isfinite(s_h) and np.isfinite(s_v) and s_h >= 0.0 and s_v >= 0.0):
            unit = "deg" if self.stream == ATTITUDE_STREAM else "m"
            raise ValueError(f"{what} sigmas ({s_h!r}, {s_v!r}) {unit}: want finite values >= 0")
        if not 0.0 <= self.correlation_steps <= GNSS_MAX_CORRELATION_STEPS:  # NaN fails both
            raise ValueError(f"{what} correlation_steps {self.correlation_steps!r}: want 0 (white) .. "
                             f"{GNSS_MAX_CORRELATION_STEPS:g} steps")
        if not 0.0 <= self.common_fraction <= 1.0:
            raise ValueError(f"{what} common_fraction {self.common_fraction!r}: want 0..1")

    @property
    def sigmas(self) -> FloatArray:
        """Per axis (east, north, up): m, or deg for the attitude."""
        return np.array([self.sigma_h_m, self.sigma_h_m, self.sigma_v_m])

    @property
    def covariance(self) -> FloatArray:
        """The 3x3 ENU covariance of each fix (m², NavSatFix's ``position_covariance``; the receiver's own east,
        north and up differ from the datum's by under a thousandth of a radian within 6 km)."""
        return np.diag(self.sigmas ** 2)

    @property
    def a(self) -> float:
        """The correlation of each axis's error between consecutive steps (0: white)."""
        return float(np.exp(-1.0 / self.correlation_steps)) if self.correlation_steps > 0.0 else 0.0

    def _draw(self, n: int, seed: int, step: int) -> tuple[FloatArray, FloatArray | None]:
        rng = np.random.default_rng([seed, step, self.stream])
        own = rng.normal(size=(n, 3))
        return own, (rng.normal(size=3) if self.common_fraction > 0.0 else None)

    def _alone(self, n: int, seed: int, step: int) -> tuple[FloatArray, FloatArray | None]:
        """The unit-variance error of ``step`` as the weighted sum of its own and earlier steps' draws."""
        a = self.a
        if a == 0.0:
            return self._draw(n, seed, step)
        first = max(0, step - int(np.log(_NEGLIGIBLE) / np.log(a)))
        own, common = np.zeros((n, 3)), (np.zeros(3) if self.common_fraction > 0.0 else None)
        for j in range(first, step + 1):
            weight = a ** (step - j) * (1.0 if j == 0 else np.sqrt(1.0 - a * a))  # step 0: e_0 = w_0
            w_own, w_common = self._draw(n, seed, j)
            own += weight * w_own
            if common is not None and w_common is not None:
                common += weight * w_common
        return own, common

    def rotations(self, n: int, seed: int, step: int) -> FloatArray:
        """(n, 3, 3) the attitude errors of :meth:`errors` (degrees about east, north and up) as rotations in
        ``map``: what turns each camera's exact orientation into its navigated one (``R_err @ R``)."""
        return rotvec_to_matrix(np.radians(self.errors(n, seed, step)))

    def errors(self, n: int, seed: int, step: int) -> FloatArray:
        """(n, 3) east, north, up errors of n receivers at ``step`` of a run seeded ``seed`` (m; deg about each axis
        for the attitude): zeros, with nothing drawn, when both sigmas are 0."""
        if step < 0:
            raise ValueError(f"step {step!r}: want >= 0")
        if not self.sigmas.any():
            return np.zeros((n, 3))
        a = self.a
        last = self._last[0] if self._last else None
        if a > 0.0 and last is not None and last[:3] == (n, seed, step - 1):  # the recursion: one draw
            b = np.sqrt(1.0 - a * a)
            w_own, w_common = self._draw(n, seed, step)
            own = a * last[3] + b * w_own
            common = None if last[4] is None or w_common is None else a * last[4] + b * w_common
        elif last is not None and last[:3] == (n, seed, step):
            own, common = last[3], last[4]
        else:
            own, common = self._alone(n, seed, step)
        self._last[:] = [(n, seed, step, own, common)]
        if common is not None:
            own = np.sqrt(1.0 - self.common_fraction) * own + np.sqrt(self.common_fraction) * common
        return own * self.sigmas

    def fixes(self, points: ArrayLike, datum: Datum, seed: int, step: int) -> tuple[FloatArray, FloatArray]:
        """``points`` of ``map`` (N, 3; east, north, up from ``datum``: the receivers in the draw's order) as the
        receivers report them: latitude, longitude (deg) and height above the WGS84 ellipsoid (m) of each point
        moved by its error at ``step``, and their covariance. Both sigmas 0: the points exactly."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        return enu_to_geodetic(pts + self.errors(len(pts), seed, step), datum), self.covariance
