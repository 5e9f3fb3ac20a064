"""The world a simulation runs in: terrain, where zebras may stand, obstacles, vegetation, ground and sky.

Frame: ``map``, ENU (REP 103/105): x east, y north, z up, metres. A world comes from a built-in preset
(:func:`generate_world`, deterministic per seed) or from a USD stage (:func:`load_world`). The types
(:class:`World`, :class:`Instances`, :class:`Obstacles`, :class:`WorldError`) live in
:mod:`zebra_sim_ros.world.model` and are importable from here too.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.world.model import DEFAULT_MATERIALS, Instances, Obstacles, World, WorldError, build_obstacles
from zebra_sim_ros.world.noise import derive_rng, smoothstep, spectral_noise, value_noise
from zebra_sim_ros.world.presets import PRESETS, Sky, WorldPreset, get_preset
from zebra_sim_ros.world.terrain import Heightfield
from zebra_sim_ros.world.usd_io import read_world_usd
from zebra_sim_ros.world.vegetation import TREE_CLEARANCE_M, scatter_vegetation

FloatArray = NDArray[np.float64]
USD_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")

__all__ = ["DEFAULT_MATERIALS", "Instances", "Obstacles", "Sky", "World", "WorldError", "generate_world",
           "load_world", "synthesize_terrain"]


def synthesize_terrain(preset: WorldPreset, seed: int) -> Heightfield:
    """The preset's heightfield for ``seed``: a square of ``terrain.size_m`` centred on the map origin.

    Spectral fractal relief (+ ridges, gullies, a valley), damped inside the central flat zone, shifted
    so that zone averages z = 0.
    """
    t = preset.terrain
    res = t.resolution
    n = int(round(t.size_m / res)) + 1
    rng = derive_rng(seed, preset.name, "terrain")
    h = spectral_noise((n, n), res, rng, t.exponent, t.min_wavelength_m, t.max_wavelength_m)
    if t.ridges > 0:
        r = spectral_noise((n, n), res, rng, t.exponent, t.min_wavelength_m, t.max_wavelength_m)
        ridged = -np.sqrt(r * r + 0.3 ** 2)  # crests along the zero lines of r, rounded off at the top
        ridged = (ridged - ridged.mean()) / ridged.std()
        h = (1 - t.ridges) * h + t.ridges * ridged
        h /= h.std()
    h = h * t.relief_m
    half = (n - 1) * res / 2
    c = np.arange(n) * res - half
    x, y = np.meshgrid(c, c)
    if t.gully_depth_m > 0:
        g = spectral_noise((n, n), res, rng, 3.5, t.gully_wavelength_m / 6, t.gully_wavelength_m)
        ggy, ggx = np.gradient(g, res)
        dist = np.abs(g) / (np.hypot(ggx, ggy) + 1e-9)
        profile = np.clip(1.0 - dist / (t.gully_width_m / 2), 0.0, 1.0) ** 1.5
        present = smoothstep(0.35, 0.55, value_noise((n, n), t.gully_wavelength_m / res, rng, octaves=2))
        h = h - t.gully_depth_m * profile * present
    zone = np.maximum(np.abs(x), np.abs(y))
    inner = t.flat_zone_m / 2
    w = t.flat_factor + (1 - t.flat_factor) * smoothstep(inner, inner + t.flat_transition_m, zone)
    inside = zone <= inner
    centre = float(h[inside].mean())
    h = centre + (h - centre) * w
    if t.valley_depth_m > 0:
        a = rng.uniform(0, np.pi)
        d = -np.sin(a) * x + np.cos(a) * y
        h = h + t.valley_depth_m * (1.0 - np.exp(-((d / t.valley_width_m) ** 2)))
    h = h - float(h[inside].mean())
    return Heightfield((-half, -half), res, h.astype(np.float32))


def preset_placeable(preset: WorldPreset, terrain: Heightfield) -> tuple[float, float, float, float]:
    """The flat central square of a preset, kept ``margin_m`` inside the terrain bounds."""
    x0, y0, x1, y1 = terrain.bounds
    m, half = preset.margin_m, preset.terrain.flat_zone_m / 2
    return (max(x0 + m, -half), max(y0 + m, -half), min(x1 - m, half), min(y1 - m, half))


def generate_world(preset: str | WorldPreset = "savanna", seed: int = 0) -> World:
    """Build a preset world (name from :data:`PRESETS`, or a :class:`WorldPreset`); same seed, same world.

    Raises :class:`ParameterError` naming 'world' (listing the presets) for an unknown name, or 'seed'
    for a negative seed.
    """
    p = preset if isinstance(preset, WorldPreset) else get_preset(preset)
    if not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ParameterError("seed", seed, "an integer >= 0")
    seed = int(seed)
    terrain = synthesize_terrain(p, seed)
    scattered, protos = scatter_vegetation(p, terrain, seed)
    vegetation = {name: Instances(name, pos, yaw, scale, protos[name].kind)
                  for name, (pos, yaw, scale) in scattered.items()}
    radius_at = {name: (pr.footprint_m, TREE_CLEARANCE_M if pr.kind == "tree" else 0.0)
                 for name, pr in protos.items()}
    return World(
        name=p.name,
        source=f"preset:{p.name}",
        seed=seed,
        terrain=terrain,
        placeable=preset_placeable(p, terrain),
        max_slope_deg=p.max_slope_deg,
        obstacles=build_obstacles(vegetation, radius_at),
        vegetation=vegetation,
        prototypes={name: pr.mesh for name, pr in protos.items()},
        materials=p.materials,
        sky=p.sky,
        description=p.description,
        footprints=radius_at,
    )


def load_world(source: str | Path, terrain_prim: str = "/World/Terrain", seed: int = 0) -> World:
    """A world from a preset name (also ``preset:<name>``) or a USD stage path (.usd/.usda/.usdc/.usdz).

    For presets ``seed`` picks the world; a USD world keeps the seed stored in it (or None). A USD
    stage needs a ``UsdGeom.Mesh`` at ``terrain_prim`` (any faces, any up axis and units: converted to
    z-up metres, sampled at 1 m); trees and rocks come from PointInstancers under ``/World/Vegetation``.
    Raises :class:`WorldError` for a missing file or a missing/non-mesh terrain prim,
    :class:`ParameterError` naming 'world' for an unknown preset name.
    """
    s = str(source)
    check_world_source(s)
    name = s.removeprefix("preset:")
    if name in PRESETS:
        return generate_world(name, seed)
    return read_world_usd(Path(s), terrain_prim)


def check_world_source(source: str | Path) -> None:
    """Raise as :func:`load_world` would for a source that is neither a preset nor an existing USD file (cheap:
    nothing is loaded)."""
    s = str(source)
    if s.removeprefix("preset:") in PRESETS:
        return
    path = Path(s)
    looks_like_path = path.suffix.lower() in USD_SUFFIXES or "/" in s or "\\" in s or path.exists()
    if s.startswith("preset:") or not looks_like_path:
        raise ParameterError("world", s, f"a preset among {sorted(PRESETS)} or a USD file path")
    if not path.is_file():
        raise WorldError(f"USD world file not found: {path}")
