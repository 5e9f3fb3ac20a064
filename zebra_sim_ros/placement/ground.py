"""Domain randomisation of the terrain's colour: the ground look of one step.

The paper varies zebras, cameras and the time of day over ten fixed environments; a detector trained so learns
the colours of those grounds too (ours, trained on seven worlds, missed grey zebras on white snow). With the
placer's ``ground_recolor`` > 0 a share of steps draws a new look for the terrain: brighter or darker, less
saturated, tinted. Only the terrain's albedo changes (vegetation, rocks, sky and zebras keep theirs), so labels,
depth and masks are those of the unchanged scene.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from zebra_sim_ros.errors import ParameterError

# Ranges of a recoloured step (linear albedo factors). Our grounds have luminance 0.1-0.3; x4 reaches fresh snow
# (about 0.85), x0.5 dark wet soil; channel factors of +-33% move the hue without making it garish.
BRIGHTNESS = (0.5, 4.0)  # log-uniform
CHANNEL = (0.75, 1.33)  # log-uniform, each channel
MAX_ALBEDO = 0.95


@dataclass(frozen=True)
class GroundLook:
    """How the renderer recolours the terrain: ``albedo' = min(mix(albedo, luma(albedo), desaturation) * tint,
    0.95)`` in linear RGB. The default is the world as authored."""

    tint: tuple[float, float, float] = (1.0, 1.0, 1.0)
    desaturation: float = 0.0

    @property
    def is_identity(self) -> bool:
        return self.tint == (1.0, 1.0, 1.0) and self.desaturation == 0.0

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dictionary (the scene's ``ground``)."""
        return {"tint": list(self.tint), "desaturation": self.desaturation}

    @classmethod
    def from_dict(cls, d: dict[str, object] | None) -> GroundLook:
        """From a scene's ``ground`` (None or absent: as authored); raises :class:`ParameterError` on bad values."""
        if not d:
            return cls()
        try:
            tint = tuple(float(v) for v in d["tint"])  # type: ignore[attr-defined]
            desat = float(d["desaturation"])  # type: ignore[arg-type]
        except (KeyError, TypeError, ValueError) as exc:
            raise ParameterError("ground", d, "{'tint': [r, g, b], 'desaturation': 0..1}") from exc
        if len(tint) != 3 or not all(0.0 <= t <= 100.0 for t in tint) or not 0.0 <= desat <= 1.0:
            raise ParameterError("ground", d, "tint of three factors in 0..100 and desaturation in 0..1")
        return cls((tint[0], tint[1], tint[2]), desat)


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
