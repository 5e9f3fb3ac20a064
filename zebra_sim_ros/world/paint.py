"""Ground colours of a world, painted from its material layers (:class:`~zebra_sim_ros.world.presets.MaterialLayer`).

Grids are indexed ``[j, i]`` = ``(y, x)`` like :class:`~zebra_sim_ros.world.terrain.Heightfield`; colours are
linear RGB 0..1.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.world.noise import box_blur, derive_rng, patchwork, smoothstep, value_noise
from zebra_sim_ros.world.presets import MaterialLayer
from zebra_sim_ros.world.terrain import Heightfield
from zebra_sim_ros.world.vegetation import stamp_discs

FloatArray = NDArray[np.float64]


def _band(x: FloatArray, band: tuple[float, float], soft: float) -> FloatArray:
    """1 inside [lo, hi], 0 outside, smooth over ``soft`` at each finite edge."""
    w = np.ones_like(x)
    lo, hi = band
    s = max(soft, 1e-6)
    if np.isfinite(lo):
        w *= smoothstep(lo - s / 2, lo + s / 2, x)
    if np.isfinite(hi):
        w *= 1.0 - smoothstep(hi - s / 2, hi + s / 2, x)
    return w


def _field_colours(layer: MaterialLayer, terrain: Heightfield, seed: int, name: str) -> FloatArray:
    """(ny, nx, 3) colours of a "fields" layer: one palette colour per field, plough rows on some fields."""
    ny, nx = terrain.heights.shape
    res = terrain.resolution
    layout = patchwork(terrain.bounds, layer.patch_scale_m, derive_rng(seed, name, "fields"))
    xs = terrain.origin[0] + np.arange(nx) * res
    ys = terrain.origin[1] + np.arange(ny) * res
    gxm, gym = np.meshgrid(xs, ys)
    ids = layout.cell_ids(gxm, gym)
    pal = np.asarray(layer.palette)
    pick = derive_rng(seed, name, "field_colours").integers(0, len(pal), int(ids.max()) + 1)
    u, _ = layout.to_uv(gxm, gym)
    rows = 1.0 + 0.06 * np.sin(2 * np.pi * u / 2.5) * (pick[ids] % 2 == 0)  # plough rows on some fields
    return np.asarray(pal[pick[ids]] * rows[..., None])


def _track_cover(layer: MaterialLayer, terrain: Heightfield, rng: np.random.Generator) -> FloatArray:
    """(ny, nx) 0..1: pairs of ruts ``track_width_m`` apart along the winding mid-level lines of a smooth noise
    (lines about ``patch_scale_m`` apart), each rut about a third of that width, with a worn strip between."""
    ny, nx = terrain.heights.shape
    res = terrain.resolution
    n = value_noise((ny, nx), layer.patch_scale_m / res, rng, octaves=2)
    gy, gx = np.gradient(n, res)
    dist = np.abs(n - 0.5) / (np.hypot(gx, gy) + 1e-9)  # metres to the line
    half = layer.track_width_m / 2
    rut = np.exp(-(((dist - half) / (0.22 * half + 0.5 * res)) ** 2))
    worn = 0.35 * (1.0 - smoothstep(0.5 * half, 1.2 * half, dist))
    present = smoothstep(0.3, 0.45, value_noise((ny, nx), 2.5 * layer.patch_scale_m / res, rng, octaves=2))
    return np.asarray(np.clip(np.maximum(rut, worn) * present, 0.0, 1.0))


def _canopy_cover(terrain: Heightfield, canopy: list[tuple[FloatArray, FloatArray, float]] | None) -> FloatArray:
    """(ny, nx) 0..1: how much crowns cover each sample (discs 1.1x the crown, weighted, blurred over 2 m)."""
    ny, nx = terrain.heights.shape
    mask = np.zeros((ny, nx), dtype=bool)
    cover = np.zeros((ny, nx))
    for xy, radius, weight in canopy or []:
        mask[:] = False
        stamp_discs(mask, terrain, xy, radius * 1.1)
        cover = np.maximum(cover, weight * mask)
    return box_blur(cover, max(1, int(round(2.0 / terrain.resolution))))


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
            base = _field_colours(layer, terrain, seed, name)
        elif layer.pattern == "tracks":
            w *= _track_cover(layer, terrain, rng)
        elif layer.pattern == "canopy":
            cover = _canopy_cover(terrain, canopy)
            w *= np.clip(cover * (0.6 + 0.8 * value_noise((ny, nx), 8.0 / res, rng)), 0, 1)
        if layer.coverage < 1 and layer.pattern not in ("canopy", "tracks"):
            n = value_noise((ny, nx), layer.patch_scale_m / res, rng, octaves=3)
            thr = float(np.quantile(n, 1.0 - layer.coverage))
            w *= smoothstep(thr - 0.05, thr + 0.05, n)
        elif layer.pattern == "canopy":
            w *= layer.coverage
        w *= layer.opacity
        col = base * (1.0 + layer.contrast * (2.0 * tex - 1.0))[..., None]
        rgb += (col - rgb) * w[..., None]
    return np.clip(rgb, 0, 1).astype(np.float32)
