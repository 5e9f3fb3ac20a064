"""One herd counted once across cameras: the optimal assignment against brute force, and the joining of views
against herds whose every point is known."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.geometry.census import _hungarian, assign, join_views, one_per_place
from zebra_sim_ros.geometry.locate import box_depths


def _best_partial(d: np.ndarray, gate: float) -> float:
    """The least total of every partial matching of ``d`` within ``gate`` (a pair its distance, a row or column
    left alone gate / 2), by trying them all."""
    n, m = d.shape
    best = np.inf
    for k in range(min(n, m) + 1):
        for rows in itertools.combinations(range(n), k):
            for cols in itertools.permutations(range(m), k):
                if all(d[r, c] < gate for r, c in zip(rows, cols, strict=True)):
                    total = sum(d[r, c] for r, c in zip(rows, cols, strict=True)) + gate / 2 * (n + m - 2 * k)
                    best = min(best, total)
    return best


def test_the_assignment_is_optimal() -> None:
    """The square solver against every permutation; the gated one against every partial matching, on random
    small problems, dense and sparse; each row and column used once."""
    rng = np.random.default_rng(7)
    for _ in range(60):
        n = int(rng.integers(1, 7))
        cost = rng.random((n, n)) * 10
        col = _hungarian(cost)
        best = min(sum(cost[i, p[i]] for i in range(n)) for p in itertools.permutations(range(n)))
        assert sorted(col.tolist()) == list(range(n)) and cost[np.arange(n), col].sum() == pytest.approx(best)
    for _ in range(80):
        n, m = int(rng.integers(0, 5)), int(rng.integers(0, 5))
        d = rng.random((n, m)) * float(rng.choice([1.5, 4.0]))
        rows, cols = assign(d, 1.0)
        assert len(set(rows.tolist())) == len(rows) and len(set(cols.tolist())) == len(cols)
        assert np.all(d[rows, cols] < 1.0)
        total = d[rows, cols].sum() + 0.5 * (n + m - 2 * len(rows))
        assert total == pytest.approx(_best_partial(d, 1.0)), d
    with pytest.raises(ParameterError, match="gate"):
        assign(np.zeros((2, 2)), 0.0)


def test_the_assignment_beats_greedy_in_a_packed_pair() -> None:
    """Two animals 1.1 m apart, the second view's points 0.6 m off, b's towards a: greedy nearest joins a to b's
    point (0.5 m) and leaves b and a's own point alone; the assignment joins each to its own (0.6 + 0.6 < 0.5 + 1)."""
    d = np.array([[0.6, 0.5], [1.6, 0.6]])  # rows: the first view's a, b; columns: the second view's a, b
    rows, cols = assign(d, 1.0)
    assert list(zip(rows.tolist(), cols.tolist(), strict=True)) == [(0, 0), (1, 1)]


