"""Time of day and the light it gives: sun direction, colour and sky/ambient light.

Directions are unit vectors in ``map`` (ENU: x east, y north, z up) pointing *towards* the light.
The sun's position follows the standard solar geometry for a latitude, day of year and local solar
time; at night the light is a dim, bluish moon opposite the sun's azimuth.
"""

from __future__ import annotations

import numpy as np

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.messages import Lighting

__all__ = ["DAY_WINDOWS", "LIGHT_BANDS", "LOW_SUN_DEG", "Lighting", "daylight_h", "light_band", "lighting_for",
           "sample_time_and_day"]


DAY_WINDOWS = ("sun", "clock")
LOW_SUN_DEG = 15.0  # the sun at or under this elevation, but above the horizon, is "low sun"
LIGHT_BANDS = ("day", "low sun", "night")


def light_band(sun_elevation_deg: float) -> str:
    """The light a frame was rendered in, as the benchmarks group frames: "day" (sun above
    :data:`LOW_SUN_DEG`), "low sun" (0 to that, the warm light of :func:`lighting_for`) or "night" (the sun at
    or below the horizon: twilight and moonlight)."""
    if not np.isfinite(sun_elevation_deg) or not -90.0 <= sun_elevation_deg <= 90.0:
        raise ParameterError("sun_elevation_deg", sun_elevation_deg, "-90..90 degrees")
    return "day" if sun_elevation_deg > LOW_SUN_DEG else ("low sun" if sun_elevation_deg > 0.0 else "night")


def sample_time_and_day(rng: np.random.Generator, night_fraction: float = 0.1, day_window: str = "sun",
                        day_start_h: float = 5.0, day_end_h: float = 20.0,
                        latitude_deg: float = -2.3) -> tuple[float, int]:
    """(local solar time in hours [0, 24), day of year 1..365) of one frame.

    ``1 - night_fraction`` of draws fall uniformly in the day window, the rest uniformly in the other hours.
    ``day_window`` "sun": the window is that day's sunrise to sunset at ``latitude_deg`` (:func:`daylight_h`),
    so the paper's 90% are frames in daylight, the effect it describes ("between 5 am and 8 pm, which results
    in good lighting conditions given our current settings"); "clock": the window is ``day_start_h`` to
    ``day_end_h`` read literally, which with a real sun puts the hours 5-6 and 18-20 in the dark (about 28% of
    frames at the equator instead of 10%). Both modes take the same three draws in the same order, so a seed
    gives the same frames and only the hour differs between them.
    """
    if not 0.0 <= night_fraction <= 1.0:
        raise ParameterError("night_fraction", night_fraction, "0..1")
    if day_window not in DAY_WINDOWS:
        raise ParameterError("day_window", day_window, " or ".join(DAY_WINDOWS))
    if not 0.0 <= day_start_h < day_end_h <= 24.0:
        raise ParameterError("day_start_h/day_end_h", (day_start_h, day_end_h), "0 <= start < end <= 24")
    is_day = rng.uniform() >= night_fraction
    u = rng.uniform()
    doy = int(rng.integers(1, 366))
    start, end = (day_start_h, day_end_h) if day_window == "clock" else daylight_h(doy, latitude_deg)
    if is_day or end - start >= 24.0:  # (midnight sun: no night hours)
        return float(start + (end - start) * u) % 24.0, doy
    return float(end + (start + 24.0 - end) * u) % 24.0, doy


def declination_rad(day_of_year: int) -> float:
    """The sun's declination (radians) on a day of the year (a cosine fit, within about 1 degree)."""
    return float(np.radians(-23.44) * np.cos(2 * np.pi * (day_of_year + 10) / 365.0))


def daylight_h(day_of_year: int, latitude_deg: float) -> tuple[float, float]:
    """(sunrise, sunset) in local solar hours: the sun's centre at the horizon (no refraction).

    Polar night gives an empty window (12, 12); midnight sun the whole day (0, 24).
    """
    cos_h0 = -np.tan(np.radians(latitude_deg)) * np.tan(declination_rad(day_of_year))
    half = float(np.degrees(np.arccos(np.clip(cos_h0, -1.0, 1.0)))) / 15.0  # half the day length, h
    return 12.0 - half, 12.0 + half


