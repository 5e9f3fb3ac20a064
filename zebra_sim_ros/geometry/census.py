"""One herd seen by several cameras, counted once: each camera's detections placed on the map
(:mod:`zebra_sim_ros.geometry.locate`) joined across cameras into animals.

Drones that overlap see an animal up to once each; summing their counts counts it up to that many times (the
double counting of every aerial survey with overlapping images). Here the cameras' points of one instant are joined
view by view: each new view's points are assigned to the animals found so far by an optimal assignment (the least
total Mahalanobis distance on the ground, the map's x and y: a placed point is off mostly along its camera's ray,
and its height is its visible surface's, which differs by view), a pair joined only under ``gate`` standard
deviations; a point left over is an animal no earlier view saw. An animal holds at most one point of each view (one
camera does not see one animal twice: a view's points closer than ``separation_m`` are first taken as one), which
greedy nearest-neighbour joining breaks in a herd packed a metre or two apart: one wrong join there pushes the right
point out, and it is counted again. Pure numpy, no ROS.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.errors import ParameterError

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
# A placed detection's error on the ground, one standard deviation along its camera's ray and across it, and the
# join's gate in standard deviations (BENCHMARKS.md, "The census")
CENSUS_ALONG_M, CENSUS_ACROSS_M, CENSUS_GATE = 0.5, 0.15, 4.0
CENSUS_SEPARATION_M = 0.5  # one view's detections closer than this on the ground are one animal


def _hungarian(cost: FloatArray) -> IntArray:
    """The column of each row in a least-cost assignment of a square, finite ``cost`` (the shortest augmenting
    path form of the Hungarian method, O(n^3), its inner loop vectorised)."""
    n = cost.shape[0]
    u, v = np.zeros(n + 1), np.zeros(n + 1)
    row_of = np.zeros(n + 1, np.int64)  # 1-based row assigned to each 1-based column; 0: none (column 0: the root)
    way = np.zeros(n + 1, np.int64)
    for i in range(1, n + 1):
        row_of[0] = i
        j0 = 0
        minv = np.full(n + 1, np.inf)
        used = np.zeros(n + 1, bool)
        while True:
            used[j0] = True
            i0 = row_of[j0]
            free = ~used
            free[0] = False
            reduced = cost[i0 - 1] - u[i0] - v[1:]
            better = free[1:] & (reduced < minv[1:])
            minv[1:][better] = reduced[better]
            way[1:][better] = j0
            masked = np.where(free, minv, np.inf)
            j1 = int(np.argmin(masked))
            delta = masked[j1]
            u[row_of[used]] += delta
            v[used] -= delta
            minv[free] -= delta
            j0 = j1
            if row_of[j0] == 0:
                break
        while j0:  # augment along the path
            j1 = int(way[j0])
            row_of[j0] = row_of[j1]
            j0 = j1
    col_of = np.zeros(n, np.int64)
    col_of[row_of[1:] - 1] = np.arange(n)
    return col_of


def _components(n: int, m: int, rows: IntArray, cols: IntArray) -> list[tuple[IntArray, IntArray]]:
    """The connected parts of the bipartite graph of ``n`` rows and ``m`` columns with edges ``rows[k]-cols[k]``:
    per part, its rows and its columns (parts of one side only left out)."""
    parent = np.arange(n + m)

    def root(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = int(parent[a])
        return a

    for r, c in zip(rows.tolist(), cols.tolist(), strict=True):
        a, b = root(r), root(n + c)
        if a != b:
            parent[a] = b
    roots = np.array([root(a) for a in range(n + m)], np.int64)
    parts = []
    for r0 in np.unique(roots[np.unique(rows)]) if len(rows) else ():
        members = np.flatnonzero(roots == r0)
        parts.append((members[members < n], members[members >= n] - n))
    return parts


def assign(distance: FloatArray, gate: float) -> tuple[IntArray, IntArray]:
    """Pairs (rows, columns) of the ``(N, M)`` ``distance`` matrix that join each row to at most one column and
    each column to at most one row, with the least total: a joined pair costs its distance, a row or column left
    alone costs ``gate / 2``, so a pair is joined only within ``gate`` and only if no better arrangement of its
    neighbours needs either (an optimal assignment, solved per connected group of pairs within the gate)."""
    if not (np.isfinite(gate) and gate > 0):
        raise ParameterError("gate", gate, "a distance above 0")
    distance = np.asarray(distance, dtype=np.float64)
    if distance.ndim != 2:
        raise ValueError(f"a distance matrix of N x M, not {distance.shape}")
    n, m = distance.shape
    near = np.isfinite(distance) & (distance < gate)
    rows, cols = np.nonzero(near)
    out_r: list[int] = []
    out_c: list[int] = []
    for pr, pc in _components(n, m, rows.astype(np.int64), cols.astype(np.int64)):
        a, b = len(pr), len(pc)
        if a == 1 and b == 1:
            out_r.append(int(pr[0]))
            out_c.append(int(pc[0]))
            continue
        big = gate * (a + b + 1)  # above any all-alone arrangement's total: never chosen
        sub = distance[np.ix_(pr, pc)]
        sub = np.where(near[np.ix_(pr, pc)], sub, big)
        # rows then "alone" slots for the columns; columns then "alone" slots for the rows
        full = np.zeros((a + b, b + a))
        full[:a, :b] = sub
        full[:a, b:] = np.where(np.eye(a, dtype=bool), gate / 2, big)
        full[a:, :b] = np.where(np.eye(b, dtype=bool), gate / 2, big)
        col_of = _hungarian(full)
        for i in range(a):
            j = int(col_of[i])
            if j < b and near[pr[i], pc[j]]:
                out_r.append(int(pr[i]))
                out_c.append(int(pc[j]))
    order = np.argsort(out_r, kind="stable")
    return np.asarray(out_r, np.int64)[order], np.asarray(out_c, np.int64)[order]


@dataclass(frozen=True)
class Census:
    """Animals found across views: per animal its position (on the ground the views' points weighed by how well
    each fixes it, :func:`join_views`; its height their mean) and, per view, the index of its point in that view's
    points (-1: that view has none of it)."""

    positions: FloatArray  # (A, 3)
    members: IntArray  # (A, V)
    # per view, each point's representative: the point of the same place that joined (itself, another within
    # ``separation_m``: :func:`one_per_place`; -1: a non-finite point, left out)
    representative: tuple[IntArray, ...]

    @property
    def count(self) -> int:
        """How many animals."""
        return int(len(self.positions))

    @property
    def views_per_animal(self) -> IntArray:
        """How many views saw each animal."""
        return np.asarray((self.members >= 0).sum(axis=1), np.int64)

    def points_of(self, animal: int) -> list[tuple[int, int]]:
        """Every point of ``animal``, as (view, index): per view its representative and the points it stands for."""
        return [(v, int(i)) for v, j in enumerate(self.members[animal].tolist()) if j >= 0
                for i in np.flatnonzero(self.representative[v] == j)]


def one_per_place(points: FloatArray, order: IntArray, separation_m: float) -> IntArray:
    """Per point of one view (``(N, 3)``, finite), its representative: taken in ``order`` (best first), a point
    closer than ``separation_m`` on the ground to one already kept stands for the nearest of those, else for
    itself. One camera sees an animal once: two of its detections that close are one animal boxed twice (a detector
    whose non-maximum suppression kept a second, partial box), not two animals."""
    reps = np.full(len(points), -1, np.int64)
    kept: list[int] = []
    for i in np.asarray(order, np.int64).tolist():
        if kept and separation_m > 0:
            gaps = np.linalg.norm(points[kept, :2] - points[i, :2], axis=1)
            j = int(np.argmin(gaps))
            if gaps[j] < separation_m:
                reps[i] = kept[j]
                continue
        reps[i] = i
        kept.append(i)
    return reps


def _information(points: FloatArray, origin: FloatArray, along_m: float, across_m: float) -> FloatArray:
    """Per point the (2, 2) inverse covariance of its ground position: ``along_m`` along its camera's ray (as seen
    from above), ``across_m`` across it. A point with no horizontal ray (straight under the camera) gets
    ``across_m`` both ways."""
    ray = points[:, :2] - np.asarray(origin, dtype=np.float64).reshape(3)[:2]
    length = np.linalg.norm(ray, axis=1, keepdims=True)
    r = np.where(length > 1e-9, ray / np.maximum(length, 1e-9), 0.0)
    n = np.stack([-r[:, 1], r[:, 0]], axis=1)
    flat = length[:, 0] <= 1e-9
    w = (r[:, :, None] * r[:, None, :]) / along_m ** 2 + (n[:, :, None] * n[:, None, :]) / across_m ** 2
    w[flat] = np.eye(2) / across_m ** 2
    return np.asarray(w)


def join_views(points: Sequence[FloatArray], origins: Sequence[FloatArray], along_m: float = CENSUS_ALONG_M,
               across_m: float = CENSUS_ACROSS_M, gate: float = CENSUS_GATE,
               separation_m: float = CENSUS_SEPARATION_M, scores: Sequence[FloatArray] | None = None) -> Census:
    """The animals that ``points`` (per view, ``(N_v, 3)`` map coordinates of one instant; rows with a non-finite
    coordinate are left out) seen from ``origins`` (per view, its camera's position in ``map``) show, joined view by
    view in the given order (module docstring). First, a view's points closer than ``separation_m`` on the ground
    are one animal (:func:`one_per_place`, the higher of their ``scores`` standing for them; without scores, the
    earlier; 0: never).

    A point placed from depth is off mostly along its camera's ray (the depth of a small or partly hidden animal's
    box mixes in what lies behind or in front of it), little across it: on the ground each point is taken to be off
    by ``along_m`` along the ray and ``across_m`` across (one standard deviation each). Each animal's position is
    its points weighed by those (two views from different sides fix it where their rays cross), and a new point
    joins an animal by their Mahalanobis distance (in standard deviations of the two together) under ``gate``,
    solved for the whole view at once (:func:`assign`)."""
    for name, value in (("along_m", along_m), ("across_m", across_m), ("gate", gate)):
        if not (np.isfinite(value) and value > 0):
            raise ParameterError(name, value, "above 0")
    if not (np.isfinite(separation_m) and separation_m >= 0):
        raise ParameterError("separation_m", separation_m, "0 (never) or more, in metres")
    if len(origins) != len(points) or (scores is not None and len(scores) != len(points)):
        raise ValueError(f"one camera position (and one score array, if any) per view: {len(points)} views, "
                         f"{len(origins)} positions, {'no' if scores is None else len(scores)} score arrays")
    n_views = len(points)
    info = np.zeros((0, 2, 2))  # per animal: the sum of its points' information
    weighted = np.zeros((0, 2))  # per animal: the sum of information x point
    heights = np.zeros(0)
    members = np.zeros((0, n_views), np.int64)
    representative = []
    for v, (pts, origin) in enumerate(zip(points, origins, strict=True)):
        pts = np.asarray(pts, dtype=np.float64).reshape(-1, 3)
        finite = np.flatnonzero(np.all(np.isfinite(pts), axis=1))
        if scores is not None:
            score = np.asarray(scores[v], dtype=np.float64).reshape(-1)
            if len(score) != len(pts):
                raise ValueError(f"view {v}: {len(score)} scores for {len(pts)} points")
            order = np.argsort(-score[finite], kind="stable")
        else:
            order = np.arange(len(finite))
        rep = np.full(len(pts), -1, np.int64)
        rep[finite] = finite[one_per_place(pts[finite], order, separation_m)]
        representative.append(rep)
        idx = np.flatnonzero(rep == np.arange(len(pts)))  # the representatives, in the view's order
        pts = pts[idx]
        w = _information(pts, origin, along_m, across_m)
        cov = np.linalg.inv(w) if len(pts) else np.zeros((0, 2, 2))
        if len(info) and len(pts):
            animal_cov = np.linalg.inv(info)
            means = np.einsum("aij,aj->ai", animal_cov, weighted)
            gap = pts[None, :, :2] - means[:, None, :]  # (A, N, 2)
            both = np.linalg.inv(animal_cov[:, None] + cov[None])  # (A, N, 2, 2)
            distance = np.sqrt(np.einsum("ani,anij,anj->an", gap, both, gap))
        else:
            distance = np.zeros((len(info), len(pts)))
        rows, cols = assign(distance, gate)
        members[rows, v] = idx[cols]
        info[rows] += w[cols]
        weighted[rows] += np.einsum("nij,nj->ni", w[cols], pts[cols, :2])
        heights[rows] += pts[cols, 2]
        alone = np.ones(len(pts), bool)
        alone[cols] = False
        new = np.full((int(alone.sum()), n_views), -1, np.int64)
        new[:, v] = idx[alone]
        members = np.vstack([members, new])
        info = np.concatenate([info, w[alone]])
        weighted = np.concatenate([weighted, np.einsum("nij,nj->ni", w[alone], pts[alone, :2])])
        heights = np.concatenate([heights, pts[alone, 2]])
    ground = np.einsum("aij,aj->ai", np.linalg.inv(info), weighted) if len(info) else np.zeros((0, 2))
    seen = np.maximum((members >= 0).sum(axis=1), 1)
    return Census(np.column_stack([ground, heights / seen]).reshape(-1, 3), members, tuple(representative))
