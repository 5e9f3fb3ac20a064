"""Procedural vegetation and rocks: prototype meshes and seeded scattering over a terrain.

Prototype meshes are in a local frame: metres, z up, the ground contact at z = 0 (trunks and rock
bottoms reach a little below z = 0 so they stay grounded on slopes); colours are linear RGB 0..1.
Faces are CCW seen from outside; grass blades are two-sided (both windings). Every instance is that
mesh rotated by ``yaw`` about +z, scaled uniformly by ``scale`` and moved to ``position`` (map frame,
z = terrain height there).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.world.noise import Patchwork, derive_rng, patchwork, value_noise
from zebra_sim_ros.world.presets import STYLES, Rgb, VegetationLayer, WorldPreset, srgb
from zebra_sim_ros.world.terrain import Heightfield

FloatArray = NDArray[np.float64]
PrototypeMesh = tuple[NDArray[np.float32], NDArray[np.int32], NDArray[np.float32]]

MAX_GRASS_TUFTS = 60_000
TREE_CLEARANCE_M = 0.3  # a zebra keeps this far from a trunk, on top of the trunk radius


@dataclass(frozen=True)
class Prototype:
    """One vegetation/rock mesh. ``footprint_m``: trunk radius (trees) or ground radius (rocks) at scale 1."""

    name: str
    kind: str
    style: str
    mesh: PrototypeMesh
    footprint_m: float

    def obstacle_radius(self, scale: FloatArray) -> FloatArray:
        """Radius (metres) a standing zebra must keep out of, per instance scale; 0 for bushes and grass."""
        s = np.asarray(scale, dtype=np.float64)
        if self.kind == "tree":
            return self.footprint_m * s + TREE_CLEARANCE_M
        if self.kind in ("rock", "prop"):
            return self.footprint_m * s
        return np.zeros_like(s)


# --- mesh building blocks -------------------------------------------------------------------------

@lru_cache(maxsize=8)
def _icosphere(subdiv: int) -> tuple[FloatArray, NDArray[np.int64]]:
    t = (1 + 5 ** 0.5) / 2
    v = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
         [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
         [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11],
         [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    verts = [np.asarray(p, dtype=np.float64) / np.linalg.norm(p) for p in v]
    faces = f
    for _ in range(subdiv):
        cache: dict[tuple[int, int], int] = {}
        new = []
        for tri in faces:
            mids = []
            for a, b in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])):
                key = (min(a, b), max(a, b))
                if key not in cache:
                    m = verts[a] + verts[b]
                    verts.append(m / np.linalg.norm(m))
                    cache[key] = len(verts) - 1
                mids.append(cache[key])
            (a, b, c), (ab, bc, ca) = tri, mids
            new += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        faces = new
    return np.asarray(verts), np.asarray(faces, dtype=np.int64)


def _lumps(dirs: FloatArray, rng: np.random.Generator, amp: float, freq: float, waves: int = 5) -> FloatArray:
    """Smooth random radial factor 1 + amp * sum of plane waves over unit directions (N, 3)."""
    k = rng.standard_normal((waves, 3))
    k /= np.linalg.norm(k, axis=1, keepdims=True)
    ph = rng.uniform(0, 2 * np.pi, waves)
    a = rng.uniform(0.5, 1.0, waves)
    s = (np.sin(freq * dirs @ k.T + ph) * a).sum(axis=1) / a.sum()
    return np.asarray(1.0 + amp * s)


def _blob(centre: FloatArray, radii: FloatArray, rng: np.random.Generator, subdiv: int = 2, amp: float = 0.15,
          freq: float = 2.5) -> tuple[FloatArray, NDArray[np.int64]]:
    """Deformed ellipsoid: an icosphere scaled by ``radii`` with smooth random lumps."""
    d, f = _icosphere(subdiv)
    v = d * _lumps(d, rng, amp, freq)[:, None] * radii + centre
    return v, f


def _tube(a: FloatArray, b: FloatArray, r0: float, r1: float, n: int = 7) -> tuple[FloatArray, NDArray[np.int64]]:
    """Open tapered cylinder from point ``a`` (radius r0) to ``b`` (radius r1), outward faces."""
    d = (b - a) / np.linalg.norm(b - a)
    u = np.cross(d, [0.0, 0.0, 1.0] if abs(d[2]) < 0.9 else [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(d, u)
    th = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = np.cos(th)[:, None] * u + np.sin(th)[:, None] * w
    v = np.concatenate([a + r0 * ring, b + r1 * ring])
    k = np.arange(n)
    k1 = (k + 1) % n
    f = np.concatenate([np.stack([k, k1, n + k1], 1), np.stack([k, n + k1, n + k], 1)])
    return v, f


def _cone(z0: float, z1: float, r: float, n: int, centre: FloatArray) -> tuple[FloatArray, NDArray[np.int64]]:
    """Closed cone: base ring radius ``r`` at z0 around ``centre`` (x, y), apex at z1."""
    th = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = np.stack([centre[0] + r * np.cos(th), centre[1] + r * np.sin(th), np.full(n, z0)], 1)
    v = np.concatenate([ring, [[centre[0], centre[1], z1], [centre[0], centre[1], z0]]])
    k = np.arange(n)
    k1 = (k + 1) % n
    f = np.concatenate([np.stack([k, k1, np.full(n, n)], 1), np.stack([np.full(n, n + 1), k1, k], 1)])
    return v, f


class _Builder:
    """Accumulates parts (vertices, faces, per-vertex colours) into one mesh."""

    def __init__(self, rng: np.random.Generator) -> None:
        self.rng = rng
        self.v: list[FloatArray] = []
        self.f: list[NDArray[np.int64]] = []
        self.c: list[FloatArray] = []
        self.n = 0

    def add(self, part: tuple[FloatArray, NDArray[np.int64]], rgb: Rgb, jitter: float = 0.06,
            shade: float = 0.0) -> None:
        """Add a part coloured ``rgb``, brightness jittered per vertex, darker towards its bottom by ``shade``."""
        v, f = part
        col = np.tile(np.asarray(rgb, dtype=np.float64), (len(v), 1))
        col *= 1 + jitter * self.rng.standard_normal((len(v), 1))
        if shade > 0:
            z = v[:, 2]
            t = (z - z.min()) / max(float(np.ptp(z)), 1e-6)
            col *= (1 - shade) + shade * t[:, None]
        self.v.append(v)
        self.f.append(f + self.n)
        self.c.append(col)
        self.n += len(v)

    def mesh(self) -> PrototypeMesh:
        return (np.concatenate(self.v).astype(np.float32), np.concatenate(self.f).astype(np.int32),
                np.clip(np.concatenate(self.c), 0, 1).astype(np.float32))


BARK = srgb(0.30, 0.24, 0.18)


def _acacia(rng: np.random.Generator) -> tuple[PrototypeMesh, float]:
    b = _Builder(rng)
    h = rng.uniform(3.0, 4.0)
    lean = rng.normal(0, 0.25, 2)
    top = np.array([lean[0], lean[1], h * 0.75])
    b.add(_tube(np.array([0.0, 0.0, -0.4]), top, 0.20, 0.14), BARK, shade=0.3)
    cz = h + rng.uniform(0.6, 1.0)
    for _ in range(rng.integers(2, 4)):
        ang = rng.uniform(0, 2 * np.pi)
        end = np.array([np.cos(ang) * rng.uniform(1.2, 2.2), np.sin(ang) * rng.uniform(1.2, 2.2), cz - 0.3])
        b.add(_tube(top, end, 0.12, 0.06, 5), BARK)
    for k in range(rng.integers(1, 3)):
        off = np.array([*(rng.normal(0, 1.0, 2) if k else (0.0, 0.0)), cz + rng.uniform(-0.2, 0.3)])
        radii = np.array([rng.uniform(3.5, 4.8), rng.uniform(3.2, 4.5), rng.uniform(0.7, 1.0)])
        v, f = _blob(off, radii, rng, 2, 0.18, 3.0)
        below = v[:, 2] < off[2]
        v[below, 2] = off[2] + 0.35 * (v[below, 2] - off[2])  # flat underside: the umbrella shape
        b.add((v, f), srgb(0.33, 0.40, 0.16), jitter=0.08, shade=0.45)
    return b.mesh(), 0.20


def _deciduous(rng: np.random.Generator) -> tuple[PrototypeMesh, float]:
    b = _Builder(rng)
    h = rng.uniform(3.0, 4.2)
    top = np.array([*rng.normal(0, 0.2, 2), h])
    b.add(_tube(np.array([0.0, 0.0, -0.4]), top, 0.30, 0.2), BARK, shade=0.3)
    cz = h + rng.uniform(2.5, 3.5)
    base = np.array(srgb(0.28, 0.45, 0.16)) * rng.uniform(0.85, 1.15, 3)
    for _ in range(rng.integers(4, 7)):
        c = np.array([*rng.normal(0, 1.4, 2), cz + rng.normal(0, 0.9)])
        r = rng.uniform(2.0, 3.0)
        b.add(_blob(c, np.array([r, r, r * 0.85]), rng, 2, 0.15, 3.0), tuple(base), jitter=0.08, shade=0.5)
    return b.mesh(), 0.30


def _conifer(rng: np.random.Generator) -> tuple[PrototypeMesh, float]:
    b = _Builder(rng)
    b.add(_tube(np.array([0.0, 0.0, -0.4]), np.array([0.0, 0.0, 2.5]), 0.25, 0.18), BARK)
    tiers = int(rng.integers(4, 6))
    height = rng.uniform(10.0, 14.0)
    green = srgb(0.16, 0.28, 0.14)
    for t in range(tiers):
        z0 = 1.8 + t * (height - 3.0) / tiers
        r = rng.uniform(2.4, 2.9) * (1 - 0.75 * t / tiers)
        b.add(_cone(z0, z0 + 3.2 + 0.2 * t, r, 10, np.zeros(2)), green, jitter=0.08, shade=0.35)
    return b.mesh(), 0.25


def _bush(rng: np.random.Generator) -> tuple[PrototypeMesh, float]:
    b = _Builder(rng)
    col = tuple(np.array(srgb(0.30, 0.40, 0.17)) * rng.uniform(0.85, 1.15, 3))
    for _ in range(rng.integers(3, 6)):
        c = np.array([*rng.normal(0, 0.45, 2), rng.uniform(0.35, 0.6)])
        r = rng.uniform(0.5, 0.85)
        b.add(_blob(c, np.array([r, r, r * 0.8]), rng, 1, 0.2, 3.0), col, jitter=0.1, shade=0.5)
    return b.mesh(), 0.0


def _rock_mesh(rng: np.random.Generator, radii: FloatArray, sink: float, rgb: Rgb, amp: float) -> tuple[
        PrototypeMesh, float]:
    b = _Builder(rng)
    v, f = _blob(np.zeros(3), radii, rng, 2, amp, 2.0)
    v[:, 2] -= sink * radii[2]  # partly buried, the buried part squashed flat (never seen, fewer overdraw)
    v[:, 2] = np.maximum(v[:, 2], -0.3 * radii[2])
    b.add((v, f), rgb, jitter=0.08, shade=0.35)
    above = v[:, 2] >= 0
    footprint = float(np.max(np.hypot(v[above, 0], v[above, 1]))) if above.any() else float(radii[:2].max())
    return b.mesh(), footprint


def _rock(rng: np.random.Generator) -> tuple[PrototypeMesh, float]:
    r = rng.uniform(0.7, 1.0)
    grey = float(rng.uniform(0.42, 0.55))
    return _rock_mesh(rng, np.array([r, r * rng.uniform(0.6, 0.9), r * rng.uniform(0.5, 0.8)]), 0.35,
                      srgb(grey, grey * 0.98, grey * 0.94), 0.25)


def _mound(rng: np.random.Generator) -> tuple[PrototypeMesh, float]:
    r = rng.uniform(0.7, 1.0)
    return _rock_mesh(rng, np.array([r, r * 0.9, rng.uniform(1.4, 2.0)]), 0.15, srgb(0.60, 0.43, 0.30), 0.2)


def _tuft(rng: np.random.Generator) -> tuple[PrototypeMesh, float]:
    n = int(rng.integers(6, 10))
    ang = rng.uniform(0, 2 * np.pi, n)
    rad = rng.uniform(0.02, 0.08, n)
    h = rng.uniform(0.3, 0.6, n)
    lean = rng.uniform(0.05, 0.2, n)
    d = np.stack([np.cos(ang), np.sin(ang), np.zeros(n)], 1)
    side = np.stack([-np.sin(ang), np.cos(ang), np.zeros(n)], 1) * 0.025
    base = d * rad[:, None]
    tip = d * (rad + lean)[:, None] + np.stack([np.zeros(n), np.zeros(n), h], 1)
    v = np.concatenate([base - side, base + side, tip])
    k = np.arange(n)
    f = np.concatenate([np.stack([k, n + k, 2 * n + k], 1), np.stack([k, 2 * n + k, n + k], 1)])
    col = np.concatenate([np.tile(srgb(0.38, 0.38, 0.18), (2 * n, 1)), np.tile(srgb(0.62, 0.60, 0.34), (n, 1))])
    col *= 1 + 0.08 * rng.standard_normal((3 * n, 1))
    return (v.astype(np.float32), f.astype(np.int32), np.clip(col, 0, 1).astype(np.float32)), 0.0


# --- man-made props: local x along the length, y across, z up; footprint = half the length ------------------

def _box(lo: tuple[float, float, float], hi: tuple[float, float, float]) -> tuple[FloatArray, NDArray[np.int64]]:
    """Closed axis-aligned box between corners ``lo`` and ``hi`` (metres), faces outward."""
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    v = np.array([[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0],
                  [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]], dtype=np.float64)
    f = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4], [1, 2, 6], [1, 6, 5],
                  [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]], dtype=np.int64)
    return v, f


def _fence(rng: np.random.Generator) -> tuple[PrototypeMesh, float]:
    """A 3 m panel of post-and-rail fence, 1.4 m high: weathered wood or galvanised steel."""
    b = _Builder(rng)
    wood = rng.uniform() < 0.6
    col = srgb(0.42, 0.34, 0.25) if wood else srgb(0.62, 0.63, 0.62)
    post = 0.06 if wood else 0.035
    for x in (-1.5, 0.0, 1.5):
        b.add(_box((x - post, -post, -0.3), (x + post, post, 1.45)), col, jitter=0.1, shade=0.2)
    for z in (0.45, 0.85, 1.25):
        b.add(_box((-1.5, -0.025, z - 0.04), (1.5, 0.025, z + 0.04)), col, jitter=0.08)
    return b.mesh(), 1.5


def _wall(rng: np.random.Generator) -> tuple[PrototypeMesh, float]:
    """A 3 m section of enclosure wall, 1.8-2.4 m high: rendered block or stone, with a coping on top."""
    b = _Builder(rng)
    h = rng.uniform(1.8, 2.4)
    col = [srgb(0.72, 0.66, 0.56), srgb(0.58, 0.55, 0.50), srgb(0.66, 0.52, 0.40)][int(rng.integers(3))]
    b.add(_box((-1.5, -0.18, -0.3), (1.5, 0.18, h)), col, jitter=0.05, shade=0.3)
    b.add(_box((-1.5, -0.24, h), (1.5, 0.24, h + 0.08)), tuple(np.array(col) * 0.8), jitter=0.03)
    return b.mesh(), 1.6


def _trough(rng: np.random.Generator) -> tuple[PrototypeMesh, float]:
    """A concrete water trough, 2 m long, with dark water a little below its rim."""
    b = _Builder(rng)
    concrete = srgb(0.60, 0.59, 0.56)
    b.add(_box((-1.0, -0.4, -0.1), (1.0, -0.3, 0.6)), concrete)
    b.add(_box((-1.0, 0.3, -0.1), (1.0, 0.4, 0.6)), concrete)
    b.add(_box((-1.0, -0.3, -0.1), (-0.9, 0.3, 0.6)), concrete)
    b.add(_box((0.9, -0.3, -0.1), (1.0, 0.3, 0.6)), concrete)
    b.add(_box((-0.9, -0.3, -0.1), (0.9, 0.3, 0.5)), srgb(0.10, 0.13, 0.12), jitter=0.02)
    return b.mesh(), 1.1


def _hut(rng: np.random.Generator) -> tuple[PrototypeMesh, float]:
    """A small building: walls 5 x 4 x 2.6 m and a pitched roof of thatch or iron sheet."""
    b = _Builder(rng)
    wall = [srgb(0.78, 0.72, 0.62), srgb(0.60, 0.46, 0.34), srgb(0.85, 0.84, 0.80)][int(rng.integers(3))]
    b.add(_box((-2.5, -2.0, -0.2), (2.5, 2.0, 2.6)), wall, jitter=0.04, shade=0.25)
    roof = srgb(0.55, 0.47, 0.30) if rng.uniform() < 0.5 else srgb(0.50, 0.30, 0.24)
    v = np.array([[-2.8, -2.3, 2.6], [2.8, -2.3, 2.6], [2.8, 2.3, 2.6], [-2.8, 2.3, 2.6], [-2.8, 0, 3.8],
                  [2.8, 0, 3.8]], dtype=np.float64)
    f = np.array([[0, 1, 5], [0, 5, 4], [2, 3, 4], [2, 4, 5], [1, 2, 5], [3, 0, 4], [0, 2, 1], [0, 3, 2]],
                 dtype=np.int64)
    b.add((v, f), roof, jitter=0.06)
    b.add(_box((2.5, -0.5, 0.0), (2.56, 0.5, 2.0)), srgb(0.25, 0.20, 0.16))  # a door
    return b.mesh(), 3.2


def _vehicle(rng: np.random.Generator) -> tuple[PrototypeMesh, float]:
    """A safari or farm vehicle, 4.6 m long: body, cabin, dark windows and four wheels."""
    b = _Builder(rng)
    paint = [srgb(0.85, 0.85, 0.82), srgb(0.70, 0.64, 0.48), srgb(0.30, 0.36, 0.26), srgb(0.55, 0.12, 0.10),
             srgb(0.20, 0.25, 0.40)][int(rng.integers(5))]
    b.add(_box((-2.3, -0.9, 0.45), (2.3, 0.9, 1.2)), paint, jitter=0.03, shade=0.3)
    b.add(_box((-1.6, -0.85, 1.2), (0.9, 0.85, 1.95)), paint, jitter=0.03)
    b.add(_box((0.9, -0.8, 1.25), (0.95, 0.8, 1.85)), srgb(0.08, 0.09, 0.10), jitter=0.02)  # windscreen
    tyre = srgb(0.07, 0.07, 0.07)
    for x in (-1.5, 1.5):
        for y in (-0.9, 0.9):
            b.add(_tube(np.array([x, y - 0.14 * np.sign(y), 0.4]), np.array([x, y + 0.14 * np.sign(y), 0.4]),
                        0.4, 0.4, 10), tyre, jitter=0.02)
    return b.mesh(), 2.4


def _person(rng: np.random.Generator) -> tuple[PrototypeMesh, float]:
    """A standing person, 1.6-1.9 m: legs, torso, arms and head in clothing colours."""
    b = _Builder(rng)
    h = rng.uniform(1.6, 1.9)
    cloth = [srgb(0.70, 0.62, 0.45), srgb(0.30, 0.35, 0.25), srgb(0.85, 0.85, 0.82), srgb(0.20, 0.28, 0.50),
             srgb(0.65, 0.20, 0.15)][int(rng.integers(5))]
    trousers = [srgb(0.25, 0.22, 0.18), srgb(0.55, 0.48, 0.35), srgb(0.18, 0.20, 0.30)][int(rng.integers(3))]
    skin = [srgb(0.35, 0.23, 0.16), srgb(0.60, 0.45, 0.35), srgb(0.85, 0.70, 0.58)][int(rng.integers(3))]
    for y in (-0.1, 0.1):
        b.add(_tube(np.array([0.0, y, -0.05]), np.array([0.0, y, 0.47 * h]), 0.07, 0.08, 6), trousers)
    b.add(_blob(np.array([0.0, 0.0, 0.64 * h]), np.array([0.13, 0.22, 0.19 * h]), rng, 1, 0.05), cloth)
    for y in (-0.27, 0.27):
        b.add(_tube(np.array([0.0, y, 0.78 * h]), np.array([0.05, y * 1.1, 0.45 * h]), 0.05, 0.04, 6), cloth)
    b.add(_blob(np.array([0.0, 0.0, 0.92 * h]), np.array([0.1, 0.09, 0.12]), rng, 1, 0.03), skin)
    return b.mesh(), 0.35


_BUILDERS: dict[str, Callable[[np.random.Generator], tuple[PrototypeMesh, float]]] = {
    "acacia": _acacia, "deciduous": _deciduous, "conifer": _conifer, "bush": _bush, "rock": _rock,
    "mound": _mound, "tuft": _tuft, "fence": _fence, "wall": _wall, "trough": _trough, "hut": _hut,
    "vehicle": _vehicle, "person": _person,
}
ALIGNED_STYLES = ("fence", "wall")
"""Props that follow the line they stand on (hedgerow pattern): yaw along the line, no sideways jitter."""


@lru_cache(maxsize=64)
def _base_prototype(style: str, variant: int) -> tuple[PrototypeMesh, float]:
    mesh, footprint = _BUILDERS[style](derive_rng(variant, "prototype", style))
    for a in mesh:
        a.setflags(write=False)
    return mesh, footprint


def build_prototype(style: str, variant: int = 0, tint: Rgb = (1.0, 1.0, 1.0)) -> Prototype:
    """Prototype mesh ``<style>_<variant>`` (same for every world), its colours multiplied by ``tint``.

    Styles: acacia (umbrella tree, ~6 m tall, ~9 m canopy), deciduous (~10 m), conifer (~12 m), bush
    (~1.2 m), rock (~1.6 m across), mound (termite-mound-like, ~2 m tall), tuft (grass, ~0.5 m); props: fence
    and wall (3 m panels), trough (2 m), hut (5 x 4 m), vehicle (4.6 m), person (~1.75 m).
    """
    if style not in _BUILDERS:
        raise ParameterError("vegetation.style", style, f"one of {sorted(_BUILDERS)}")
    (v, f, c), footprint = _base_prototype(style, int(variant))
    rgb = np.clip(c * np.asarray(tint, dtype=np.float32), 0, 1).astype(np.float32)
    return Prototype(f"{style}_{variant}", STYLES[style], style, (v.copy(), f.copy(), rgb), footprint)


# --- scattering -----------------------------------------------------------------------------------

def _sample_grid(grid: NDArray[Any], terrain: Heightfield, x: FloatArray, y: FloatArray) -> NDArray[Any]:
    """Nearest-sample look-up of a per-heightfield-sample array at points (x, y)."""
    ny, nx = terrain.shape
    i = np.clip(np.rint((x - terrain.origin[0]) / terrain.resolution).astype(np.int64), 0, nx - 1)
    j = np.clip(np.rint((y - terrain.origin[1]) / terrain.resolution).astype(np.int64), 0, ny - 1)
    return np.asarray(grid[j, i])


def thin_min_distance(xy: FloatArray, r: float) -> NDArray[np.bool_]:
    """Keep-mask so that no two kept points are closer than ``r`` m; earlier points win (vectorised).

    A point is dropped when an earlier point in its grid cell or an earlier kept-cell point within ``r``
    exists; this can drop a little more than a sequential dart throw would, never keeps a conflict.
    """
    n = len(xy)
    if n == 0 or r <= 0:
        return np.ones(n, dtype=bool)
    cell = r / np.sqrt(2.0)
    lo = xy.min(axis=0)
    c = np.floor((xy - lo) / cell).astype(np.int64)
    gx, gy = int(c[:, 0].max()) + 5, int(c[:, 1].max()) + 5
    key = c[:, 1] * gx + c[:, 0]
    _, first = np.unique(key, return_index=True)
    cand = np.zeros(n, dtype=bool)
    cand[first] = True
    grid = np.full((gy, gx), -1, dtype=np.int64)
    idx = np.nonzero(cand)[0]
    grid[c[idx, 1] + 2, c[idx, 0] + 2] = idx
    keep = cand.copy()
    for dy in range(-2, 3):
        for dx in range(-2, 3):
            if dx == 0 and dy == 0:
                continue
            other = grid[c[idx, 1] + 2 + dy, c[idx, 0] + 2 + dx]
            ok = other >= 0
            close = np.zeros(len(idx), dtype=bool)
            close[ok] = (other[ok] < idx[ok]) & (np.linalg.norm(xy[other[ok]] - xy[idx[ok]], axis=1) < r)
            keep[idx[close]] = False
    return keep


def stamp_discs(mask: NDArray[np.bool_], terrain: Heightfield, xy: FloatArray, radii: FloatArray) -> None:
    """Mark every heightfield sample within ``radii`` (m) of the points (x, y) in ``mask``, in place."""
    ny, nx = mask.shape
    res = terrain.resolution
    ci = np.rint((xy[:, 0] - terrain.origin[0]) / res).astype(np.int64)
    cj = np.rint((xy[:, 1] - terrain.origin[1]) / res).astype(np.int64)
    cells = np.ceil(radii / res).astype(np.int64)
    for rc in np.unique(cells):
        sel = cells == rc
        oj, oi = np.mgrid[-rc:rc + 1, -rc:rc + 1]
        oj, oi = oj.ravel(), oi.ravel()
        i = ci[sel, None] + oi[None, :]
        j = cj[sel, None] + oj[None, :]
        inside = (oi[None, :] ** 2 + oj[None, :] ** 2) * res * res <= radii[sel, None] ** 2 + 0.25 * res * res
        inside &= (i >= 0) & (i < nx) & (j >= 0) & (j < ny)
        mask[j[inside], i[inside]] = True


@dataclass(frozen=True)
class ForestEdge:
    """A straight forest edge: density rises from 0 to 1 across ``offset_m`` along unit ``direction``."""

    direction: tuple[float, float]
    offset_m: float

    def density(self, x: FloatArray, y: FloatArray, width_m: float) -> FloatArray:
        """Relative tree density 0..1 at (x, y): smoothstep over ``width_m`` across the edge line."""
        s = (np.asarray(x) * self.direction[0] + np.asarray(y) * self.direction[1] - self.offset_m) / width_m + 0.5
        s = np.clip(s, 0.0, 1.0)
        return np.asarray(s * s * (3 - 2 * s))


def forest_edge(preset: WorldPreset, seed: int) -> ForestEdge:
    """The forest edge of a world (random direction, dense side ~30 % of the terrain), per seed."""
    rng = derive_rng(seed, preset.name, "forest_edge")
    a = float(rng.uniform(0, 2 * np.pi))
    return ForestEdge((float(np.cos(a)), float(np.sin(a))), 0.20 * preset.terrain.size_m)


def field_layout(preset: WorldPreset, terrain: Heightfield, seed: int) -> Patchwork | None:
    """The farm-field layout of a world with a "fields" material layer, else None (same for ground and hedges)."""
    layer = preset.fields_layer()
    if layer is None:
        return None
    return patchwork(terrain.bounds, layer.patch_scale_m, derive_rng(seed, preset.name, "fields"))


def hedge_segments(preset: WorldPreset, layout: Patchwork, seed: int) -> FloatArray:
    """The field sides that carry a hedgerow (about 55 %), as (K, 2, 2) map-frame segments, metres."""
    segs = layout.boundary_segments()
    keep = derive_rng(seed, preset.name, "hedges").random(len(segs)) < 0.55
    segs = segs[keep]
    x, y = layout.to_xy(segs[..., 0], segs[..., 1])
    return np.stack([x, y], axis=-1)


@dataclass(frozen=True)
class Scatter:
    """Instances of one vegetation layer: map-frame positions (M, 3) m, yaw (M,) rad, scale (M,), variant (M,)."""

    layer: VegetationLayer
    positions: FloatArray
    yaw: FloatArray
    scale: FloatArray
    variant: NDArray[np.int64]


def _line_candidates(layer: VegetationLayer, terrain: Heightfield, hedges: FloatArray | None) -> tuple[
        FloatArray, FloatArray]:
    """Fence and wall panels end to end along the hedge segments: centres (K, 2) m and yaw along the line (K,)."""
    x0, y0, x1, y1 = terrain.bounds
    if hedges is None or len(hedges) == 0:
        return np.zeros((0, 2)), np.zeros(0)
    walls = np.arange(len(hedges)) % 4 == 0  # a quarter of the lines are walls, the rest fences
    hedges = hedges[walls if layer.style == "wall" else ~walls]
    a, b = hedges[:, 0], hedges[:, 1]
    length = np.linalg.norm(b - a, axis=1)
    counts = np.maximum(np.ceil(length / layer.hedge_spacing_m).astype(np.int64), 1)
    seg = np.repeat(np.arange(len(hedges)), counts)
    k = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    t = (k + 0.5) / counts[seg]
    xy = a[seg] + (b - a)[seg] * t[:, None]
    d = (b - a)[seg]
    yaw = np.arctan2(d[:, 1], d[:, 0])
    inside = (xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1)
    return np.asarray(xy[inside]), np.asarray(yaw[inside])


def _hedgerow_candidates(layer: VegetationLayer, terrain: Heightfield, rng: np.random.Generator,
                         hedges: FloatArray | None) -> FloatArray:
    """Candidate (x, y) (K, 2) m every ``hedge_spacing_m`` along the hedge segments, jittered; 70% kept for trees."""
    x0, y0, x1, y1 = terrain.bounds
    if hedges is None or len(hedges) == 0:
        return np.zeros((0, 2))
    a, b = hedges[:, 0], hedges[:, 1]
    length = np.linalg.norm(b - a, axis=1)
    counts = np.maximum(np.floor(length / layer.hedge_spacing_m).astype(np.int64), 0)
    seg = np.repeat(np.arange(len(hedges)), counts)
    k = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    t = (k + 0.5 + rng.uniform(-0.35, 0.35, len(k))) / np.maximum(counts[seg], 1)
    d = (b - a)[seg] / length[seg, None]
    normal = np.stack([-d[:, 1], d[:, 0]], 1)
    xy = a[seg] + (b - a)[seg] * t[:, None] + normal * rng.uniform(-0.6, 0.6, (len(k), 1))
    if layer.kind == "tree":
        xy = xy[rng.random(len(xy)) < 0.7]
    return np.asarray(xy[(xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1)])


def _area_candidates(layer: VegetationLayer, terrain: Heightfield, rng: np.random.Generator,
                     edge: ForestEdge | None) -> FloatArray:
    """Candidate (x, y) (K, 2) m drawn uniformly at ``per_hectare``, thinned by the layer's relative density."""
    x0, y0, x1, y1 = terrain.bounds
    area_ha = (x1 - x0) * (y1 - y0) / 1e4
    target = layer.per_hectare * area_ha
    if layer.pattern == "clustered":
        ny, nx = terrain.shape
        field = value_noise((ny, nx), layer.cluster_scale_m / terrain.resolution, rng, octaves=2) ** 2
        n_cand = int(rng.poisson(target / max(float(field.mean()), 1e-3)))
        xy = np.stack([rng.uniform(x0, x1, n_cand), rng.uniform(y0, y1, n_cand)], 1)
        return np.asarray(xy[rng.random(n_cand) < _sample_grid(field, terrain, xy[:, 0], xy[:, 1])])
    if layer.pattern == "gradient":
        if edge is None:
            raise ParameterError("vegetation.pattern", layer.pattern, "a forest edge for 'gradient'")
        n_cand = int(rng.poisson(target))
        xy = np.stack([rng.uniform(x0, x1, n_cand), rng.uniform(y0, y1, n_cand)], 1)
        ny, nx = terrain.shape
        clearings = value_noise((ny, nx), 45.0 / terrain.resolution, rng, octaves=2)
        dens = edge.density(xy[:, 0], xy[:, 1], layer.cluster_scale_m)
        dens = dens * np.clip(1.6 * _sample_grid(clearings, terrain, xy[:, 0], xy[:, 1]) - 0.1, 0, 1)
        return np.asarray(xy[rng.random(n_cand) < np.maximum(dens, 0.01)])
    n_cand = int(rng.poisson(target))
    return np.stack([rng.uniform(x0, x1, n_cand), rng.uniform(y0, y1, n_cand)], 1)


