"""Named body keypoints, defined once on the mesh, and their skeleton edges.

A keypoint is a fixed convex combination of mesh vertices: either one ring's vertices (its centre:
inside the limb, where a joint is) or a few neighbouring surface vertices (on the skin: eyes, nose,
withers). Posing a keypoint is then the same combination of the posed vertices, so it stays on or in
the posed, skinned mesh in every frame by construction rather than by luck.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.zebra.mesh import ZebraMesh

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class KeypointDef:
    """``part``, ring position along it (0 = start, 1 = end) and where on the ring.

    ``angle`` None means the ring's centre; otherwise the surface vertex nearest that direction
    (radians around the ring, 0 along the ring's ``a`` axis), averaged with its two neighbours.
    """

    name: str
    part: str
    along: float
    angle: float | None = None


# Angles on rings: angle 0 is the ring's a axis (up on barrel and head, the throat side on the neck),
# +pi/2 its b axis, which points to the animal's right (-y) on the barrel and head.
KEYPOINTS: tuple[KeypointDef, ...] = (
    KeypointDef("nose", "head", 1.0, None),
    KeypointDef("left_eye", "head", 0.30, -np.pi / 2 + 0.5),
    KeypointDef("right_eye", "head", 0.30, np.pi / 2 - 0.5),
    KeypointDef("left_ear_tip", "ear_l", 0.92, None),
    KeypointDef("right_ear_tip", "ear_r", 0.92, None),
    KeypointDef("throat", "neck", 0.80, 0.0),
    KeypointDef("withers", "barrel", 0.80, 0.0),
    KeypointDef("mid_back", "barrel", 0.50, 0.0),
    KeypointDef("tail_base", "tail", 0.12, None),
    KeypointDef("tail_tip", "tail", 1.0, None),
    KeypointDef("left_shoulder", "leg_fl", 0.10, None),
    KeypointDef("right_shoulder", "leg_fr", 0.10, None),
    KeypointDef("left_front_elbow", "leg_fl", 0.30, None),
    KeypointDef("right_front_elbow", "leg_fr", 0.30, None),
    KeypointDef("left_front_knee", "leg_fl", 0.55, None),
    KeypointDef("right_front_knee", "leg_fr", 0.55, None),
    KeypointDef("left_front_hoof", "leg_fl", 0.97, None),
    KeypointDef("right_front_hoof", "leg_fr", 0.97, None),
    KeypointDef("left_hip", "leg_hl", 0.12, None),
    KeypointDef("right_hip", "leg_hr", 0.12, None),
    KeypointDef("left_stifle", "leg_hl", 0.30, None),
    KeypointDef("right_stifle", "leg_hr", 0.30, None),
    KeypointDef("left_hock", "leg_hl", 0.52, None),
    KeypointDef("right_hock", "leg_hr", 0.52, None),
    KeypointDef("left_hind_hoof", "leg_hl", 0.97, None),
    KeypointDef("right_hind_hoof", "leg_hr", 0.97, None),
)
KEYPOINT_NAMES: tuple[str, ...] = tuple(k.name for k in KEYPOINTS)
_EDGES_BY_NAME: tuple[tuple[str, str], ...] = (
    ("nose", "left_eye"), ("nose", "right_eye"), ("left_eye", "left_ear_tip"),
    ("right_eye", "right_ear_tip"), ("nose", "throat"), ("throat", "withers"),
    ("withers", "mid_back"), ("mid_back", "tail_base"), ("tail_base", "tail_tip"),
    ("withers", "left_shoulder"), ("withers", "right_shoulder"),
    ("left_shoulder", "left_front_elbow"), ("left_front_elbow", "left_front_knee"),
    ("left_front_knee", "left_front_hoof"),
    ("right_shoulder", "right_front_elbow"), ("right_front_elbow", "right_front_knee"),
    ("right_front_knee", "right_front_hoof"),
    ("tail_base", "left_hip"), ("tail_base", "right_hip"),
    ("left_hip", "left_stifle"), ("left_stifle", "left_hock"), ("left_hock", "left_hind_hoof"),
    ("right_hip", "right_stifle"), ("right_stifle", "right_hock"), ("right_hock", "right_hind_hoof"),
)
# Skeleton edges as pairs of 0-based keypoint indices (COCO's own file is 1-based: add 1 there).
KEYPOINT_EDGES: tuple[tuple[int, int], ...] = tuple(
    (KEYPOINT_NAMES.index(a), KEYPOINT_NAMES.index(b)) for a, b in _EDGES_BY_NAME
)
# Left/right swaps, for horizontal-flip augmentation of keypoints.
KEYPOINT_FLIP: tuple[int, ...] = tuple(
    KEYPOINT_NAMES.index(n.replace("left_", "@").replace("right_", "left_").replace("@", "right_"))
    for n in KEYPOINT_NAMES
)


def keypoint_weights(mesh: ZebraMesh) -> tuple[NDArray[np.int64], FloatArray]:
    """Vertex indices (K, n) and weights (K, n) defining each keypoint on ``mesh``.

    ``n`` is the widest ring; unused slots have weight 0.
    """
    rows: list[tuple[list[int], list[float]]] = []
    for kp in KEYPOINTS:
        g = mesh.part(kp.part).grid
        r = int(round(kp.along * (g.shape[0] - 1)))
        ring = g[r]
        if kp.angle is None:
            rows.append((list(ring), [1.0 / len(ring)] * len(ring)))
        else:
            n = len(ring)
            k = int(round(kp.angle / (2 * np.pi) * n)) % n
            rows.append(([int(ring[(k - 1) % n]), int(ring[k]), int(ring[(k + 1) % n])], [0.25, 0.5, 0.25]))
    width = max(len(i) for i, _ in rows)
    idx = np.zeros((len(rows), width), dtype=np.int64)
    w = np.zeros((len(rows), width))
    for i, (ii, ww) in enumerate(rows):
        idx[i, : len(ii)] = ii
        w[i, : len(ww)] = ww
    return idx, w


def pose_keypoints(vertices: FloatArray, idx: NDArray[np.int64], w: FloatArray) -> FloatArray:
    """Keypoints (..., K, 3) from posed vertices (..., V, 3)."""
    return np.asarray(np.einsum("...kni,kn->...ki", vertices[..., idx, :], w))
