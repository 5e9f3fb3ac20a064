"""The sky of one step (clouds, overcast days) and the structured domain randomisation of sky, light and plants.

Photographs are taken under clear, broken and overcast skies; our first renders had a clear sky only. Each step
draws a :class:`~zebra_sim_ros.messages.Weather` from its own random stream (``[seed, placement, reroll + 1,
WEATHER_STREAM]``), so the other draws of a step, and hence placement, cameras and labels, do not depend on it.
With the placer's ``look_randomise`` > 0 a share of steps also gets a tinted sky, a tinted light, recoloured plants
and the sun turned to another azimuth (its elevation, so the time of day's light level, is kept): randomisation
kept inside a realistic scene (Prakash et al., structured domain randomisation), for training sets.
"""

from __future__ import annotations

import math

import numpy as np

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.messages import Lighting, Vec3, Weather

__all__ = ["SKIES", "WEATHER_STREAM", "rotate_sun", "sample_weather"]

WEATHER_STREAM = 0x5C1E
# Kinds of sky: (share of steps, cloud cover range); a step's cover is then scaled by cloud_cover_max.
SKIES = ((0.45, (0.0, 0.15)), (0.35, (0.15, 0.7)), (0.20, (0.7, 1.0)))
SKY_TINT = (0.8, 1.25)  # log-uniform per channel
LIGHT_WARMTH = 0.2  # light colour temperature shift: (1 + t, 1, 1 - t), t in +-this
VEGETATION_BRIGHTNESS = (0.6, 1.6)  # log-uniform
VEGETATION_CHANNEL = (0.75, 1.33)  # log-uniform per channel


def _log_uniform(u: float, lo: float, hi: float) -> float:
    return math.exp(math.log(lo) + (math.log(hi) - math.log(lo)) * u)


def sample_weather(rng: np.random.Generator, cloud_cover_max: float,
                   randomise: float) -> tuple[Weather, Vec3, float]:
    """The step's weather, its plants' tint and the sun's azimuth turn in degrees (0 unless the step is
    randomised). Always takes the same 14 draws, so neither setting changes any other draw."""
    if not 0.0 <= cloud_cover_max <= 1.0:
        raise ParameterError("cloud_cover_max", cloud_cover_max, "0..1")
    if not 0.0 <= randomise <= 1.0:
        raise ParameterError("look_randomise", randomise, "0..1")
    u = rng.uniform(size=14)
    kind = min(int(np.searchsorted(np.cumsum([share for share, _ in SKIES]), u[0], side="right")), len(SKIES) - 1)
    lo, hi = SKIES[kind][1]
    cover = lo + (hi - lo) * float(u[1])
    offset = (float(u[2] * 20000.0 - 10000.0), float(u[3] * 20000.0 - 10000.0))
    if u[4] >= randomise:
        return Weather(round(cover * cloud_cover_max, 4), offset), (1.0, 1.0, 1.0), 0.0
    sky = tuple(_log_uniform(float(v), *SKY_TINT) for v in u[5:8])
    t = (2.0 * float(u[8]) - 1.0) * LIGHT_WARMTH
    light = (1.0 + t, 1.0, 1.0 - t)
    b = _log_uniform(float(u[9]), *VEGETATION_BRIGHTNESS)
    veg = tuple(b * _log_uniform(float(v), *VEGETATION_CHANNEL) for v in u[10:13])
    turn = float(u[13] * 360.0 - 180.0)
    weather = Weather(round(cover * cloud_cover_max, 4), offset, (sky[0], sky[1], sky[2]), light)
    return weather, (veg[0], veg[1], veg[2]), turn


def rotate_sun(lighting: Lighting, degrees: float) -> Lighting:
    """``lighting`` with the sun (and the key light) turned about the vertical by ``degrees`` (clockwise seen
    from above, as azimuths count): same elevation, colour and intensity, other shadows."""
    if degrees == 0.0:
        return lighting
    a = math.radians(-degrees)  # azimuth is clockwise from north; rotation in ENU is counter-clockwise
    c, s = math.cos(a), math.sin(a)

    def turn(v: Vec3) -> Vec3:
        return (c * v[0] - s * v[1], s * v[0] + c * v[1], v[2])

    az = (lighting.sun_azimuth_deg + degrees) % 360.0
    return Lighting(lighting.time_of_day_h, lighting.day_of_year, lighting.latitude_deg, turn(lighting.sun_direction),
                    lighting.sun_elevation_deg, az, turn(lighting.light_direction), lighting.light_rgb,
                    lighting.light_intensity, lighting.ambient_rgb, lighting.ambient_intensity, lighting.is_night)
