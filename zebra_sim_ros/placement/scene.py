"""The scene of one step and its JSON form (``/zebra_sim/scene``, std_msgs/String).

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
      "cameras": [{"name": "drone_0", "strategy": "far" | "closeby", "frame_id": "drone_0_camera_optical",
                   "position": [3], "orientation_xyzw": [4] (optical frame: z forward, x right, y down),
                   "yaw_deg", "pitch_deg" (optical-axis elevation, negative looks down), "roll_deg"}],
      "ground": {"tint": [3], "desaturation": float}   # optional, absent = the terrain as authored: linear
                                                    # albedo' = min(mix(albedo, luma, desaturation) * tint, 0.95)
    }
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import numpy as np

from zebra_sim_ros.errors import ZebraSimError
from zebra_sim_ros.geometry.rotations import matrix_to_quat
from zebra_sim_ros.placement.cameras import CameraPose
from zebra_sim_ros.placement.ground import GroundLook
from zebra_sim_ros.placement.herd import Herd
from zebra_sim_ros.placement.sun import Lighting

SCHEMA = "zebra_sim_ros/scene"
VERSION = 1


class SceneFormatError(ZebraSimError):
    """A scene message is not valid JSON of a schema version we read."""


@dataclass(frozen=True)
class Scene:
    """Everything drawn for one step."""

    step: int
    placement: int
    reroll: int
    seed: int
    stamp_ns: int
    world: dict[str, Any]
    asset_digest: str
    morph_names: tuple[str, ...]
    clip_names: tuple[str, ...]
    coat_seeds: np.ndarray  # (N,) of the placed zebras
    herd: Herd
    box_center: np.ndarray  # (N, 3)
    box_size: np.ndarray  # (N, 3)
    lighting: Lighting
    cameras: tuple[CameraPose, ...]
    ground: GroundLook = GroundLook()  # the terrain's colour as authored, or this step's randomised look

    def to_dict(self) -> dict[str, Any]:
        """The scene as the versioned JSON structure of the module docstring."""
        h = self.herd
        quats = matrix_to_quat(h.rotation) if h.count else np.zeros((0, 4))
        zebras = []
        for i in range(h.count):
            q = [float(quats[i, 1]), float(quats[i, 2]), float(quats[i, 3]), float(quats[i, 0])]
            zebras.append({
                "id": int(h.ids[i]), "morph": self.morph_names[int(h.morph[i])], "coat_seed": int(self.coat_seeds[i]),
                "clip": self.clip_names[int(h.clip[i])], "frame": int(h.frame[i]), "scale": float(h.scale[i]),
                "yaw_deg": float(np.degrees(h.yaw[i])), "position": [float(v) for v in h.position[i]],
                "orientation_xyzw": q,
                "box": {"center": [float(v) for v in self.box_center[i]], "size": [float(v) for v in self.box_size[i]],
                        "orientation_xyzw": q},
            })
        return {
            "schema": SCHEMA, "version": VERSION,
            "stamp": {"sec": self.stamp_ns // 1_000_000_000, "nanosec": self.stamp_ns % 1_000_000_000},
            "step": self.step, "placement": self.placement, "reroll": self.reroll, "seed": self.seed,
            "asset_digest": self.asset_digest, "world": self.world, "lighting": self.lighting.to_dict(),
            "rectangle": {"center": list(h.rect_center), "size": list(h.rect_size)},
            "requested": h.requested, "placed": h.count, "zebras": zebras,
            "cameras": [c.to_dict() for c in self.cameras],
            **({} if self.ground.is_identity else {"ground": self.ground.to_dict()}),
        }

    def to_json(self) -> str:
        """Compact JSON text of :meth:`to_dict`."""
        return json.dumps(self.to_dict(), separators=(",", ":"))


def parse_scene(text: str) -> dict[str, Any]:
    """Parse and check a scene message; raises :class:`SceneFormatError` saying what is wrong."""
    try:
        d = json.loads(text)
    except json.JSONDecodeError as exc:
        raise SceneFormatError(f"scene is not JSON: {exc}") from exc
    if not isinstance(d, dict) or d.get("schema") != SCHEMA:
        raise SceneFormatError(f"not a {SCHEMA} message (schema={d.get('schema') if isinstance(d, dict) else None!r})")
    if d.get("version") != VERSION:
        raise SceneFormatError(f"scene schema version {d.get('version')!r}; this build reads {VERSION}")
    for key in ("stamp", "step", "seed", "world", "lighting", "zebras", "cameras"):
        if key not in d:
            raise SceneFormatError(f"scene lacks '{key}'")
    return d
