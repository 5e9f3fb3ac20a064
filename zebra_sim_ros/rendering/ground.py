"""What the ground shader needs besides colour: surface classes per terrain sample and contact shadows.

Pure numpy (no GL), so both are tested without a context. The shader (``shaders.TERRAIN_FS``) turns the
surface weights into procedural detail at every scale: grass tufts and blades, soil grain, pebbles and
cracks, rock plates and wet mud. Contact shadows darken the ground under each animal where the sun's
shadow map cannot (ambient occlusion of the light from the sky: under the belly, between the hooves), and the
vegetation's occlusion does the same under every tree and bush.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.world.world import World

FloatArray = NDArray[np.float64]
SURFACES = ("grass", "soil", "rock", "wet")  # the four channels of a surface map, in order


def surface_from_colours(rgb: NDArray[np.float32]) -> NDArray[np.float32]:
    """Surface weights (ny, nx, 4) from ground colours (linear RGB) where a world brings no surface classes:
    green and yellow-green ground is grass, grey-brown ground soil, dark ground wet; the weights sum to 1."""
    c = np.asarray(rgb, dtype=np.float32)
    r, g, b = c[..., 0], c[..., 1], c[..., 2]
    lum = 0.2126 * r + 0.7152 * g + 0.0722 * b
    greenness = np.clip((g - 0.5 * (r + b)) / np.maximum(lum, 1e-3) * 3.0 + 0.35, 0.0, 1.0)
    wet = np.clip((0.02 - lum) / 0.02, 0.0, 1.0) * 0.7
    grass = greenness * (1.0 - wet)
    soil = (1.0 - greenness) * (1.0 - wet)
    out = np.stack([grass, soil, np.zeros_like(grass), wet], axis=-1)
    return np.ascontiguousarray(out / np.maximum(out.sum(axis=-1, keepdims=True), 1e-6), dtype=np.float32)


@dataclass(frozen=True)
class ContactMap:
    """Ground darkening factors (ny, nx) float32 in 0..1 (1 = no occlusion) over the rectangle that starts at
    ``origin`` (map x, y, m) with ``resolution`` m per texel; ``xform`` is what the shader wants."""

    values: NDArray[np.float32]
    origin: tuple[float, float]
    resolution: float

    @property
    def xform(self) -> tuple[float, float, float, float]:
        """(origin x, origin y, 1/width m, 1/height m)."""
        ny, nx = self.values.shape
        return (self.origin[0], self.origin[1], 1.0 / (nx * self.resolution), 1.0 / (ny * self.resolution))


def contact_map(position: FloatArray, forward: FloatArray, scale: FloatArray, max_texels: int = 1024,
                strength: float = 0.55) -> ContactMap:
    """Soft elliptical occlusion under each animal: ``position`` (N, 3) feet centres, ``forward`` (N, 2) unit
    body axes in the ground plane, ``scale`` (N,) body scale (1 = an adult zebra, 2.4 m long). The map covers all
    animals with a margin; its resolution is the finest that keeps it within ``max_texels`` per side (at least
    0.05 m). An empty herd gives a 1x1 map of ones."""
    if len(position) == 0:
        return ContactMap(np.ones((1, 1), dtype=np.float32), (0.0, 0.0), 1.0)
    xy = np.asarray(position, dtype=np.float64)[:, :2]
    s = np.asarray(scale, dtype=np.float64)
    margin = 2.0 * float(s.max()) + 1.0
    lo, hi = xy.min(axis=0) - margin, xy.max(axis=0) + margin
    res = max(0.05, float((hi - lo).max()) / max_texels)
    nx, ny = (int(np.ceil((hi - lo)[k] / res)) for k in (0, 1))
    occl = np.zeros((ny, nx), dtype=np.float32)
    fwd = np.asarray(forward, dtype=np.float64)
    for p, f, sc in zip(xy, fwd, s, strict=True):
        half_len, half_wid = 1.15 * sc, 0.45 * sc
        r = int(np.ceil((half_len * 1.6) / res))
        ci, cj = int((p[0] - lo[0]) / res), int((p[1] - lo[1]) / res)
        i0, i1, j0, j1 = max(ci - r, 0), min(ci + r + 1, nx), max(cj - r, 0), min(cj + r + 1, ny)
        if i0 >= i1 or j0 >= j1:
            continue
        gx = lo[0] + (np.arange(i0, i1) + 0.5) * res - p[0]
        gy = lo[1] + (np.arange(j0, j1) + 0.5) * res - p[1]
        dx, dy = np.meshgrid(gx, gy)
        along = dx * f[0] + dy * f[1]
        across = -dx * f[1] + dy * f[0]
        q = (along / half_len) ** 2 + (across / half_wid) ** 2
        blob = np.exp(-1.6 * q).astype(np.float32)
        occl[j0:j1, i0:i1] = np.maximum(occl[j0:j1, i0:i1], blob)
    values = np.ascontiguousarray(1.0 - strength * occl, dtype=np.float32)
    return ContactMap(values, (float(lo[0]), float(lo[1])), res)


def vegetation_occlusion(world: World, strength: float = 0.45) -> NDArray[np.float32]:
    """Ambient occlusion of the ground under trees and bushes, over the terrain grid (ny, nx), 1 = open sky: a
    soft disc of the plant's crown radius (its prototype's horizontal extent times its scale) darkening the
    ground by up to ``strength``, what a crown hides of the sky. Computed once per world (plants do not move)."""
    t = world.terrain
    ny, nx = t.heights.shape
    occl = np.zeros((ny, nx), dtype=np.float32)
    for name, inst in world.vegetation.items():
        if inst.kind not in ("tree", "bush") or not len(inst) or name not in world.prototypes:
            continue
        v = np.asarray(world.prototypes[name][0], dtype=np.float64)
        crown = float(np.max(np.hypot(v[:, 0], v[:, 1])))
        for p, sc in zip(inst.positions, inst.scale, strict=True):
            r = crown * float(sc)
            k = int(np.ceil(1.5 * r / t.resolution))
            ci, cj = (int(round((p[a] - t.origin[a]) / t.resolution)) for a in (0, 1))
            i0, i1, j0, j1 = max(ci - k, 0), min(ci + k + 1, nx), max(cj - k, 0), min(cj + k + 1, ny)
            if i0 >= i1 or j0 >= j1:
                continue
            gx = t.origin[0] + np.arange(i0, i1) * t.resolution - p[0]
            gy = t.origin[1] + np.arange(j0, j1) * t.resolution - p[1]
            d2 = (gx[None, :] ** 2 + gy[:, None] ** 2) / (r * r)
            blob = np.exp(-1.4 * d2).astype(np.float32)
            occl[j0:j1, i0:i1] = np.maximum(occl[j0:j1, i0:i1], blob)
    return 1.0 - strength * occl