def solar_direction(time_of_day_h: float, day_of_year: int, latitude_deg: float) -> tuple[np.ndarray, float, float]:
    """(unit vector towards the sun in ENU, elevation deg, azimuth deg clockwise from north)."""
    decl = declination_rad(day_of_year)
    hour = np.radians(15.0 * (time_of_day_h - 12.0))
    lat = np.radians(latitude_deg)
    east = -np.cos(decl) * np.sin(hour)
    north = np.sin(decl) * np.cos(lat) - np.cos(decl) * np.cos(hour) * np.sin(lat)
    up = np.sin(decl) * np.sin(lat) + np.cos(decl) * np.cos(hour) * np.cos(lat)
    v = np.array([east, north, up])
    v /= np.linalg.norm(v)
    elev = float(np.degrees(np.arcsin(np.clip(v[2], -1, 1))))
    azim = float(np.degrees(np.arctan2(v[0], v[1])) % 360.0)
    return v, elev, azim


def lighting_for(time_of_day_h: float, day_of_year: int, latitude_deg: float) -> Lighting:
    """Sun or moon light, colour and ambient for a time of day.

    Noon is white-yellow; low sun is warm orange; civil twilight (sun 0..6 degrees below the horizon)
    keeps a dim blue-purple sky light; night is a faint, bluish moon.
    """
    if not 0.0 <= time_of_day_h < 24.0:
        raise ParameterError("time_of_day_h", time_of_day_h, "[0, 24) hours")
    if not 1 <= day_of_year <= 366:
        raise ParameterError("day_of_year", day_of_year, "1..366")
    if not -90.0 <= latitude_deg <= 90.0:
        raise ParameterError("latitude_deg", latitude_deg, "-90..90 degrees")
    sun, elev, azim = solar_direction(time_of_day_h, day_of_year, latitude_deg)
    if elev > 0.0:
        warm = float(np.clip(1.0 - elev / 25.0, 0.0, 1.0))  # 1 at the horizon, 0 above 25 degrees
        rgb = np.array([1.0, 0.97, 0.92]) * (1 - warm) + np.array([1.0, 0.62, 0.36]) * warm
        intensity = float(np.clip(np.sin(np.radians(elev)) * 1.6, 0.08, 1.0))
        ambient_rgb = np.array([0.62, 0.72, 0.90]) * (1 - warm) + np.array([0.72, 0.62, 0.70]) * warm
        ambient = 0.35 * (0.4 + 0.6 * (1 - warm))
        light, night = sun, False
    else:
        # Below the horizon: twilight sky fading into moonlight.
        twilight = float(np.clip(1.0 + elev / 6.0, 0.0, 1.0))  # 1 at sunset, 0 at 6 degrees below
        moon_az = np.radians(azim + 180.0)
        moon = np.array([np.sin(moon_az) * np.cos(np.radians(40)), np.cos(moon_az) * np.cos(np.radians(40)),
                         np.sin(np.radians(40))])
        light = moon / np.linalg.norm(moon)
        rgb = np.array([0.55, 0.65, 0.95])
        intensity = 0.06
        ambient_rgb = np.array([0.45, 0.45, 0.75]) * twilight + np.array([0.30, 0.36, 0.55]) * (1 - twilight)
        ambient = 0.03 + 0.12 * twilight
        night = True
    return Lighting(
        time_of_day_h=float(time_of_day_h), day_of_year=int(day_of_year), latitude_deg=float(latitude_deg),
        sun_direction=(float(sun[0]), float(sun[1]), float(sun[2])), sun_elevation_deg=elev, sun_azimuth_deg=azim,
        light_direction=(float(light[0]), float(light[1]), float(light[2])),
        light_rgb=(float(rgb[0]), float(rgb[1]), float(rgb[2])), light_intensity=intensity,
        ambient_rgb=(float(ambient_rgb[0]), float(ambient_rgb[1]), float(ambient_rgb[2])),
        ambient_intensity=float(ambient), is_night=night,
    )
