"""The world's data types: :class:`World`, its vegetation :class:`Instances` and :class:`Obstacles`.

Frame: ``map``, ENU (REP 103/105): x east, y north, z up, metres. Builders live elsewhere: presets in
:mod:`zebra_sim_ros.world.world`, USD stages in :mod:`zebra_sim_ros.world.usd_io`; both import from here, so
neither imports the other.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.errors import ZebraSimError
from zebra_sim_ros.world.paint import paint_ground
from zebra_sim_ros.world.presets import MaterialLayer, Sky, srgb
from zebra_sim_ros.world.terrain import Heightfield
from zebra_sim_ros.world.vegetation import PrototypeMesh

FloatArray = NDArray[np.float64]


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
    (optional, (ny, nx, 3)) overrides the colours painted from ``materials``. ``water`` (optional, (ny, nx)
    float32) is the depth of open water per sample in metres, negative above the water line (how far above it);
    the terrain there is the flat water surface.
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
    water: NDArray[np.float32] | None = None

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


OBSTACLE_KINDS = ("tree", "rock", "prop")
"""Kinds of instances a zebra keeps out of (bushes and grass it may stand in)."""


def build_obstacles(vegetation: dict[str, Instances], radius_at: dict[str, tuple[float, float]]) -> Obstacles:
    """Obstacles from tree, rock and prop instances; ``radius_at[name]`` = (radius at scale 1, clearance) m."""
    pos, rad, kinds = [], [], []
    for name in sorted(vegetation):
        inst = vegetation[name]
        if inst.kind not in OBSTACLE_KINDS or name not in radius_at or not len(inst):
            continue
        r1, clearance = radius_at[name]
        pos.append(inst.positions)
        rad.append(r1 * inst.scale + clearance)
        kinds += [inst.kind] * len(inst)
    if not pos:
        return Obstacles.empty()
    return Obstacles(np.concatenate(pos), np.concatenate(rad), tuple(kinds))
