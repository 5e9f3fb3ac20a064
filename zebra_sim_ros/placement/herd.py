"""Placing a herd: the paper's per-frame zebra placement, with exact footprints and ground contact.

Per placement: a random axis-aligned rectangle with sides U(rect_min, rect_max) inside the world's
placeable area; N ~ U{count_min..count_max} distinct zebras from the pool; each gets a clip and frame,
a scale and a yaw. Zebras are placed one after another: up to ``max_attempts`` centres are drawn in the
rectangle and the first whose oriented footprint (the posed, scaled box of that very clip frame) overlaps
no placed zebra and no tree or rock, on ground no steeper than ``max_slope_deg``, is taken; a zebra with
no valid centre is dropped, as in the paper. Placed zebras stand at the ground height under their centre,
tilted to the plane through the ground under their footprint (beyond the paper).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.geometry.boxes import box_axes
from zebra_sim_ros.geometry.rotations import rot_z
from zebra_sim_ros.world.terrain import Heightfield
from zebra_sim_ros.zebra.asset import ZebraLibrary

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class ZebraPool:
    """The individuals preloaded for an experiment: stable ids, morphs and coat seeds. The first ``zebras`` are
    zebras; the rest (ids ``zebras`` and up) animals of other species."""

    morph: IntArray  # (P,) index into the library's morphs
    coat_seed: IntArray  # (P,)
    zebras: int = -1  # -1: all

    def __post_init__(self) -> None:
        if self.zebras < 0:
            object.__setattr__(self, "zebras", int(len(self.morph)))

    @property
    def size(self) -> int:
        """Number of individuals."""
        return int(len(self.morph))

    @property
    def others(self) -> int:
        """Number of animals of other species."""
        return self.size - self.zebras


OTHER_POOL_SIZE = 120
"""Animals of other species preloaded per experiment (each species equally likely among those allowed)."""


def make_pool(seed: int, size: int, morph_weights: tuple[float, ...], n_morphs: int,
              other_morphs: tuple[int, ...] = ()) -> ZebraPool:
    """Draw the pool of an experiment from ``seed`` (its own stream, independent of the step draws): ``size``
    zebras of the first ``n_morphs`` morphs by ``morph_weights``, then, if ``other_morphs`` (library morph indices
    of other species) are given, :data:`OTHER_POOL_SIZE` animals of those from a second stream."""
    if len(morph_weights) != n_morphs:
        raise ParameterError("morph_weights", list(morph_weights), f"{n_morphs} weights")
    rng = np.random.default_rng([seed, 0x9001])
    p = np.asarray(morph_weights, dtype=np.float64)
    morph = rng.choice(n_morphs, size=size, p=p / p.sum())
    coat = rng.integers(0, 2**31 - 1, size=size)
    if other_morphs:
        orng = np.random.default_rng([seed, 0x9002])
        morph = np.concatenate([morph, np.asarray(other_morphs)[orng.integers(0, len(other_morphs), OTHER_POOL_SIZE)]])
        coat = np.concatenate([coat, orng.integers(0, 2**31 - 1, size=OTHER_POOL_SIZE)])
    return ZebraPool(morph=morph.astype(np.int64), coat_seed=coat.astype(np.int64), zebras=size)


@dataclass(frozen=True)
class Herd:
    """The zebras of one placement, all arrays (N,) or (N, ...) over the placed zebras."""

    rect_center: tuple[float, float]
    rect_size: tuple[float, float]
    requested: int
    ids: IntArray  # pool indices
    morph: IntArray
    clip: IntArray  # clip index in the library
    frame: IntArray  # frame within the clip
    global_frame: IntArray
    scale: FloatArray
    yaw: FloatArray  # radians, heading of the zebra's x axis, counter-clockwise from east
    position: FloatArray  # (N, 3) asset origin (ground under the body) in map
    rotation: FloatArray  # (N, 3, 3) asset-to-map rotation (tilt to the ground, then yaw)
    footprint_center: FloatArray  # (N, 2)
    footprint_half: FloatArray  # (N, 2) half length and half width of the footprint, m

    @property
    def count(self) -> int:
        """Number of zebras placed."""
        return int(len(self.ids))


@dataclass(frozen=True)
class PlacementDraw:
    """The random draws of one placement (arrays over the requested zebras)."""

    rect_center: tuple[float, float]
    rect_size: tuple[float, float]
    ids: IntArray
    clip: IntArray
    frame: IntArray
    global_frame: IntArray
    scale: FloatArray
    yaw: FloatArray
    candidates: FloatArray  # (N, max_attempts, 2) centres tried in order


class PlacementError(ParameterError):
    """Placement cannot proceed with these settings (e.g. the rectangle cannot fit the world)."""


class _BoxGrid:
    """Placed footprints for the packing: a hash grid of their bounding circles (cells of ``CELL`` metres) for the
    broad phase, the separating axis test for the few neighbours found. A box is (centre x, y, half extents e0,
    e1, axis ux, uy (second axis (-uy, ux)), bounding radius), in plain floats: this is the placer's inner loop."""

    CELL = 3.0

    def __init__(self) -> None:
        self.boxes: list[tuple[float, float, float, float, float, float, float]] = []
        self.grid: dict[tuple[int, int], list[int]] = {}

    def insert(self, b: tuple[float, float, float, float, float, float, float]) -> None:
        x, y, r, cell = b[0], b[1], b[6], self.CELL
        idx = len(self.boxes)
        self.boxes.append(b)
        for gx in range(int((x - r) // cell), int((x + r) // cell) + 1):
            for gy in range(int((y - r) // cell), int((y + r) // cell) + 1):
                self.grid.setdefault((gx, gy), []).append(idx)

    def clear(self, x: float, y: float, e0: float, e1: float, ux: float, uy: float, rk: float) -> bool:
        """Whether a box there overlaps none stored."""
        cell, grid, boxes = self.CELL, self.grid, self.boxes
        seen: set[int] = set()
        for gx in range(int((x - rk) // cell), int((x + rk) // cell) + 1):
            for gy in range(int((y - rk) // cell), int((y + rk) // cell) + 1):
                for j in grid.get((gx, gy), ()):
                    if j in seen:
                        continue
                    seen.add(j)
                    bx, by, f0, f1, vx, vy, rj = boxes[j]
                    dx, dy = bx - x, by - y
                    if dx * dx + dy * dy >= (rk + rj) ** 2:
                        continue
                    if _sat_overlap(dx, dy, e0, e1, ux, uy, f0, f1, vx, vy):
                        return False
        return True


def _sat_overlap(dx: float, dy: float, e0: float, e1: float, ux: float, uy: float, f0: float, f1: float,
                 vx: float, vy: float) -> bool:
    """Separating axis test of two oriented boxes; ``(dx, dy)`` from the first centre to the second.

    Box axes are (u, u-perp) and (v, v-perp); e and f are half extents. Touching counts as apart.
    """
    for ax, ay in ((ux, uy), (-uy, ux), (vx, vy), (-vy, vx)):
        r1 = e0 * abs(ux * ax + uy * ay) + e1 * abs(-uy * ax + ux * ay)
        r2 = f0 * abs(vx * ax + vy * ay) + f1 * abs(-vy * ax + vx * ay)
        if abs(dx * ax + dy * ay) >= r1 + r2:
            return False
    return True


def _tilt_to(normals: FloatArray) -> FloatArray:
    """Rotations (N, 3, 3) taking +z to each unit normal by the shortest arc."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, normals)
    s = np.linalg.norm(axis, axis=1)
    c = normals[:, 2]
    out = np.tile(np.eye(3), (len(normals), 1, 1))
    m = s > 1e-12
    k = axis[m] / s[m, None]
    kx = np.zeros((int(m.sum()), 3, 3))
    kx[:, 0, 1], kx[:, 0, 2], kx[:, 1, 0] = -k[:, 2], k[:, 1], k[:, 2]
    kx[:, 1, 2], kx[:, 2, 0], kx[:, 2, 1] = -k[:, 0], -k[:, 1], k[:, 0]
    out[m] = np.eye(3) + s[m, None, None] * kx + (1 - c[m])[:, None, None] * (kx @ kx)
    return out


class HerdPlacer:
    """Places herds on one world; holds what does not change between placements."""

    def __init__(self, terrain: Heightfield, placeable: tuple[float, float, float, float], max_slope_deg: float,
                 obstacle_xy: FloatArray, obstacle_radius: FloatArray, library: ZebraLibrary,
                 water: NDArray[np.float32] | None = None) -> None:
        """``water``: the world's water depth per terrain sample (m, negative above the water line), if it has
        water; zebras stand only where the ground is at least 5 cm above it."""
        self.terrain = terrain
        self.placeable = placeable
        self.library = library
        self.obstacle_xy = np.asarray(obstacle_xy, dtype=np.float64).reshape(-1, 2)
        self.obstacle_radius = np.asarray(obstacle_radius, dtype=np.float64).reshape(-1)
        # Slope mask on the terrain grid, once: a candidate check is then one look-up.
        ny, nx = terrain.shape
        xs = terrain.origin[0] + np.arange(nx) * terrain.resolution
        ys = terrain.origin[1] + np.arange(ny) * terrain.resolution
        gx, gy = np.meshgrid(xs, ys)
        self.slope_ok = terrain.slope_deg(gx, gy) <= max_slope_deg
        if water is not None:
            self.slope_ok &= np.asarray(water) < -0.05
        boxes = np.asarray(library.boxes(), dtype=np.float64)  # (M, F, 2, 3)
        self._box_center_xy = (boxes[:, :, 0, :2] + boxes[:, :, 1, :2]) / 2
        self._box_half_xy = (boxes[:, :, 1, :2] - boxes[:, :, 0, :2]) / 2
        self._contacts = _contact_points(library)  # (M, F, 5, 3): lowest point of each leg and the belly

    def _slope_ok_at(self, xy: FloatArray) -> NDArray[np.bool_]:
        t = self.terrain
        i = np.clip(np.rint((xy[:, 0] - t.origin[0]) / t.resolution).astype(np.int64), 0, t.shape[1] - 1)
        j = np.clip(np.rint((xy[:, 1] - t.origin[1]) / t.resolution).astype(np.int64), 0, t.shape[0] - 1)
        return np.asarray(self.slope_ok[j, i])

    def draw(self, rng: np.random.Generator, pool: ZebraPool, count_range: tuple[int, int],
             scale_range: tuple[float, float], rect_range: tuple[float, float], clip_ids: IntArray,
             max_attempts: int) -> PlacementDraw:
        """Every random draw of one placement, from ``rng`` in a fixed order (before any collision test)."""
        lib = self.library
        x0, y0, x1, y1 = self.placeable
        w, h = rng.uniform(rect_range[0], rect_range[1], size=2)
        if w > x1 - x0 or h > y1 - y0:
            raise PlacementError("rect_max", float(max(w, h)),
                                 f"<= the world's placeable area ({x1 - x0:.0f} x {y1 - y0:.0f} m)")
        cx = rng.uniform(x0 + w / 2, x1 - w / 2)
        cy = rng.uniform(y0 + h / 2, y1 - h / 2)
        n_req = int(rng.integers(count_range[0], count_range[1] + 1))
        ids = np.sort(rng.choice(pool.zebras, size=n_req, replace=False))
        clip = clip_ids[rng.integers(0, len(clip_ids), size=n_req)]
        frame = np.floor(rng.uniform(0, 1, size=n_req) * lib.clip_frames[clip]).astype(np.int64)
        scale = rng.uniform(scale_range[0], scale_range[1], size=n_req)
        yaw = rng.uniform(-np.pi, np.pi, size=n_req)
        # Centre draws for all zebras and attempts at once, consumed in order: same stream, fast.
        cand = np.stack([rng.uniform(cx - w / 2, cx + w / 2, size=(n_req, max_attempts)),
                         rng.uniform(cy - h / 2, cy + h / 2, size=(n_req, max_attempts))], axis=-1)
        return PlacementDraw((float(cx), float(cy)), (float(w), float(h)), ids, clip, frame,
                             lib.clip_start[clip] + frame, scale, yaw, cand)

    def draw_others(self, rng: np.random.Generator, pool: ZebraPool, zebras: PlacementDraw, count_max: int,
                    clip_ids: IntArray, max_attempts: int) -> PlacementDraw:
        """The draws of the other species' animals of a placement (their own stream ``rng``): U{0..count_max} of
        the pool's others, in the zebras' rectangle grown by half (a mixed herd thins out at its edges), their
        own size x U(0.85, 1.1)."""
        lib = self.library
        n = min(int(rng.integers(0, count_max + 1)), pool.others)
        ids = np.sort(pool.zebras + rng.choice(pool.others, size=n, replace=False)) if n else np.zeros(0, np.int64)
        clip = clip_ids[rng.integers(0, len(clip_ids), size=n)]
        frame = np.floor(rng.uniform(0, 1, size=n) * lib.clip_frames[clip]).astype(np.int64)
        scale = rng.uniform(0.85, 1.1, size=n)
        yaw = rng.uniform(-np.pi, np.pi, size=n)
        (cx, cy), (w, h) = zebras.rect_center, zebras.rect_size
        x0, y0, x1, y1 = self.placeable
        cand = np.stack([np.clip(rng.uniform(cx - 0.75 * w, cx + 0.75 * w, size=(n, max_attempts)), x0, x1),
                         np.clip(rng.uniform(cy - 0.75 * h, cy + 0.75 * h, size=(n, max_attempts)), y0, y1)], axis=-1)
        return PlacementDraw(zebras.rect_center, zebras.rect_size, ids, clip, frame, lib.clip_start[clip] + frame,
                             scale, yaw, cand)

    def place(self, rng: np.random.Generator, pool: ZebraPool, count_range: tuple[int, int],
              scale_range: tuple[float, float], rect_range: tuple[float, float], clip_ids: IntArray,
              max_attempts: int, others: tuple[np.random.Generator, int, IntArray] | None = None) -> Herd:
        """One placement: :meth:`draw`, then place the zebras one after another, then the animals of other
        species (``others``: their stream, most per placement and clips) around them by the same rules."""
        d = self.draw(rng, pool, count_range, scale_range, rect_range, clip_ids, max_attempts)
        if others is not None and others[1] > 0 and pool.others:
            o = self.draw_others(others[0], pool, d, others[1], others[2], max_attempts)
            d = PlacementDraw(d.rect_center, d.rect_size, *(np.concatenate([a, b]) for a, b in (
                (d.ids, o.ids), (d.clip, o.clip), (d.frame, o.frame), (d.global_frame, o.global_frame),
                (d.scale, o.scale), (d.yaw, o.yaw), (d.candidates, o.candidates))))
        (cx, cy), (w, h) = d.rect_center, d.rect_size
        ids, clip, frame, gframe = d.ids, d.clip, d.frame, d.global_frame
        scale, yaw, cand = d.scale, d.yaw, d.candidates
        morph = pool.morph[ids]
        half = self._box_half_xy[morph, gframe] * scale[:, None]
        off_local = self._box_center_xy[morph, gframe] * scale[:, None]
        axes = box_axes(yaw)  # (N, 2, 2)
        off = off_local[:, 0, None] * axes[:, 0] + off_local[:, 1, None] * axes[:, 1]

        placed, fp_center = self._pack(cx, cy, w, h, cand, off, half, axes)
        sel = np.flatnonzero(placed)
        centre = fp_center[sel] - off[sel]
        position, rotation = self._stand(centre, yaw[sel], morph[sel], gframe[sel], scale[sel])
        return Herd(
            rect_center=d.rect_center, rect_size=d.rect_size, requested=int((ids < pool.zebras).sum()), ids=ids[sel],
            morph=morph[sel], clip=clip[sel], frame=frame[sel], global_frame=gframe[sel], scale=scale[sel],
            yaw=yaw[sel], position=position, rotation=rotation, footprint_center=fp_center[sel],
            footprint_half=half[sel],
        )

    def _pack(self, cx: float, cy: float, w: float, h: float, cand: FloatArray, off: FloatArray, half: FloatArray,
              axes: FloatArray) -> tuple[NDArray[np.bool_], FloatArray]:
        """Take, zebra after zebra, the first candidate whose footprint is clear; exact, and fast.

        Broad phase: a hash grid of the boxes' bounding circles (cells of ``cell`` metres). Narrow phase:
        the separating axis test between oriented boxes, in plain floats, for the few neighbours found.
        Trees and rocks enter as axis-aligned squares around their footprint circles (conservative).
        """
        n_req, attempts = cand.shape[:2]
        slope_ok = self._slope_ok_at(cand.reshape(-1, 2)).reshape(n_req, attempts).tolist()
        centres = (cand + off[:, None, :]).tolist()
        reach = float(np.hypot(half[:, 0], half[:, 1]).max()) * 2 + 1.0 if n_req else 1.0
        near = np.flatnonzero((np.abs(self.obstacle_xy[:, 0] - cx) <= w / 2 + reach)
                              & (np.abs(self.obstacle_xy[:, 1] - cy) <= h / 2 + reach))
        grid = _BoxGrid()
        for k in near.tolist():
            ox, oy = self.obstacle_xy[k].tolist()
            rad = float(self.obstacle_radius[k])
            grid.insert((ox, oy, rad, rad, 1.0, 0.0, rad * 1.4143))
        placed = np.zeros(n_req, dtype=bool)
        fp_center = np.zeros((n_req, 2))
        e_all, u_all = half.tolist(), axes[:, 0, :].tolist()
        for k in range(n_req):
            e0, e1 = e_all[k]
            ux, uy = u_all[k]
            rk = (e0 * e0 + e1 * e1) ** 0.5
            ok_k, c_k = slope_ok[k], centres[k]
            for a in range(attempts):
                if not ok_k[a]:
                    continue
                x, y = c_k[a]
                if grid.clear(x, y, e0, e1, ux, uy, rk):
                    grid.insert((x, y, e0, e1, ux, uy, rk))
                    placed[k] = True
                    fp_center[k] = (x, y)
                    break
        return placed, fp_center

    def _stand(self, centre: FloatArray, yaw: FloatArray, morph: IntArray, gframe: IntArray,
               scale: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Tilt each zebra to the plane through the ground under its contact points, and rest it there.

        Contact points of a clip frame are those of the lowest point of each leg and of the belly that touch
        the ground in the asset frame (within 5 cm): the four hooves of a standing zebra, folded legs and
        belly of a lying one. The plane is fitted to the ground under them (least squares) and the height
        puts them on it on average.
        """
        n = len(centre)
        if n == 0:
            return np.zeros((0, 3)), np.zeros((0, 3, 3))
        pts = self._contacts[morph, gframe]  # (N, 5, 3) unscaled asset frame
        w = (pts[..., 2] <= pts[..., 2].min(axis=1, keepdims=True) + 0.05).astype(np.float64)
        # Fewer than three contacts (a gait's stride) do not fix a plane: tilt to the ground under all four legs.
        legs = np.array([1.0, 1.0, 1.0, 1.0, 0.0])
        w_fit = np.where(w.sum(axis=1, keepdims=True) >= 3, w, legs)
        local = pts * scale[:, None, None]
        rotation = rot_z(yaw)
        for _ in range(2):  # the contacts' xy depend on the tilt: one refinement is plenty
            world = np.einsum("nij,nkj->nki", rotation, local)
            xy = world[..., :2] + centre[:, None, :]
            h = self.terrain.height_at(xy[..., 0], xy[..., 1])  # (N, 5)
            a = np.concatenate([xy - centre[:, None, :], np.ones((n, 5, 1))], axis=-1) * w_fit[..., None]
            coef = np.linalg.solve(np.einsum("nsi,nsj->nij", a, a) + 1e-9 * np.eye(3),
                                   np.einsum("nsi,ns->ni", a, h * w_fit)[..., None])[..., 0]
            normal = np.stack([-coef[:, 0], -coef[:, 1], np.ones(n)], axis=-1)
            normal /= np.linalg.norm(normal, axis=1, keepdims=True)
            rotation = _tilt_to(normal) @ rot_z(yaw)
        world = np.einsum("nij,nkj->nki", rotation, local)
        xy = world[..., :2] + centre[:, None, :]
        gap = self.terrain.height_at(xy[..., 0], xy[..., 1]) - world[..., 2]
        z = (gap * w).sum(axis=1) / w.sum(axis=1)
        return np.column_stack([centre, z]), rotation


_CONTACTS: dict[str, FloatArray] = {}


def _contact_points(library: ZebraLibrary) -> FloatArray:
    """(M, F, 5, 3) lowest vertex of each leg (fl, fr, hl, hr) and of the barrel, per morph and frame.

    Computed once per baked library and process (it reads every frame's vertices).
    """
    from zebra_sim_ros.zebra.mesh import PART_NAMES

    key = str(library.root)
    if key in _CONTACTS:
        return _CONTACTS[key]

    faces, part = library.faces(0), library.face_part(0)
    out = np.zeros((len(library.morphs), library.n_frames, 5, 3))
    for k, name in enumerate(("leg_fl", "leg_fr", "leg_hl", "leg_hr", "barrel")):
        idx = np.unique(faces[part == PART_NAMES.index(name)])
        for m in range(len(library.morphs)):
            v = np.asarray(library.vertices(m, np.arange(library.n_frames)), dtype=np.float64)[:, idx]  # (F, V, 3)
            low = np.argmin(v[..., 2], axis=1)
            out[m, :, k] = v[np.arange(library.n_frames), low]
    _CONTACTS[key] = out
    return out