def _herd(rng: np.random.Generator, n: int, spacing: float) -> np.ndarray:
    """``n`` animals on a jittered grid ``spacing`` m apart, on the ground (z 0.7)."""
    side = int(np.ceil(np.sqrt(n)))
    grid = np.array([(i % side, i // side) for i in range(n)], np.float64) * spacing
    return np.column_stack([grid + rng.uniform(-0.15, 0.15, grid.shape) * spacing, np.full(n, 0.7)])


def _views(rng: np.random.Generator, herd: np.ndarray, cameras: np.ndarray, along: float, across: float,
           seen: float) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Each camera's points of the animals it sees (a ``seen`` share, shuffled): each off along its ray (seen from
    above) by ``along`` m (normal), a sixth of them by up to 1.5 m (the depth's heavy tail: ground or another
    animal in the box), and across it by ``across`` m (normal); and the ids of its points."""
    points, ids = [], []
    for cam in cameras:
        keep = rng.permutation(np.flatnonzero(rng.random(len(herd)) < seen))
        p = herd[keep].copy()
        ray = p[:, :2] - cam[:2]
        ray /= np.linalg.norm(ray, axis=1, keepdims=True)
        normal = np.column_stack([-ray[:, 1], ray[:, 0]])
        off = np.where(rng.random((len(p), 1)) < 1 / 6, rng.uniform(-1.5, 1.5, (len(p), 1)),
                       rng.normal(0, along, (len(p), 1)))
        p[:, :2] += ray * off + normal * rng.normal(0, across, (len(p), 1))
        points.append(p)
        ids.append(keep)
    return points, ids


def test_three_views_of_a_herd_count_each_animal_once() -> None:
    """Three cameras 80 m from a herd packed 2.5 m apart, at 0, 100 and 220 degrees, each seeing 70% of it, each
    point off along its ray (20 cm, a sixth by up to 1.5 m) and 5 cm across: the animals seen are counted within 3
    (-3 to +1 of 58 over 40 seeds of this test; every assertion held on 60), each animal's points from one animal
    but for a few, and a position seen twice or more is nearer the animal than one view's. A circle as tight as the
    across-error (no regard to the ray) splits animals (+4 to +16 over those seeds); summing the views counts twice
    the herd."""
    rng = np.random.default_rng(11)
    herd = _herd(rng, 60, 2.5)
    centre = herd[:, :2].mean(axis=0)
    angles = np.radians([0.0, 100.0, 220.0])
    cameras = np.column_stack([centre + 80 * np.column_stack([np.cos(angles), np.sin(angles)]), np.full(3, 60.0)])
    points, ids = _views(rng, herd, cameras, along=0.2, across=0.05, seen=0.7)
    census = join_views(points, list(cameras))
    truth = set(np.concatenate(ids).tolist())
    assert abs(census.count - len(truth)) <= 3, (census.count, len(truth))
    animals = [{int(ids[v][j]) for v, j in census.points_of(a)} for a in range(census.count)]
    assert sum(len(a) > 1 for a in animals) <= 6, animals  # animals that join two (0-5 over 60 seeds)
    every = sorted(p for a in range(census.count) for p in census.points_of(a))
    assert every == [(v, j) for v, p in enumerate(points) for j in range(len(p))]  # every point in one animal
    pure = [i for i, a in enumerate(animals) if len(a) == 1 and census.views_per_animal[i] >= 2]
    own = herd[[next(iter(animals[i])) for i in pure]]
    fused = np.linalg.norm(census.positions[pure, :2] - own[:, :2], axis=1)
    single = np.concatenate([np.linalg.norm(p[:, :2] - herd[i, :2], axis=1) for p, i in zip(points, ids, strict=True)])
    assert len(pure) > 30 and np.median(fused) < np.median(single), (np.median(fused), np.median(single))
    circle = join_views(points, list(cameras), along_m=0.15, across_m=0.15)
    assert circle.count - len(truth) > abs(census.count - len(truth)), (circle.count, census.count, len(truth))
    assert sum(len(p) for p in points) > 1.8 * len(truth)  # the scene itself: what summing the views would count


def test_join_views_edges() -> None:
    """No views, empty views, a non-finite point left out, a point straight under its camera; bad arguments named."""
    assert join_views([], []).count == 0
    empty = join_views([np.zeros((0, 3)), np.zeros((0, 3))], [np.zeros(3), np.ones(3)])
    assert empty.count == 0 and empty.members.shape == (0, 2)
    points = [np.array([[0.0, 0, 0], [np.nan, 0, 0]]), np.array([[0.05, 0, 0.1], [30.0, 0, 0]])]
    census = join_views(points, [np.array([0.0, 0, 50]), np.array([10.0, 0, 50])])  # the first straight below
    assert census.count == 2 and census.members.tolist() == [[0, 0], [-1, 1]]
    assert census.positions[0] == pytest.approx([0.0, 0.0, 0.05], abs=0.05)
    with pytest.raises(ParameterError, match="along_m"):
        join_views(points, [np.zeros(3)] * 2, along_m=0.0)
    with pytest.raises(ValueError, match="one camera position"):
        join_views(points, [np.zeros(3)])


def test_one_animal_boxed_twice_by_one_camera_is_one_animal() -> None:
    """One view's points closer than the separation are one animal, the higher score standing for them (the
    nearest kept one where two are near); farther ones stay apart; separation 0 never joins; the animal's points
    list every box."""
    pts = np.array([[0.0, 0, 0], [0.3, 0, 0], [0.9, 0, 0], [1.15, 0, 0]])
    assert one_per_place(pts, np.array([1, 0, 2, 3]), 0.5).tolist() == [1, 1, 2, 2]
    assert one_per_place(pts, np.array([0, 1, 2, 3]), 0.0).tolist() == [0, 1, 2, 3]
    between = np.array([[0.0, 0, 0], [0.6, 0, 0], [0.35, 0, 0]])  # the last near both kept ones: the nearer
    assert one_per_place(between, np.array([0, 1, 2]), 0.5).tolist() == [0, 1, 1]
    other = np.array([[0.25, 0.05, 0], [1.0, 0.05, 0]])
    census = join_views([pts, other], [np.array([0.0, -60, 50]), np.array([60.0, 0, 50])],
                        scores=[np.array([0.3, 0.9, 0.8, 0.5]), np.array([0.7, 0.6])])
    assert census.count == 2 and census.representative[0].tolist() == [1, 1, 2, 2]  # the higher scores stand
    assert sorted(sorted(census.points_of(a)) for a in range(2)) == [[(0, 0), (0, 1), (1, 0)], [(0, 2), (0, 3), (1, 1)]]
    apart = join_views([pts, other], [np.array([0.0, -60, 50]), np.array([60.0, 0, 50])], separation_m=0.0)
    assert apart.count == 4 and apart.representative[0].tolist() == [0, 1, 2, 3]
    with pytest.raises(ValueError, match="3 scores for 4 points"):
        join_views([pts], [np.zeros(3)], scores=[np.ones(3)])
    with pytest.raises(ParameterError, match="separation_m"):
        join_views([pts], [np.zeros(3)], separation_m=-1.0)


def test_a_box_depth_is_its_animal_not_the_ground_behind_it() -> None:
    """A box whose animal holds 40% of its pixels, the ground behind it the rest, spread over 10 m of depth (a
    slanted view): the densest 1.5 m of depths is the animal; a plain median is on the ground."""
    depth = np.repeat(np.linspace(52.0, 62.0, 20, dtype=np.float32)[:, None], 20, axis=1)  # ground: row by row
    depth[12:20, :] = 50.0  # the animal: 8 of 20 rows
    box = np.array([[0.0, 0, 20, 20]])
    assert box_depths(depth, box)[0] == pytest.approx(50.0)
    assert box_depths(depth, box, window_m=0.0)[0] > 52.0  # 2 m off
    with pytest.raises(ParameterError, match="window_m"):
        box_depths(depth, box, window_m=-1.0)
