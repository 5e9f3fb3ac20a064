"""The map on the Earth: WGS84 conversions checked against the ellipsoid's own figures (its radii, its meridian's
curvature) and against each other, everywhere on the Earth; the placer's datum parameters refused by name."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.geometry.geodesy import (
    ATTITUDE_STREAM,
    GNSS_MAX_CORRELATION_STEPS,
    GNSS_STREAM,
    WGS84_A,
    WGS84_B,
    WGS84_E2,
    NavNoise,
    ecef_to_geodetic,
    enu_to_geodetic,
    geodetic_to_ecef,
    geodetic_to_enu,
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


def _random_lla(seed: int, lat_max: float, n: int = 2000) -> np.ndarray:
    """n points anywhere on the Earth up to ``lat_max`` degrees from the equator, -500..12,000 m high."""
    rng = np.random.default_rng(seed)
    return np.stack([rng.uniform(-lat_max, lat_max, n), rng.uniform(-180, 180, n), rng.uniform(-500, 12000, n)],
                    axis=-1)


def test_the_inverse_agrees_with_heikkinens_closed_form() -> None:
    lla = _random_lla(11, 89.0)
    xyz = geodetic_to_ecef(lla)
    ours, theirs = ecef_to_geodetic(xyz), _heikkinen(xyz)
    assert ours[:, :2] == pytest.approx(theirs[:, :2], abs=1e-9) and ours[:, 2] == pytest.approx(theirs[:, 2], abs=1e-4)
    assert theirs[:, :2] == pytest.approx(lla[:, :2], abs=1e-9)  # the closed form inverts the forward one too


def test_geodetic_round_trips_everywhere_to_well_under_a_millimetre() -> None:
    lla = _random_lla(5, 89.9)
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
    for name, value in (("longitude_deg", 200.0), ("origin_altitude_m", -1000.0), ("latitude_deg", -95.0),
                        ("nav_tilt_sigma_deg", -0.1), ("nav_heading_sigma_deg", 31.0)):
        with pytest.raises(ParameterError, match=name):
            PlacerConfig.from_params({name: value})


def test_gnss_fixes_are_seeded_gaussian_about_the_points_with_their_covariance() -> None:
    """A receiver's noise: the same seed gives the same fixes, another step others; a white, independent error is
    the step's own standard normals times the sigmas, and converted back, the fixes' offsets are those draws; the
    covariance is their diagonal; without
    noise the fixes are the points exactly and nothing is drawn. Bad settings are named."""
    datum = Datum(-2.3, 34.8, 1550.0)
    rng = np.random.default_rng(4)
    points = np.column_stack([rng.uniform(-500, 500, (4000, 2)), rng.uniform(40, 120, 4000)])
    noise = NavNoise(2.5, 5.0)
    fixes, cov = noise.fixes(points, datum, 9, 3)
    again, _ = NavNoise(2.5, 5.0).fixes(points, datum, 9, 3)
    other, _ = noise.fixes(points, datum, 9, 4)
    np.testing.assert_array_equal(fixes, again)
    want = np.random.default_rng([9, 3, GNSS_STREAM]).normal(size=(4000, 3)) * [2.5, 2.5, 5.0]
    np.testing.assert_array_equal(noise.errors(4000, 9, 3), want)
    back = geodetic_to_enu(fixes, datum)
    assert np.abs(geodetic_to_enu(other, datum) - back).mean() > 1.0  # other draws
    off = back - points
    np.testing.assert_allclose(off, want, atol=1e-6)  # through latitude and longitude and back: the draws
    np.testing.assert_allclose(cov, np.diag([6.25, 6.25, 25.0]))
    silent = NavNoise()
    exact, zero = silent.fixes(points[:5], datum, 9, 3)
    np.testing.assert_allclose(geodetic_to_enu(exact, datum), points[:5], atol=1e-6)
    assert not zero.any() and not silent._last  # nothing drawn
    for bad, what in (((-1.0, 0.0), "GNSS sigmas"), ((0.0, float("nan")), "GNSS sigmas"),
                      ((float("inf"), 1.0), "GNSS sigmas"), ((1.0, 1.0, -0.5), "correlation_steps -0.5"),
                      ((1.0, 1.0, float("nan")), "correlation_steps nan"),
                      ((1.0, 1.0, GNSS_MAX_CORRELATION_STEPS + 1), "correlation_steps 3601"),
                      ((1.0, 1.0, 0.0, 1.5), "common_fraction 1.5")):
        with pytest.raises(ValueError, match=what):
            NavNoise(*bad)
    with pytest.raises(ValueError, match="step -1"):
        noise.errors(2, 9, -1)


def _gauss_markov(unit: np.ndarray, a: float) -> np.ndarray:
    """The process by its recursion, from the draws of steps 0..k (k, ..., 3): e_0 = w_0, e_k = a e_(k-1) +
    sqrt(1 - a²) w_k."""
    out = np.empty_like(unit)
    out[0] = unit[0]
    for k in range(1, len(unit)):
        out[k] = a * out[k - 1] + np.sqrt(1.0 - a * a) * unit[k]
    return out


def test_a_correlated_gnss_error_wanders_as_a_gauss_markov_process() -> None:
    """A time constant of 5 steps: the errors are the recursion's on the same draws (to 1e-9 m at every step,
    past step 138 too, where the sum leaves out the draws that weigh under 1e-12), whether the steps come in order
    or a step comes alone; over
    6,000 steps each axis keeps its sigma (within 6%), and its correlation between steps 1 and 5 apart is
    exp(-1/5) and exp(-1) (within 0.04); a common fraction of 0.6 correlates two receivers' errors by 0.6 and leaves
    each its sigma."""
    tau, n_steps = 5.0, 6000
    a = float(np.exp(-1.0 / tau))
    noise = NavNoise(2.0, 4.0, correlation_steps=tau)
    seq = np.stack([noise.errors(2, 17, k) for k in range(n_steps)])  # (steps, receivers, axes)
    draws = np.stack([np.random.default_rng([17, k, GNSS_STREAM]).normal(size=(2, 3)) for k in range(n_steps)])
    want = _gauss_markov(draws, a) * [2.0, 2.0, 4.0]
    np.testing.assert_allclose(seq, want, atol=1e-9, rtol=0)
    np.testing.assert_allclose(NavNoise(2.0, 4.0, tau).errors(2, 17, 4321), want[4321], atol=1e-9, rtol=0)
    np.testing.assert_allclose(NavNoise(2.0, 4.0, tau).errors(2, 17, 3), want[3], atol=1e-12, rtol=0)
    unit = (seq / [2.0, 2.0, 4.0]).reshape(n_steps, 6)
    np.testing.assert_allclose(unit.std(0), 1.0, atol=0.06)
    for lag in (1, 5):
        r = [np.corrcoef(unit[:-lag, i], unit[lag:, i])[0, 1] for i in range(6)]
        assert np.allclose(r, a ** lag, atol=0.04), (lag, r)
    assert np.abs(np.corrcoef(unit.T) - np.eye(6)).max() < 0.08  # receivers and axes independent

    shared = NavNoise(2.0, 2.0, tau, common_fraction=0.6)
    both = np.stack([shared.errors(2, 5, k) for k in range(n_steps)]) / 2.0
    np.testing.assert_allclose(both.std(0), 1.0, atol=0.06)
    r = [np.corrcoef(both[:, 0, i], both[:, 1, i])[0, 1] for i in range(3)]
    assert np.allclose(r, 0.6, atol=0.05), r
    lag1 = [np.corrcoef(both[:-1, 0, i], both[1:, 0, i])[0, 1] for i in range(3)]
    assert np.allclose(lag1, a, atol=0.04), lag1
    np.testing.assert_allclose(NavNoise(2.0, 2.0, tau, common_fraction=0.6).errors(2, 5, 4321) / 2.0, both[4321],
                               atol=1e-9, rtol=0)  # alone, past the truncation, as in order
    copied = replace(shared, stream=ATTITUDE_STREAM)  # a copy keeps nothing of the original's last step
    assert not copied._last and np.abs(copied.errors(2, 5, n_steps - 1) / 2.0 - both[-1]).max() > 0.01
    white_shared = NavNoise(2.0, 2.0, 0.0, common_fraction=0.6)
    rng = np.random.default_rng([5, 8, GNSS_STREAM])
    own, common = rng.normal(size=(2, 3)), rng.normal(size=3)
    np.testing.assert_allclose(white_shared.errors(2, 5, 8), (np.sqrt(0.4) * own + np.sqrt(0.6) * common) * 2.0,
                               atol=1e-12)


def test_the_placer_names_a_correlation_too_long_for_its_rate() -> None:
    """A time constant is counted in steps: 3600 steps at most, so its bound in seconds follows rate_hz."""
    ok = PlacerConfig.from_params({"fix_sigma_m": 1.0, "fix_correlation_s": 360.0, "rate_hz": 10.0,
                                   "fix_common_fraction": 0.5})
    noise = ok.gnss_noise()
    assert (noise.sigma_h_m, noise.sigma_v_m, noise.correlation_steps, noise.common_fraction) == \
        pytest.approx((1.0, 0.0, 3600.0, 0.5))
    with pytest.raises(ParameterError, match=r"fix_correlation_s.*<= 360 s at rate_hz 10"):
        PlacerConfig.from_params({"fix_correlation_s": 361.0, "rate_hz": 10.0})
    assert ok.navigation_text() == "GNSS 1 m horizontal, 0 m up, wandering over 360 s, 50% common to the drones"
    assert PlacerConfig.from_params({"nav_heading_sigma_deg": 0.5}).navigation_text() == (
        "attitude 0 deg tilt, 0.5 deg heading")
    assert PlacerConfig().navigation_text() == "exact"
    # the bound itself, whatever the rounding of seconds times rate: accepted, and no more than 3600 steps
    at_bound = PlacerConfig.from_params({"fix_correlation_s": 3600.0 / 7.0, "rate_hz": 7.0}).gnss_noise()
    assert at_bound.correlation_steps == pytest.approx(3600.0, abs=1e-9) and at_bound.correlation_steps <= 3600.0
    with pytest.raises(ParameterError, match="fix_common_fraction"):
        PlacerConfig.from_params({"fix_common_fraction": 1.2})
