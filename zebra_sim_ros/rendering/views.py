"""From a scene (:class:`~zebra_sim_ros.messages.Scene`) to what the renderer draws: zebras and camera views.

The camera node gets scenes as JSON; ``generate`` and ``zebra-sim render`` get them from the placer core directly.
Both go through :func:`zebras_from_scene`, so a frame rendered from a recorded scene is the frame the live graph
rendered.
"""

from __future__ import annotations

import numpy as np

from zebra_sim_ros.errors import ZebraSimError
from zebra_sim_ros.geometry.frames import xyzw_to_matrix
from zebra_sim_ros.messages import Scene
from zebra_sim_ros.rendering.renderer import CameraView, ZebraSet
from zebra_sim_ros.zebra.asset import ZebraLibrary


def zebras_from_scene(scene: Scene, library: ZebraLibrary) -> ZebraSet:
    """The scene's zebras as arrays the renderer takes (morphs and clip frames looked up in ``library``)."""
    zs = scene.zebras
    try:
        morph = np.array([library.morphs.index(z.morph) for z in zs], dtype=np.int64)
        frame = np.array([library.frame_index(z.clip, z.frame) for z in zs], dtype=np.int64)
    except (ValueError, ZebraSimError) as exc:
        raise ZebraSimError(f"scene {scene.step} refers to a morph or clip frame this zebra asset lacks "
                            f"({exc}); scene asset {scene.asset_digest}, ours {library.manifest['digest']}") from exc
    rot = np.stack([xyzw_to_matrix(z.orientation_xyzw) for z in zs]) if zs else np.zeros((0, 3, 3))
    return ZebraSet(
        ids=np.array([z.id for z in zs], dtype=np.int64), morph=morph, global_frame=frame,
        scale=np.array([z.scale for z in zs]), rotation=rot,
        position=np.array([z.position for z in zs], dtype=np.float64).reshape(-1, 3),
        coat_seed=np.array([z.coat_seed for z in zs], dtype=np.int64),
    )


def views_from_scene(scene: Scene, names: list[str] | None = None) -> list[CameraView]:
    """Camera views of the scene (all, or those named), optical frame poses in map."""
    return [CameraView(c.name, np.array(c.position, dtype=np.float64), xyzw_to_matrix(c.orientation_xyzw))
            for c in scene.cameras if names is None or c.name in names]
