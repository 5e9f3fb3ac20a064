"""A regular-grid terrain heightfield: height and normal look-ups, mesh conversion both ways.

``heights[j, i]`` is the ground height (metres, ``map`` frame, z up) at
``x = origin_x + i * resolution``, ``y = origin_y + j * resolution``. Between samples the
ground is bilinear, which is also what the triangle mesh shows to within the diagonal split.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zebra_sim_ros.errors import ParameterError, ZebraSimError

FloatArray = NDArray[np.float64]


class TerrainError(ZebraSimError):
    """A terrain is unusable (empty, not a surface one can stand on, outside its bounds)."""


@dataclass(frozen=True)
class Heightfield:
    """Ground heights on a regular grid (see the module docstring for the indexing)."""

    origin: tuple[float, float]
    resolution: float
    heights: NDArray[np.float32]

    def __post_init__(self) -> None:
        if self.resolution <= 0:
            raise ParameterError("heightfield.resolution", self.resolution, "> 0 m")
        if self.heights.ndim != 2 or min(self.heights.shape) < 2:
            raise ParameterError("heightfield.heights", self.heights.shape, "a 2D grid of at least 2x2")
        if not np.all(np.isfinite(self.heights)):
            raise TerrainError("heightfield has non-finite heights")

    @property
    def shape(self) -> tuple[int, int]:
        """(ny, nx) samples."""
        return (int(self.heights.shape[0]), int(self.heights.shape[1]))

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(x_min, y_min, x_max, y_max) in metres."""
        ny, nx = self.shape
        x0, y0 = self.origin
        return (x0, y0, x0 + (nx - 1) * self.resolution, y0 + (ny - 1) * self.resolution)

    def _cell(self, x: ArrayLike, y: ArrayLike) -> tuple[NDArray[np.int64], NDArray[np.int64], FloatArray, FloatArray]:
        ny, nx = self.shape
        fx = (np.asarray(x, dtype=np.float64) - self.origin[0]) / self.resolution
        fy = (np.asarray(y, dtype=np.float64) - self.origin[1]) / self.resolution
        fx = np.clip(fx, 0.0, nx - 1.0)
        fy = np.clip(fy, 0.0, ny - 1.0)
        i = np.minimum(np.floor(fx).astype(np.int64), nx - 2)
        j = np.minimum(np.floor(fy).astype(np.int64), ny - 2)
        return i, j, fx - i, fy - j

    def height_at(self, x: ArrayLike, y: ArrayLike) -> FloatArray:
        """Bilinear ground height at (x, y); points outside are clamped to the border."""
        i, j, tx, ty = self._cell(x, y)
        h = self.heights
        return np.asarray(
            (1 - ty) * ((1 - tx) * h[j, i] + tx * h[j, i + 1]) + ty * ((1 - tx) * h[j + 1, i] + tx * h[j + 1, i + 1]),
            dtype=np.float64,
        )

    def gradient_at(self, x: ArrayLike, y: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """(dh/dx, dh/dy) of the bilinear surface at (x, y)."""
        i, j, tx, ty = self._cell(x, y)
        h = self.heights.astype(np.float64)
        r = self.resolution
        dx = ((1 - ty) * (h[j, i + 1] - h[j, i]) + ty * (h[j + 1, i + 1] - h[j + 1, i])) / r
        dy = ((1 - tx) * (h[j + 1, i] - h[j, i]) + tx * (h[j + 1, i + 1] - h[j, i + 1])) / r
        return np.asarray(dx), np.asarray(dy)

    def normal_at(self, x: ArrayLike, y: ArrayLike) -> FloatArray:
        """Unit upward normals (..., 3) at (x, y)."""
        dx, dy = self.gradient_at(x, y)
        n = np.stack([-dx, -dy, np.ones_like(dx)], axis=-1)
        return np.asarray(n / np.linalg.norm(n, axis=-1, keepdims=True))

    def slope_deg(self, x: ArrayLike, y: ArrayLike) -> FloatArray:
        """Slope angle in degrees at (x, y)."""
        n = self.normal_at(x, y)
        return np.asarray(np.degrees(np.arccos(np.clip(n[..., 2], -1.0, 1.0))))

    def contains(self, x: ArrayLike, y: ArrayLike) -> NDArray[np.bool_]:
        """Whether (x, y) lies within the grid."""
        x0, y0, x1, y1 = self.bounds
        xa, ya = np.asarray(x), np.asarray(y)
        return np.asarray((xa >= x0) & (xa <= x1) & (ya >= y0) & (ya <= y1))

    def to_mesh(self, step: int = 1) -> tuple[NDArray[np.float32], NDArray[np.int32]]:
        """Triangle mesh of the grid (every ``step``-th sample): vertices (N, 3), faces (F, 3), CCW from above."""
        h = self.heights[::step, ::step]
        ny, nx = h.shape
        xs = self.origin[0] + np.arange(nx) * self.resolution * step
        ys = self.origin[1] + np.arange(ny) * self.resolution * step
        gx, gy = np.meshgrid(xs, ys)
        verts = np.stack([gx, gy, h], axis=-1).reshape(-1, 3).astype(np.float32)
        idx = np.arange(ny * nx).reshape(ny, nx)
        a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
        c, d = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
        faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]).astype(np.int32)
        return verts, faces

    @classmethod
    def from_mesh(cls, vertices: ArrayLike, faces: ArrayLike, resolution: float = 1.0) -> Heightfield:
        """Sample any triangle mesh from above onto a grid (highest surface wins).

        Grid cells no triangle covers take the height of the nearest covered cell, so a terrain with
        holes still gives heights everywhere inside its bounds. Raises :class:`TerrainError` for a mesh
        with no upward-visible area.
        """
        v = np.asarray(vertices, dtype=np.float64)
        f = np.asarray(faces, dtype=np.int64)
        if v.ndim != 2 or v.shape[1] != 3 or len(v) < 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
            raise TerrainError(f"terrain mesh needs vertices (N, 3) and triangles (F, 3); got {v.shape}, {f.shape}")
        lo, hi = v[:, :2].min(axis=0), v[:, :2].max(axis=0)
        nx = int(np.floor((hi[0] - lo[0]) / resolution)) + 1
        ny = int(np.floor((hi[1] - lo[1]) / resolution)) + 1
        if nx < 2 or ny < 2:
            raise TerrainError(f"terrain mesh spans {hi - lo} m, less than two samples at {resolution} m")
        heights = np.full((ny, nx), -np.inf)
        tri = v[f]
        p0, p1, p2 = tri[:, 0], tri[:, 1], tri[:, 2]
        den = (p1[:, 1] - p2[:, 1]) * (p0[:, 0] - p2[:, 0]) + (p2[:, 0] - p1[:, 0]) * (p0[:, 1] - p2[:, 1])
        keep = np.abs(den) > 1e-12
        tri, den = tri[keep], den[keep]
        imin = np.ceil((tri[:, :, 0].min(axis=1) - lo[0]) / resolution - 1e-9).astype(np.int64)
        imax = np.floor((tri[:, :, 0].max(axis=1) - lo[0]) / resolution + 1e-9).astype(np.int64)
        jmin = np.ceil((tri[:, :, 1].min(axis=1) - lo[1]) / resolution - 1e-9).astype(np.int64)
        jmax = np.floor((tri[:, :, 1].max(axis=1) - lo[1]) / resolution + 1e-9).astype(np.int64)
        span = np.maximum(imax - imin, jmax - jmin) + 1
        # Triangles grouped by footprint size: each group tests a fixed window of cells at once.
        for w in np.unique(np.clip(2 ** np.ceil(np.log2(np.maximum(span, 1))), 1, None)).astype(np.int64):
            sel = np.nonzero((span <= w) & (span > w // 2) | ((w == 1) & (span <= 1)))[0]
            for s in range(0, len(sel), max(1, 2_000_000 // (w * w))):
                part = sel[s:s + max(1, 2_000_000 // (w * w))]
                oi, oj = np.meshgrid(np.arange(w), np.arange(w), indexing="ij")
                ci = imin[part, None] + oi.ravel()[None, :]
                cj = jmin[part, None] + oj.ravel()[None, :]
                px = lo[0] + ci * resolution
                py = lo[1] + cj * resolution
                t = tri[part]
                d = den[part, None]
                l0 = ((t[:, 1, 1] - t[:, 2, 1])[:, None] * (px - t[:, 2, 0, None])
                      + (t[:, 2, 0] - t[:, 1, 0])[:, None] * (py - t[:, 2, 1, None])) / d
                l1 = ((t[:, 2, 1] - t[:, 0, 1])[:, None] * (px - t[:, 2, 0, None])
                      + (t[:, 0, 0] - t[:, 2, 0])[:, None] * (py - t[:, 2, 1, None])) / d
                l2 = 1 - l0 - l1
                eps = -1e-9
                inside = (l0 >= eps) & (l1 >= eps) & (l2 >= eps) & (ci <= imax[part, None]) & (cj <= jmax[part, None])
                inside &= (ci >= 0) & (ci < nx) & (cj >= 0) & (cj < ny)
                z = l0 * t[:, 0, 2, None] + l1 * t[:, 1, 2, None] + l2 * t[:, 2, 2, None]
                np.maximum.at(heights, (cj[inside], ci[inside]), z[inside])
        covered = np.isfinite(heights)
        if not covered.any():
            raise TerrainError("terrain mesh covers no grid sample seen from above")
        if not covered.all():
            heights = _fill_nearest(heights, covered)
        return cls((float(lo[0]), float(lo[1])), float(resolution), heights.astype(np.float32))


def _fill_nearest(h: FloatArray, covered: NDArray[np.bool_]) -> FloatArray:
    """Fill uncovered cells by repeated 4-neighbour propagation (terrains have few, small holes)."""
    h = h.copy()
    known = covered.copy()
    while not known.all():
        grown = h.copy()
        k = known.copy()
        for axis, shift in ((0, 1), (0, -1), (1, 1), (1, -1)):
            src_h = np.roll(h, shift, axis=axis)
            src_k = np.roll(known, shift, axis=axis)
            if axis == 0:
                if shift == 1:
                    src_k[0, :] = False
                else:
                    src_k[-1, :] = False
            elif shift == 1:
                src_k[:, 0] = False
            else:
                src_k[:, -1] = False
            take = ~k & src_k
            grown[take] = src_h[take]
            k |= take
        h, known = grown, k
    return h
