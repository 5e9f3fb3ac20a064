"""From a scene JSON (``/zebra_sim/scene``) to what the renderer draws: zebras, lighting, camera views.

The camera node gets scenes as JSON; ``zebra-sim render`` gets them from the placer core directly. Both go
through :func:`zebras_from_scene`, so a frame rendered from a recorded scene is the frame the live graph
rendered.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from zebra_sim_ros.errors import ZebraSimError
from zebra_sim_ros.geometry.rotations import quat_to_matrix
from zebra_sim_ros.placement.ground import GroundLook
from zebra_sim_ros.placement.sun import Lighting
from zebra_sim_ros.rendering.renderer import CameraView, ZebraSet
from zebra_sim_ros.zebra.asset import ZebraLibrary


def _matrix_xyzw(q: list[float]) -> np.ndarray:
    x, y, z, w = q
    return np.asarray(quat_to_matrix(np.array([w, x, y, z], dtype=np.float64)))


def zebras_from_scene(scene: dict[str, Any], library: ZebraLibrary) -> ZebraSet:
    """The scene's zebras as arrays the renderer takes (morphs and clip frames looked up in ``library``)."""
    zs = scene["zebras"]
    try:
        morph = np.array([library.morphs.index(z["morph"]) for z in zs], dtype=np.int64)
        frame = np.array([library.frame_index(z["clip"], int(z["frame"])) for z in zs], dtype=np.int64)
    except (ValueError, ZebraSimError) as exc:
        raise ZebraSimError(f"scene {scene.get('step')} refers to a morph or clip frame this zebra asset lacks "
                            f"({exc}); scene asset {scene.get('asset_digest')}, ours {library.manifest['digest']}") \
            from exc
    rot = np.stack([_matrix_xyzw(z["orientation_xyzw"]) for z in zs]) if zs else np.zeros((0, 3, 3))
    return ZebraSet(
        ids=np.array([int(z["id"]) for z in zs], dtype=np.int64), morph=morph, global_frame=frame,
        scale=np.array([float(z["scale"]) for z in zs]), rotation=rot,
        position=np.array([z["position"] for z in zs], dtype=np.float64).reshape(-1, 3),
        coat_seed=np.array([int(z["coat_seed"]) for z in zs], dtype=np.int64),
    )


def ground_from_scene(scene: dict[str, Any]) -> GroundLook:
    """The scene's ground look (the terrain as authored when the scene has none)."""
    return GroundLook.from_dict(scene.get("ground"))


def lighting_from_scene(scene: dict[str, Any]) -> Lighting:
    """The scene's lighting."""
    d = dict(scene["lighting"])
    for key in ("sun_direction", "light_direction", "light_rgb", "ambient_rgb"):
        d[key] = tuple(float(v) for v in d[key])
    return Lighting(**d)


def views_from_scene(scene: dict[str, Any], names: list[str] | None = None) -> list[CameraView]:
    """Camera views of the scene (all, or those named), optical frame poses in map."""
    out = []
    for c in scene["cameras"]:
        if names is None or c["name"] in names:
            out.append(CameraView(c["name"], np.array(c["position"], dtype=np.float64),
                                  _matrix_xyzw(c["orientation_xyzw"])))
    return out


def world_source(scene: dict[str, Any]) -> tuple[str, str, int]:
    """(source, terrain_prim, seed) to pass to ``load_world`` for the scene's world."""
    w = scene["world"]
    source = str(w["source"])
    if source.startswith("preset:"):
        source = source.split(":", 1)[1]
    return source, str(w.get("terrain_prim", "/World/Terrain")), int(w.get("seed") or 0)
