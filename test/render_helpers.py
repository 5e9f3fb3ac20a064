"""Small worlds of known geometry for renderer tests."""

from __future__ import annotations

import numpy as np

from zebra_sim_ros.world.presets import Sky
from zebra_sim_ros.world.terrain import Heightfield
from zebra_sim_ros.world.world import Instances, Obstacles, World


def cube_mesh(size: float, rgb: tuple[float, float, float] = (0.5, 0.3, 0.2), height: float | None = None):  # type: ignore[no-untyped-def]
    """An axis-aligned box of side ``size`` (and ``height``, default ``size``) on z = 0, centred on x = y = 0."""
    h = size / 2
    top = size if height is None else height
    v = np.array([[x, y, z] for z in (0.0, top) for y in (-h, h) for x in (-h, h)], dtype=np.float32)
    f = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4], [2, 6, 3], [3, 6, 7],
                  [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]], dtype=np.int32)
    return v, f, np.tile(np.array(rgb, dtype=np.float32), (8, 1))


def flat_world(things: dict[str, tuple[tuple, list[tuple[float, float, float]]]] | None = None,
               size: int = 200) -> World:
    """A flat world at z = 0 with prototypes placed at the given points: {name: (mesh, [(x, y, scale)])}."""
    h = np.zeros((size + 1, size + 1), dtype=np.float32)
    terrain = Heightfield((-size / 2, -size / 2), 1.0, h)
    prototypes, vegetation = {}, {}
    for name, (mesh, places) in (things or {}).items():
        prototypes[name] = mesh
        p = np.array(places, dtype=np.float64)
        vegetation[name] = Instances(name, np.column_stack([p[:, :2], np.zeros(len(p))]), np.zeros(len(p)), p[:, 2],
                                     kind="rock")
    return World(name="flat", source="test", seed=0, terrain=terrain, placeable=(-50, -50, 50, 50), max_slope_deg=30,
                 obstacles=Obstacles.empty(), vegetation=vegetation, prototypes=prototypes, materials=(), sky=Sky(),
                 ground_rgb=np.full((size + 1, size + 1, 3), 0.3, dtype=np.float32))