def scatter_layer(
    layer: VegetationLayer,
    terrain: Heightfield,
    rng: np.random.Generator,
    exclusion: NDArray[np.bool_],
    *,
    edge: ForestEdge | None = None,
    hedges: FloatArray | None = None,
    max_count: int | None = None,
) -> Scatter:
    """Scatter one layer over the whole terrain.

    Candidates are drawn uniformly (or along ``hedges``), accepted with the layer's relative density
    (clumps for "clustered", the ``edge`` gradient for "gradient"), then rejected on slopes over
    ``layer.max_slope_deg``, outside ``layer.height_band``, on ``exclusion`` samples, and closer than
    ``layer.min_spacing_m`` to an earlier instance. At most ``max_count`` instances are kept.
    """
    along: FloatArray | None = None
    if layer.pattern == "hedgerow" and layer.style in ALIGNED_STYLES:
        xy, along = _line_candidates(layer, terrain, hedges)
    elif layer.pattern == "hedgerow":
        xy = _hedgerow_candidates(layer, terrain, rng, hedges)
    else:
        xy = _area_candidates(layer, terrain, rng, edge)
    ok = terrain.slope_deg(xy[:, 0], xy[:, 1]) <= layer.max_slope_deg
    z = terrain.height_at(xy[:, 0], xy[:, 1])
    ok &= (z >= layer.height_band[0]) & (z <= layer.height_band[1])
    ok &= ~_sample_grid(exclusion, terrain, xy[:, 0], xy[:, 1]).astype(bool)
    xy, z = xy[ok], z[ok]
    keep = thin_min_distance(xy, layer.min_spacing_m)
    xy, z = xy[keep], z[keep]
    if max_count is not None and len(xy) > max_count:
        xy, z = xy[:max_count], z[:max_count]
    m = len(xy)
    yaw = rng.uniform(0, 2 * np.pi, m)
    if along is not None:  # panels along their line, the same scale so they meet end to end
        yaw = along[ok][keep][:m]
        return Scatter(layer, np.column_stack([xy, z]), yaw, np.ones(m), rng.integers(0, layer.variants, m))
    return Scatter(layer, np.column_stack([xy, z]), yaw, rng.uniform(layer.scale[0], layer.scale[1], m),
                   rng.integers(0, layer.variants, m))


