"""The map on the Earth: points of ``map`` (ENU, metres, REP 105) as WGS84 latitude, longitude and height, and back.

``map`` is the local tangent plane at the scene's :class:`~zebra_sim_ros.messages.Datum`: its origin at the datum's
latitude, longitude and height above the WGS84 ellipsoid, x east, y north, z up along the ellipsoid's normal there.
The conversions are exact (through Earth-centred, Earth-fixed coordinates; the inverse by Bowring's method,
iterated to well under a millimetre), not a flat-Earth approximation, so a survey hundreds of kilometres wide stays
right. :func:`gnss_fixes` adds a GNSS receiver's seeded noise. Pure numpy.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

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


def gnss_fixes(points: ArrayLike, datum: Datum, sigma_h_m: float, sigma_v_m: float,
               seed: Sequence[int]) -> tuple[FloatArray, FloatArray]:
    """``points`` of ``map`` (N, 3; east, north, up from ``datum``) as GNSS receivers there report them: latitude,
    longitude (deg) and height above the WGS84 ellipsoid (m) of each point moved by Gaussian noise of ``sigma_h_m``
    per horizontal axis and ``sigma_v_m`` up, drawn from ``numpy.random.default_rng(seed)`` (one draw per point, in
    order: the same seed, the same fixes), and the 3x3 ENU covariance those sigmas give (m², NavSatFix's
    ``position_covariance``; the receiver's own east, north and up differ from the datum's by under a thousandth of a
    radian within 6 km). Both sigmas 0: the points exactly, no draw made."""
    if not (np.isfinite(sigma_h_m) and np.isfinite(sigma_v_m) and sigma_h_m >= 0.0 and sigma_v_m >= 0.0):
        raise ValueError(f"GNSS sigmas ({sigma_h_m!r}, {sigma_v_m!r}) m: want finite values >= 0")
    if not len(seed):  # default_rng([]) would draw as default_rng(0): one draw for every caller
        raise ValueError("GNSS seed (): want the draw's seed, e.g. (scene seed, step, GNSS_STREAM)")
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    sigma = np.array([sigma_h_m, sigma_h_m, sigma_v_m])
    if sigma.any():
        pts = pts + np.random.default_rng(list(seed)).normal(size=pts.shape) * sigma
    return enu_to_geodetic(pts, datum), np.diag(sigma**2)
