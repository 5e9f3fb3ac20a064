"""Seeded noise for worlds: spectral (FFT power-law) fractal fields, value noise, field patchworks.

Every function takes a ``numpy.random.Generator``; :func:`derive_rng` makes one per purpose from the
world seed, so adding a draw for one purpose never shifts the numbers another purpose sees.
Grids are indexed ``[j, i]`` = ``(y, x)`` like :class:`~zebra_sim_ros.world.terrain.Heightfield`.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.errors import ParameterError

FloatArray = NDArray[np.float64]


def derive_rng(seed: int, *tags: str) -> np.random.Generator:
    """A generator for one purpose (``tags``, e.g. ``("savanna", "terrain")``) of the world ``seed`` (>= 0).

    The tags are hashed with CRC-32 (stable across runs and platforms, unlike ``hash``).
    """
    if seed < 0:
        raise ParameterError("seed", seed, "an integer >= 0")
    return np.random.default_rng([int(seed), *(zlib.crc32(t.encode()) for t in tags)])


def smoothstep(e0: float, e1: float, x: FloatArray) -> FloatArray:
    """0 below ``e0``, 1 above ``e1``, the cubic 3t^2 - 2t^3 between (``e1 < e0`` runs it backwards)."""
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return np.asarray(t * t * (3 - 2 * t))


def _fft_size(n: int) -> int:
    """Smallest 2^a * 3^b >= n (fast FFT lengths)."""
    best = 1 << int(np.ceil(np.log2(n)))
    p3 = 1
    while p3 < best:
        p2 = p3
        while p2 < n:
            p2 *= 2
        best = min(best, p2)
        p3 *= 3
    return best


def spectral_noise(
    shape: tuple[int, int],
    resolution: float,
    rng: np.random.Generator,
    exponent: float,
    min_wavelength_m: float,
    max_wavelength_m: float,
) -> FloatArray:
    """Fractal Gaussian field (ny, nx) with power spectrum ~ k^-exponent, zero mean, unit std.

    ``resolution`` is metres per sample. Wavelengths longer than ``max_wavelength_m`` are rolled off
    (no huge tilt) and those shorter than ``min_wavelength_m`` damped (no 1-sample jaggies). The field
    is synthesised on a grid about 1.6x larger and cropped, so opposite edges are not periodic copies.
    ``exponent`` ~ 2H + 2: 3 gives natural rolling relief, lower is rougher.
    """
    ny, nx = shape
    p = _fft_size(int(np.ceil(1.6 * max(ny, nx))))
    white = rng.standard_normal((p, p))
    ky = np.fft.fftfreq(p, d=resolution)[:, None]
    kx = np.fft.rfftfreq(p, d=resolution)[None, :]
    k2 = kx * kx + ky * ky
    k0 = 1.0 / max_wavelength_m
    amp = (k2 + k0 * k0) ** (-exponent / 4.0) * np.exp(-k2 * (min_wavelength_m / 2.0) ** 2)
    amp[0, 0] = 0.0
    field = np.fft.irfft2(np.fft.rfft2(white) * amp, s=(p, p))
    oy, ox = int(rng.integers(0, p - ny + 1)), int(rng.integers(0, p - nx + 1))
    out = field[oy:oy + ny, ox:ox + nx]
    out = out - out.mean()
    std = float(out.std())
    return np.asarray(out / std if std > 0 else out)


def value_noise(shape: tuple[int, int], cell: float, rng: np.random.Generator, octaves: int = 1,
                persistence: float = 0.5) -> FloatArray:
    """Smooth value noise (ny, nx) in [0, 1]: random lattice every ``cell`` samples, smoothstep blend.

    With ``octaves`` > 1 finer copies (cell / 2, / 4, ...) are added with weights ``persistence**o``
    and the sum rescaled to [0, 1]. Cheap: for material textures and density masks, not terrain.
    """
    ny, nx = shape
    total = np.zeros(shape)
    weight = 0.0
    for o in range(octaves):
        c = max(cell / (2 ** o), 1.0)
        gy, gx = int(np.ceil(ny / c)) + 2, int(np.ceil(nx / c)) + 2
        lattice = rng.random((gy, gx))
        fy = np.arange(ny) / c + rng.random()
        fx = np.arange(nx) / c + rng.random()
        iy, ix = np.floor(fy).astype(np.int64), np.floor(fx).astype(np.int64)
        ty, tx = fy - iy, fx - ix
        ty, tx = (ty * ty * (3 - 2 * ty))[:, None], (tx * tx * (3 - 2 * tx))[None, :]
        a = lattice[np.ix_(iy, ix)]
        b = lattice[np.ix_(iy, ix + 1)]
        c_ = lattice[np.ix_(iy + 1, ix)]
        d = lattice[np.ix_(iy + 1, ix + 1)]
        w = persistence ** o
        total += w * ((1 - ty) * ((1 - tx) * a + tx * b) + ty * ((1 - tx) * c_ + tx * d))
        weight += w
    total /= weight
    lo, hi = float(total.min()), float(total.max())
    return np.asarray((total - lo) / (hi - lo) if hi > lo else total * 0 + 0.5)


def box_blur(a: FloatArray, radius: int) -> FloatArray:
    """Mean over a (2r+1)^2 window (edges clamped), by cumulative sums: O(n) for any radius."""
    if radius <= 0:
        return np.asarray(a, dtype=np.float64)
    out = np.asarray(a, dtype=np.float64)
    for axis in (0, 1):
        pad = [(0, 0), (0, 0)]
        pad[axis] = (radius + 1, radius)
        c = np.cumsum(np.pad(out, pad, mode="edge"), axis=axis)
        n = out.shape[axis]
        hi = np.take(c, np.arange(2 * radius + 1, 2 * radius + 1 + n), axis=axis)
        lo = np.take(c, np.arange(0, n), axis=axis)
        out = (hi - lo) / (2 * radius + 1)
    return out


@dataclass(frozen=True)
class Patchwork:
    """Rectangular fields in a frame rotated by ``angle`` (radians, about ``centre``) — farmland layouts.

    ``u_edges`` / ``v_edges`` are the field boundaries (metres) along the rotated axes
    u = R(-angle) (p - centre). Field (a, b) spans ``u_edges[a]..u_edges[a+1]`` x ``v_edges[b]..v_edges[b+1]``.
    """

    centre: tuple[float, float]
    angle: float
    u_edges: FloatArray
    v_edges: FloatArray

    def to_uv(self, x: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Map-frame (x, y) to field-frame (u, v), metres."""
        c, s = np.cos(self.angle), np.sin(self.angle)
        dx, dy = np.asarray(x) - self.centre[0], np.asarray(y) - self.centre[1]
        return c * dx + s * dy, -s * dx + c * dy

    def to_xy(self, u: FloatArray, v: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Field-frame (u, v) to map-frame (x, y), metres."""
        c, s = np.cos(self.angle), np.sin(self.angle)
        return self.centre[0] + c * u - s * v, self.centre[1] + s * u + c * v

    def cell_ids(self, x: FloatArray, y: FloatArray) -> NDArray[np.int64]:
        """Field index of each point (a * len(v_edges) + b); stable per layout."""
        u, v = self.to_uv(x, y)
        a = np.clip(np.searchsorted(self.u_edges, u) - 1, 0, len(self.u_edges) - 2)
        b = np.clip(np.searchsorted(self.v_edges, v) - 1, 0, len(self.v_edges) - 2)
        return np.asarray(a * len(self.v_edges) + b, dtype=np.int64)

    def boundary_segments(self) -> FloatArray:
        """Every field side as a segment (K, 2, 2): [[u0, v0], [u1, v1]] in the field frame, metres."""
        segs = []
        for u in self.u_edges:
            for v0, v1 in zip(self.v_edges[:-1], self.v_edges[1:], strict=True):
                segs.append([[u, v0], [u, v1]])
        for v in self.v_edges:
            for u0, u1 in zip(self.u_edges[:-1], self.u_edges[1:], strict=True):
                segs.append([[u0, v], [u1, v]])
        return np.asarray(segs, dtype=np.float64)


def patchwork(bounds: tuple[float, float, float, float], mean_size_m: float, rng: np.random.Generator) -> Patchwork:
    """A random field layout covering ``bounds`` (x_min, y_min, x_max, y_max): sides U(0.6, 1.4) x mean size."""
    x0, y0, x1, y1 = bounds
    centre = ((x0 + x1) / 2, (y0 + y1) / 2)
    angle = float(rng.uniform(-np.pi / 6, np.pi / 6))
    half = 0.5 * float(np.hypot(x1 - x0, y1 - y0))

    def edges() -> FloatArray:
        e = [-half - float(rng.uniform(0, mean_size_m))]
        while e[-1] < half:
            e.append(e[-1] + float(rng.uniform(0.6, 1.4)) * mean_size_m)
        return np.asarray(e)

    return Patchwork(centre, angle, edges(), edges())
