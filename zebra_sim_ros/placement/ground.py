"""Domain randomisation of the terrain's colour: the ground look of one step.

The paper varies zebras, cameras and the time of day over ten fixed environments; a detector trained so learns
the colours of those grounds too (ours, trained on seven worlds, missed grey zebras on white snow). With the
placer's ``ground_recolor`` > 0 a share of steps draws a new look for the terrain: brighter or darker, less
saturated, tinted. Only the terrain's albedo changes (vegetation, rocks, sky and zebras keep theirs), so labels,
depth and masks are those of the unchanged scene.
"""

from __future__ import annotations

import math

import numpy as np

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.messages import GroundLook

__all__ = ["BRIGHTNESS", "CHANNEL", "GroundLook", "sample_ground_look"]

# Ranges of a recoloured step (linear albedo factors). Our grounds have luminance 0.1-0.3; x4 reaches fresh snow
# (about 0.85), x0.5 dark wet soil; channel factors of +-33% move the hue without making it garish.
BRIGHTNESS = (0.5, 4.0)  # log-uniform
CHANNEL = (0.75, 1.33)  # log-uniform, each channel


def sample_ground_look(rng: np.random.Generator, recolor: float) -> GroundLook:
    """With probability ``recolor`` a random look (brightness log-uniform in :data:`BRIGHTNESS`, desaturation
    uniform 0..1, each channel log-uniform in :data:`CHANNEL`), else the world as authored. Always takes the same
    six draws, so ``recolor`` changes no other draw of the step."""
    if not 0.0 <= recolor <= 1.0:
        raise ParameterError("ground_recolor", recolor, "0..1")
    u = rng.uniform(size=6)
    if u[0] >= recolor:
        return GroundLook()
    lo, hi = (math.log(v) for v in BRIGHTNESS)
    b = math.exp(lo + (hi - lo) * u[1])
    clo, chi = (math.log(v) for v in CHANNEL)
    r, g, bl = (b * math.exp(clo + (chi - clo) * v) for v in u[3:6])
    return GroundLook((r, g, bl), float(u[2]))
