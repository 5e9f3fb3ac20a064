"""The scene of one step: the placer's arrays as a typed :class:`~zebra_sim_ros.messages.Scene`, whose JSON form
(``zebra_sim/scene``, std_msgs/String) is:

Schema ``zebra_sim_ros/scene`` version 1 (all lengths metres, angles degrees, frame ``map`` = ENU)::

    {
      "schema": "zebra_sim_ros/scene", "version": 1,
      "stamp": {"sec": int, "nanosec": int},     # simulated time of the step (also every image's stamp)
      "step": int, "placement": int, "reroll": int,   # step = placement * camera_rerolls + reroll
      "seed": int,                                  # with step, enough to regenerate this scene alone
      "asset_digest": str,                          # zebra asset the clip frames refer to
      "world": {"name": str, "source": str, "seed": int | null, "terrain_prim": str},
      "lighting": {"time_of_day_h", "day_of_year", "latitude_deg", "sun_direction" [3] (towards the sun),
                   "sun_elevation_deg", "sun_azimuth_deg" (clockwise from north), "light_direction" [3],
                   "light_rgb" [3], "light_intensity", "ambient_rgb" [3], "ambient_intensity", "is_night"},
      "rectangle": {"center": [x, y], "size": [w, h]},
      "requested": int, "placed": int,              # zebras asked for and actually placed
      "zebras": [{"id": int (pool index; instance masks use id + 1), "morph": str, "coat_seed": int,
                  "clip": str, "frame": int, "scale": float, "yaw_deg": float,
                  "position": [x, y, z] (asset origin: the ground under the body),
                  "orientation_xyzw": [4] (asset frame x forward, y left, z up, in map),
                  "box": {"center": [3], "size": [3] (length, width, height), "orientation_xyzw": [4]}}],
      "cameras": [{"name": "drone_0", "strategy": "far" | "closeby", "frame_id": "drone_0/camera_optical",
                   "position": [3], "orientation_xyzw": [4] (optical frame: z forward, x right, y down),
                   "yaw_deg", "pitch_deg" (optical-axis elevation, negative looks down), "roll_deg"}],
      "ground": {"tint": [3], "desaturation": float},  # optional, absent = the terrain as authored: linear
                                                    # albedo' = min(mix(albedo, luma, desaturation) * tint, 0.95)
      "datum": {"latitude_deg", "longitude_deg", "altitude_m"}  # map's origin on the Earth (WGS84; map is the
                                                    # local tangent plane there); absent in scenes written before it
    }
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from zebra_sim_ros.geometry.frames import optical_frame
from zebra_sim_ros.geometry.rotations import matrix_to_quat
from zebra_sim_ros.messages import (
    Datum,
    GroundLook,
    Lighting,
    OrientedBox,
    Scene,
    SceneCamera,
    SceneZebra,
    Stamp,
    Weather,
    WorldRef,
)
from zebra_sim_ros.placement.cameras import CameraPose
from zebra_sim_ros.placement.herd import Herd


def scene_camera(c: CameraPose) -> SceneCamera:
    """A drawn camera pose as the scene lists it."""
    q = c.quaternion_xyzw()
    return SceneCamera(c.name, c.strategy, (float(c.position[0]), float(c.position[1]), float(c.position[2])),
                       (float(q[0]), float(q[1]), float(q[2]), float(q[3])), c.yaw_deg, c.pitch_deg, c.roll_deg,
                       optical_frame(c.name))


def scene_zebras(herd: Herd, morph_names: Sequence[str], clip_names: Sequence[str], coat_seeds: np.ndarray,
                 box_center: np.ndarray, box_size: np.ndarray,
                 species: Sequence[str] | None = None) -> tuple[SceneZebra, ...]:
    """The placed zebras of ``herd`` (asset indices named by ``morph_names`` and ``clip_names``) with their coat
    seeds and oriented boxes (``box_center``, ``box_size``: (N, 3) in map, m); ``species`` names each morph's
    species (None: all zebras)."""
    quats = matrix_to_quat(herd.rotation) if herd.count else np.zeros((0, 4))
    out = []
    for i in range(herd.count):
        q = (float(quats[i, 1]), float(quats[i, 2]), float(quats[i, 3]), float(quats[i, 0]))
        box = OrientedBox(_vec3(box_center[i]), _vec3(box_size[i]), q)
        out.append(SceneZebra(int(herd.ids[i]), morph_names[int(herd.morph[i])], int(coat_seeds[i]),
                              clip_names[int(herd.clip[i])], int(herd.frame[i]), float(herd.scale[i]),
                              float(np.degrees(herd.yaw[i])), _vec3(herd.position[i]), q, box,
                              species[int(herd.morph[i])] if species is not None else "zebra"))
    return tuple(out)


def _vec3(v: Any) -> tuple[float, float, float]:
    return float(v[0]), float(v[1]), float(v[2])


def build_scene(step: int, placement: int, reroll: int, seed: int, stamp_ns: int, world: WorldRef,
                asset_digest: str, zebras: tuple[SceneZebra, ...], herd: Herd, lighting: Lighting,
                cameras: Sequence[CameraPose], ground: GroundLook, weather: Weather, datum: Datum) -> Scene:
    """The typed scene of one step (the placement rectangle and the count asked for come from ``herd``)."""
    return Scene(Stamp.from_ns(stamp_ns), step, placement, reroll, seed, asset_digest, world, lighting,
                 (float(herd.rect_center[0]), float(herd.rect_center[1])),
                 (float(herd.rect_size[0]), float(herd.rect_size[1])), int(herd.requested), zebras,
                 tuple(scene_camera(c) for c in cameras), ground, weather, datum)
