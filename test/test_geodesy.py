"""The map on the Earth: WGS84 conversions checked against the ellipsoid's own figures (its radii, its meridian's
curvature) and against each other, everywhere on the Earth; the placer's datum parameters refused by name."""

from __future__ import annotations

import numpy as np
import pytest

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.geometry.geodesy import (
    WGS84_A,
    WGS84_B,
    WGS84_E2,
    ecef_to_geodetic,
    enu_to_geodetic,
    geodetic_to_ecef,
    geodetic_to_enu,
    gnss_fixes,
)
from zebra_sim_ros.messages import Datum
from zebra_sim_ros.placement.config import PlacerConfig


def test_known_points_of_the_ellipsoid() -> None:
    got = geodetic_to_ecef([[0.0, 0.0, 0.0], [90.0, 0.0, 0.0], [0.0, 90.0, 100.0], [-90.0, 0.0, -20.0]])
    want = [[WGS84_A, 0, 0], [0, 0, WGS84_B], [0, WGS84_A + 100.0, 0], [0, 0, -WGS84_B + 20.0]]
    assert got == pytest.approx(np.array(want), abs=1e-6)
    assert ecef_to_geodetic(want) == pytest.approx(np.array([[0, 0, 0], [90, 0, 0], [0, 90, 100], [-90, 0, -20]]),
                                                   abs=1e-9)


def _heikkinen(xyz: np.ndarray) -> np.ndarray:
    """Latitude, longitude (deg) and height of ECEF points by Heikkinen's closed form (1982): another method than
    the module's iteration, written here from its published equations, to check it against."""
    a, b, e2 = WGS84_A, WGS84_B, WGS84_E2
    ep2 = (a * a - b * b) / (b * b)
    x, y, z = xyz.T
    p = np.hypot(x, y)
    f = 54 * b * b * z * z
    g = p * p + (1 - e2) * z * z - e2 * (a * a - b * b)
    c = e2 * e2 * f * p * p / g ** 3
    s = np.cbrt(1 + c + np.sqrt(c * c + 2 * c))
    k = s + 1 + 1 / s
    pp = f / (3 * k * k * g * g)
    q = np.sqrt(1 + 2 * e2 * e2 * pp)
    r0 = -pp * e2 * p / (1 + q) + np.sqrt(a * a / 2 * (1 + 1 / q) - pp * (1 - e2) * z * z / (q * (1 + q))
                                           - pp * p * p / 2)
    u = np.sqrt((p - e2 * r0) ** 2 + z * z)
    v = np.sqrt((p - e2 * r0) ** 2 + (1 - e2) * z * z)
    z0 = b * b * z / (a * v)
    return np.stack([np.degrees(np.arctan((z + ep2 * z0) / p)), np.degrees(np.arctan2(y, x)),
                     u * (1 - b * b / (a * v))], axis=-1)


def test_the_inverse_agrees_with_heikkinens_closed_form() -> None:
    rng = np.random.default_rng(11)
    lla = np.stack([rng.uniform(-89, 89, 2000), rng.uniform(-180, 180, 2000), rng.uniform(-500, 12000, 2000)],
                   axis=-1)
    xyz = geodetic_to_ecef(lla)
    ours, theirs = ecef_to_geodetic(xyz), _heikkinen(xyz)
    assert ours[:, :2] == pytest.approx(theirs[:, :2], abs=1e-9) and ours[:, 2] == pytest.approx(theirs[:, 2], abs=1e-4)
    assert theirs[:, :2] == pytest.approx(lla[:, :2], abs=1e-9)  # the closed form inverts the forward one too


def test_geodetic_round_trips_everywhere_to_well_under_a_millimetre() -> None:
    rng = np.random.default_rng(5)
    lla = np.stack([rng.uniform(-89.9, 89.9, 2000), rng.uniform(-180, 180, 2000), rng.uniform(-500, 12000, 2000)],
                   axis=-1)
    back = ecef_to_geodetic(geodetic_to_ecef(lla))
    assert back[:, :2] == pytest.approx(lla[:, :2], abs=1e-9)  # 1e-9 deg: 0.1 mm on the ground
    assert back[:, 2] == pytest.approx(lla[:, 2], abs=1e-5)
    assert np.abs(geodetic_to_ecef(back) - geodetic_to_ecef(lla)).max() < 1e-5


