"""The world a simulation runs in: terrain, where zebras may stand, obstacles, vegetation, ground and sky.

Frame: ``map``, ENU (REP 103/105): x east, y north, z up, metres. A world comes from a built-in preset
(:func:`generate_world`, deterministic per seed) or from a USD stage (:func:`load_world`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.errors import ParameterError, ZebraSimError
from zebra_sim_ros.world.noise import box_blur, derive_rng, patchwork, spectral_noise, value_noise
from zebra_sim_ros.world.presets import PRESETS, MaterialLayer, Sky, WorldPreset, get_preset, srgb
from zebra_sim_ros.world.terrain import Heightfield
from zebra_sim_ros.world.vegetation import TREE_CLEARANCE_M, PrototypeMesh, scatter_vegetation, stamp_discs

FloatArray = NDArray[np.float64]
USD_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")

__all__ = ["DEFAULT_MATERIALS", "Instances", "Obstacles", "Sky", "World", "WorldError", "generate_world",
           "load_world", "synthesize_terrain"]


class WorldError(ZebraSimError):
    """A world cannot be built or loaded (missing USD file, missing or wrong terrain prim)."""


@dataclass(frozen=True, eq=False)
class Instances:
    """Copies of one prototype: map-frame positions (M, 3) m, yaw (M,) rad about +z, uniform scale (M,)."""

    prototype: str
    positions: FloatArray
    yaw: FloatArray
    scale: FloatArray
    kind: str = "other"  # "tree", "bush", "rock", "grass" (or "other" for unknown USD prototypes)

    def __len__(self) -> int:
        return int(len(self.positions))


@dataclass(frozen=True, eq=False)
class Obstacles:
    """Footprints zebras must keep out of: centres (M, 3) m (map frame, on the ground), radii (M,) m.

    Tree radii are trunk radius + 0.3 m clearance; rock radii the rock's ground radius. Bushes and grass
    are no obstacles (a zebra may stand in them).
    """

    positions: FloatArray
    radii: FloatArray
    kinds: tuple[str, ...]

    def __len__(self) -> int:
        return int(len(self.radii))

    @classmethod
    def empty(cls) -> Obstacles:
        """No obstacles."""
        return cls(np.zeros((0, 3)), np.zeros(0), ())


# Ground for worlds that bring no materials (USD stages without displayColor): grass, dirt on slopes.
DEFAULT_MATERIALS: tuple[MaterialLayer, ...] = (
    MaterialLayer("grass", srgb(0.45, 0.50, 0.26), noise_scale_m=5.0),
    MaterialLayer("dry_grass", srgb(0.62, 0.58, 0.36), coverage=0.3, patch_scale_m=50.0),
    MaterialLayer("dirt", srgb(0.50, 0.42, 0.32), slope_band=(20.0, 90.0)),
)


@dataclass(frozen=True, eq=False)
class World:
    """Everything static in a simulation. ``placeable`` = (x_min, y_min, x_max, y_max), metres, the
    rectangle zebras may be placed in; ``max_slope_deg`` the steepest ground they may stand on.
    ``prototypes`` maps a prototype name to its mesh (vertices (N, 3) float32 m, faces (F, 3) int32,
    per-vertex RGB (N, 3) float32 0..1) in its local frame (base at z = 0); ``vegetation`` has the
    instances of each. ``footprints`` gives tree and rock prototypes' (radius at scale 1, clearance) in
    metres: each instance is an obstacle of radius ``radius * scale + clearance``. ``ground_rgb``
    (optional, (ny, nx, 3)) overrides the colours painted from ``materials``.
    """

    name: str
    source: str
    seed: int | None
    terrain: Heightfield
    placeable: tuple[float, float, float, float]
    max_slope_deg: float
    obstacles: Obstacles
    vegetation: dict[str, Instances]
    prototypes: dict[str, PrototypeMesh]
    materials: tuple[MaterialLayer, ...]
    sky: Sky
    description: str = ""
    footprints: dict[str, tuple[float, float]] = field(default_factory=dict)
    ground_rgb: NDArray[np.float32] | None = None

    def ground_colors(self) -> NDArray[np.float32]:
        """Linear RGB 0..1 of the ground per heightfield sample, (ny, nx, 3) float32, indexed like heights.

        Painted from ``materials`` (or :data:`DEFAULT_MATERIALS`) by height band, slope band and seeded
        noise; deterministic per world seed. For renderers and the USD ``displayColor`` of the terrain.
        """
        if self.ground_rgb is not None:
            return np.array(self.ground_rgb, dtype=np.float32, copy=True)
        canopy = [(inst.positions[:, :2], _canopy_radius(self.prototypes[p]) * inst.scale,
                   1.0 if inst.kind == "tree" else 0.5)
                  for p, inst in self.vegetation.items() if inst.kind in ("tree", "bush") and len(inst)]
        return paint_ground(self.materials or DEFAULT_MATERIALS, self.terrain, self.seed or 0, self.name, canopy)

    def instance_count(self) -> dict[str, int]:
        """Instances per prototype name."""
        return {name: len(inst) for name, inst in self.vegetation.items()}


def _canopy_radius(mesh: PrototypeMesh) -> float:
    v = mesh[0]
    return float(np.max(np.hypot(v[:, 0], v[:, 1]))) if len(v) else 0.0


def _smoothstep(e0: float, e1: float, x: FloatArray) -> FloatArray:
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return np.asarray(t * t * (3 - 2 * t))


def _band(x: FloatArray, band: tuple[float, float], soft: float) -> FloatArray:
    """1 inside [lo, hi], 0 outside, smooth over ``soft`` at each finite edge."""
    w = np.ones_like(x)
    lo, hi = band
    s = max(soft, 1e-6)
    if np.isfinite(lo):
        w *= _smoothstep(lo - s / 2, lo + s / 2, x)
    if np.isfinite(hi):
        w *= 1.0 - _smoothstep(hi - s / 2, hi + s / 2, x)
    return w


def paint_ground(
    materials: tuple[MaterialLayer, ...],
    terrain: Heightfield,
    seed: int,
    name: str,
    canopy: list[tuple[FloatArray, FloatArray, float]] | None = None,
) -> NDArray[np.float32]:
    """Ground RGB (ny, nx, 3) float32 from material layers, painted in order (see :class:`MaterialLayer`).

    ``canopy`` lists (xy (M, 2) m, radius (M,) m, weight) of crowns for layers with pattern "canopy".
    """
    h = terrain.heights.astype(np.float64)
    ny, nx = h.shape
    res = terrain.resolution
    gy, gx = np.gradient(h, res)
    slope = np.degrees(np.arctan(np.hypot(gx, gy)))
    rgb = np.zeros((ny, nx, 3))
    for k, layer in enumerate(materials):
        rng = derive_rng(seed, name, "ground", str(k), layer.name)
        w = np.ones((ny, nx))
        if np.isfinite(layer.height_band[0]) or np.isfinite(layer.height_band[1]):
            jitter = (value_noise((ny, nx), 25.0 / res, rng, octaves=3) - 0.5) * 2 * layer.height_soft_m
            w *= _band(h + jitter, layer.height_band, layer.height_soft_m)
        if layer.slope_band != (0.0, 90.0):
            w *= _band(slope, layer.slope_band, layer.slope_soft_deg)
        tex = value_noise((ny, nx), max(layer.noise_scale_m / res, 1.0), rng, octaves=3)
        base = np.broadcast_to(np.asarray(layer.rgb), (ny, nx, 3))
        if layer.pattern == "fields":
            layout = patchwork(terrain.bounds, layer.patch_scale_m, derive_rng(seed, name, "fields"))
            xs = terrain.origin[0] + np.arange(nx) * res
            ys = terrain.origin[1] + np.arange(ny) * res
            gxm, gym = np.meshgrid(xs, ys)
            ids = layout.cell_ids(gxm, gym)
            pal = np.asarray(layer.palette)
            pick = derive_rng(seed, name, "field_colours").integers(0, len(pal), int(ids.max()) + 1)
            u, _ = layout.to_uv(gxm, gym)
            rows = 1.0 + 0.06 * np.sin(2 * np.pi * u / 2.5) * (pick[ids] % 2 == 0)  # plough rows on some fields
            base = pal[pick[ids]] * rows[..., None]
        elif layer.pattern == "canopy":
            mask = np.zeros((ny, nx), dtype=bool)
            cover = np.zeros((ny, nx))
            for xy, radius, weight in canopy or []:
                mask[:] = False
                stamp_discs(mask, terrain, xy, radius * 1.1)
                cover = np.maximum(cover, weight * mask)
            cover = box_blur(cover, max(1, int(round(2.0 / res))))
            w *= np.clip(cover * (0.6 + 0.8 * value_noise((ny, nx), 8.0 / res, rng)), 0, 1)
        if layer.coverage < 1 and layer.pattern != "canopy":
            n = value_noise((ny, nx), layer.patch_scale_m / res, rng, octaves=3)
            thr = float(np.quantile(n, 1.0 - layer.coverage))
            w *= _smoothstep(thr - 0.05, thr + 0.05, n)
        elif layer.pattern == "canopy":
            w *= layer.coverage
        w *= layer.opacity
        col = base * (1.0 + layer.contrast * (2.0 * tex - 1.0))[..., None]
        rgb += (col - rgb) * w[..., None]
    return np.clip(rgb, 0, 1).astype(np.float32)


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
        present = _smoothstep(0.35, 0.55, value_noise((n, n), t.gully_wavelength_m / res, rng, octaves=2))
        h = h - t.gully_depth_m * profile * present
    zone = np.maximum(np.abs(x), np.abs(y))
    inner = t.flat_zone_m / 2
    w = t.flat_factor + (1 - t.flat_factor) * _smoothstep(inner, inner + t.flat_transition_m, zone)
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


def build_obstacles(vegetation: dict[str, Instances], radius_at: dict[str, tuple[float, float]]) -> Obstacles:
    """Obstacles from tree and rock instances; ``radius_at[name]`` = (radius at scale 1, clearance) m."""
    pos, rad, kinds = [], [], []
    for name in sorted(vegetation):
        inst = vegetation[name]
        if inst.kind not in ("tree", "rock") or name not in radius_at or not len(inst):
            continue
        r1, clearance = radius_at[name]
        pos.append(inst.positions)
        rad.append(r1 * inst.scale + clearance)
        kinds += [inst.kind] * len(inst)
    if not pos:
        return Obstacles.empty()
    return Obstacles(np.concatenate(pos), np.concatenate(rad), tuple(kinds))


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
    from zebra_sim_ros.world.usd_io import read_world_usd

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