_KIND_ORDER = {"prop": 0, "tree": 1, "rock": 2, "bush": 3, "grass": 4}
_EXCLUDE_PAD_M = {"prop": 0.5, "tree": 0.8, "rock": 0.3, "bush": 0.0, "grass": 0.0}


def scatter_vegetation(preset: WorldPreset, terrain: Heightfield, seed: int,
                       keep_out: NDArray[np.bool_] | None = None) -> tuple[
        dict[str, tuple[FloatArray, FloatArray, FloatArray]], dict[str, Prototype]]:
    """All vegetation of a preset world: per prototype name ``(positions (M,3), yaw (M,), scale (M,))``
    and the prototypes themselves. Trees go first, then rocks, bushes and grass, each avoiding the
    footprints of what came before; grass tufts are capped at ``MAX_GRASS_TUFTS`` per world. Nothing grows or
    stands on ``keep_out`` samples (open water).
    """
    edge = forest_edge(preset, seed) if any(v.pattern == "gradient" for v in preset.vegetation) else None
    layout = field_layout(preset, terrain, seed)
    hedges = hedge_segments(preset, layout, seed) if layout is not None else None
    exclusion = np.zeros(terrain.shape, dtype=bool) if keep_out is None else keep_out.copy()
    grass_left = MAX_GRASS_TUFTS
    parts: dict[str, list[tuple[FloatArray, FloatArray, FloatArray]]] = {}
    protos: dict[str, Prototype] = {}
    order = sorted(range(len(preset.vegetation)), key=lambda i: (_KIND_ORDER[preset.vegetation[i].kind], i))
    for i in order:
        layer = preset.vegetation[i]
        rng = derive_rng(seed, preset.name, "vegetation", str(i), layer.style)
        cap = grass_left if layer.kind == "grass" else None
        sc = scatter_layer(layer, terrain, rng, exclusion, edge=edge, hedges=hedges, max_count=cap)
        if layer.kind == "grass":
            grass_left -= len(sc.positions)
        for v in range(layer.variants):
            sel = sc.variant == v
            if not sel.any():
                continue
            name = f"{layer.style}_{v}"
            if name not in protos:
                protos[name] = build_prototype(layer.style, v, layer.tint)
            proto = protos[name]
            parts.setdefault(name, []).append((sc.positions[sel], sc.yaw[sel], sc.scale[sel]))
            if layer.kind in ("tree", "rock", "prop"):
                r = proto.obstacle_radius(sc.scale[sel]) + _EXCLUDE_PAD_M[layer.kind]
                stamp_discs(exclusion, terrain, sc.positions[sel, :2], r)
            elif layer.kind == "bush":
                stamp_discs(exclusion, terrain, sc.positions[sel, :2], 0.6 * sc.scale[sel])
    out = {name: (np.concatenate([p[0] for p in ps]), np.concatenate([p[1] for p in ps]),
                  np.concatenate([p[2] for p in ps])) for name, ps in parts.items()}
    return out, protos