@pytest.mark.parametrize("lat", [0.0, -2.3, 45.0, 70.0])
def test_a_kilometre_north_east_and_up_of_the_datum(lat: float) -> None:
    """A metre north is 1/(M + h) rad of latitude, a metre east 1/((N + h) cos lat) rad of longitude (M, N: the
    ellipsoid's radii of curvature at the datum, h its height); up changes the height alone; the tangent plane
    rises above the ellipsoid by d^2 / 2R at d (the figures of a textbook's second-order expansion, not of this
    module)."""
    datum = Datum(lat, 34.8, 1550.0)
    phi = np.radians(lat)
    w = 1.0 - WGS84_E2 * np.sin(phi) ** 2
    m, n = WGS84_A * (1 - WGS84_E2) / w ** 1.5 + 1550.0, WGS84_A / np.sqrt(w) + 1550.0
    got = enu_to_geodetic([[0, 0, 0], [0, 1000.0, 0], [1000.0, 0, 0], [0, 0, 100.0]], datum)
    assert got[0] == pytest.approx([lat, 34.8, 1550.0], abs=1e-9)
    assert got[1, 0] - lat == pytest.approx(np.degrees(1000.0 / m), rel=1e-5)
    assert got[1, 1] == pytest.approx(34.8, abs=1e-10)
    # east: a kilometre along the tangent plane leaves the parallel towards the equator by d^2 tan(lat) / 2MN rad
    assert got[2, 0] - lat == pytest.approx(-np.degrees(1000.0 ** 2 * np.tan(phi) / (2 * m * n)), rel=1e-3, abs=1e-12)
    assert got[2, 1] - 34.8 == pytest.approx(np.degrees(1000.0 / (n * np.cos(phi))), rel=1e-5)
    assert got[1, 2] - 1550.0 == pytest.approx(1000.0 ** 2 / (2 * m), rel=0.01)  # 7.9 cm at the equator
    assert got[2, 2] - 1550.0 == pytest.approx(1000.0 ** 2 / (2 * n), rel=0.01)
    assert got[3] == pytest.approx([lat, 34.8, 1650.0], abs=1e-8)


def test_map_points_round_trip_through_latitude_and_longitude() -> None:
    rng = np.random.default_rng(7)
    points = np.concatenate([rng.uniform(-200, 200, (500, 3)), rng.uniform(-1e5, 1e5, (500, 3))])
    for datum in (Datum(-2.3, 34.8, 1550.0), Datum(78.2, 15.6, 0.0), Datum(-33.9, -179.9, 20.0)):
        back = geodetic_to_enu(enu_to_geodetic(points, datum), datum)
        assert np.abs(back - points).max() < 1e-4  # 0.1 mm, 100 km out


def test_datums_and_the_placers_datum_parameters_are_refused_by_name() -> None:
    for bad, named in (((91.0, 0.0), "latitude 91.0"), ((0.0, -181.0), "longitude -181.0"),
                       ((0.0, 0.0, float("nan")), "altitude nan")):
        with pytest.raises(ValueError, match=named):
            Datum(*bad)
    for name, value in (("longitude_deg", 200.0), ("origin_altitude_m", -1000.0), ("latitude_deg", -95.0)):
        with pytest.raises(ParameterError, match=name):
            PlacerConfig.from_params({name: value})


def test_gnss_fixes_are_seeded_gaussian_about_the_points_with_their_covariance() -> None:
    """A receiver's noise: the same seed gives the same fixes, another seed others; converted back, the offsets of
    4,000 fixes have the sigmas asked per axis (within 5%), no mean and no correlation between axes; the covariance
    is their diagonal; without noise the fixes are the points exactly and nothing is drawn. Bad sigmas are named."""
    datum = Datum(-2.3, 34.8, 1550.0)
    rng = np.random.default_rng(4)
    points = np.column_stack([rng.uniform(-500, 500, (4000, 2)), rng.uniform(40, 120, 4000)])
    fixes, cov = gnss_fixes(points, datum, 2.5, 5.0, (9, 3, 7))
    again, _ = gnss_fixes(points, datum, 2.5, 5.0, (9, 3, 7))
    other, _ = gnss_fixes(points, datum, 2.5, 5.0, (9, 4, 7))
    np.testing.assert_array_equal(fixes, again)
    back = geodetic_to_enu(fixes, datum)
    assert np.abs(geodetic_to_enu(other, datum) - back).mean() > 1.0  # other draws
    off = back - points
    np.testing.assert_allclose(off.std(0), [2.5, 2.5, 5.0], rtol=0.05)
    assert np.abs(off.mean(0)).max() < 0.25  # 3 standard errors of 5 m over 4,000
    assert np.abs(np.corrcoef(off.T) - np.eye(3)).max() < 0.06
    np.testing.assert_allclose(cov, np.diag([6.25, 6.25, 25.0]))
    exact, zero = gnss_fixes(points[:5], datum, 0.0, 0.0, (9, 3, 7))
    np.testing.assert_allclose(geodetic_to_enu(exact, datum), points[:5], atol=1e-6)
    assert not zero.any()
    for bad in ((-1.0, 0.0), (0.0, float("nan")), (float("inf"), 1.0)):
        with pytest.raises(ValueError, match="GNSS sigmas"):
            gnss_fixes(points[:1], datum, *bad, (1,))
    with pytest.raises(ValueError, match="GNSS seed"):
        gnss_fixes(points[:1], datum, 1.0, 1.0, ())
