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
    if t.basin_depth_m > 0:
        h = h - basin_profile(preset, seed, x, y)
    h = h - float(h[inside].mean())
    return Heightfield((-half, -half), res, h.astype(np.float32))


def basin_centre(preset: WorldPreset, seed: int) -> tuple[float, float]:
    """Where a preset's waterhole lies (map x, y, m): a quarter of the flat zone off the centre, per seed."""
    rng = derive_rng(seed, preset.name, "basin")
    a = float(rng.uniform(0, 2 * np.pi))
    r = 0.25 * preset.terrain.flat_zone_m / 2
    return (r * float(np.cos(a)), r * float(np.sin(a)))


def basin_profile(preset: WorldPreset, seed: int, x: FloatArray, y: FloatArray) -> FloatArray:
    """How far (m) the waterhole lowers the ground at (x, y): ``basin_depth_m`` at its centre, a smooth bowl out to
    a shoreline whose radius wanders by +-25% around ``basin_radius_m``."""
    t = preset.terrain
    cx, cy = basin_centre(preset, seed)
    rng = derive_rng(seed, preset.name, "basin_shape")
    ang = np.arctan2(y - cy, x - cx)
    k, ph = rng.uniform(0.5, 1.0, 4), rng.uniform(0, 2 * np.pi, 4)
    wobble = sum(k[i] * np.sin((i + 2) * ang + ph[i]) for i in range(4)) / k.sum()
    rel = np.hypot(x - cx, y - cy) / (t.basin_radius_m * (1.0 + 0.25 * wobble))
    return np.asarray(t.basin_depth_m * np.clip(1.0 - rel ** 2, 0.0, 1.0) ** 2)


def fill_water(preset: WorldPreset, seed: int, terrain: Heightfield) -> tuple[Heightfield, NDArray[np.float32] | None]:
    """A preset's open water: the terrain with its basin filled to ``water_fill`` of the basin's depth (a flat water
    surface) and the water depth per sample (negative above the water line); the terrain unchanged and None for a
    preset without water."""
    t = preset.terrain
    if t.basin_depth_m <= 0 or t.water_fill <= 0:
        return terrain, None
    cx, cy = basin_centre(preset, seed)
    level = float(terrain.height_at(cx, cy)) + t.water_fill * t.basin_depth_m
    bed = terrain.heights.astype(np.float32)
    water = (level - bed).astype(np.float32)
    # Only the pond itself: the ground below the water line that connects to the basin's centre (other hollows
    # of the relief stay dry land, 2 m "above" the water for the shore rules).
    import cv2

    _, labels = cv2.connectedComponents((water > 0).astype(np.uint8), connectivity=4)
    ci = int(round((cx - terrain.origin[0]) / terrain.resolution))
    cj = int(round((cy - terrain.origin[1]) / terrain.resolution))
    pond = labels == labels[cj, ci]
    water[(water > 0) & ~pond] = -2.0
    filled = Heightfield(terrain.origin, terrain.resolution, np.where(pond, np.float32(level), bed))
    return filled, water


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
    terrain, water = fill_water(p, seed, synthesize_terrain(p, seed))
    scattered, protos = scatter_vegetation(p, terrain, seed, None if water is None else water > -0.3)
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
        water=water,
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
