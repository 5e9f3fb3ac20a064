"""A contact sheet of the zebra in several clips and frames, from the side and from above.

Plain orthographic projection with a painter's algorithm (OpenCV polygons), flat Lambert shading and
the baked coat: enough to judge proportions, poses and stripes without a GPU renderer.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.zebra.asset import ZebraLibrary

FloatArray = NDArray[np.float64]
_LIGHT = np.array([0.35, 0.5, 0.8]) / np.linalg.norm([0.35, 0.5, 0.8])


def render_orthographic(vertices: FloatArray, faces: NDArray[np.int64], uv: NDArray[np.float32],
                        texture: NDArray[np.uint8], view: str, size: tuple[int, int],
                        extent: tuple[float, float, float, float], supersample: int = 2) -> NDArray[np.uint8]:
    """Render one posed mesh orthographically into an RGB image (h, w, 3).

    ``view`` is ``side`` (from the zebra's left, +y, looking at -y) or ``top`` (from above);
    ``extent`` is (x_min, x_max, v_min, v_max) of the world window, metres, where v is z for the
    side view and y for the top view.
    """
    w, h = size[0] * supersample, size[1] * supersample
    img = np.full((h, w, 3), 245, dtype=np.uint8)
    tri = vertices[faces]  # (F, 3, 3)
    if view == "side":
        u2, v2, depth = tri[..., 0], tri[..., 2], tri[..., 1]
    elif view == "top":
        u2, v2, depth = tri[..., 0], tri[..., 1], tri[..., 2]
    else:
        raise ValueError(f"view must be 'side' or 'top', got {view!r}")
    x0, x1, y0, y1 = extent
    px = (u2 - x0) / (x1 - x0) * w
    py = (1 - (v2 - y0) / (y1 - y0)) * h
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    toward = np.array([0.0, 1.0, 0.0]) if view == "side" else np.array([0.0, 0.0, 1.0])
    visible = n @ toward > 0  # back faces of closed parts are hidden anyway
    shade = 0.35 + 0.65 * np.clip(n @ _LIGHT, 0, 1)
    # Painter's algorithm into a triangle-id buffer, then per-pixel barycentric UVs: textures stay
    # sharp, where one colour per triangle would turn the stripes into a mosaic.
    ids = np.zeros((h, w, 3), dtype=np.uint8)
    order = np.argsort(depth.mean(axis=1))  # far to near: side view looks from +y, top from +z
    pts = np.stack([px, py], axis=-1)
    ipts = pts.round().astype(np.int32)
    for i in order:
        if visible[i]:
            code = int(i) + 1
            cv2.fillConvexPoly(ids, ipts[i], (code & 255, (code >> 8) & 255, (code >> 16) & 255))
    tid = ids[..., 0].astype(np.int64) | (ids[..., 1].astype(np.int64) << 8) | (ids[..., 2].astype(np.int64) << 16)
    ys, xs = np.nonzero(tid)
    f = tid[ys, xs] - 1
    a, b, c = pts[f, 0], pts[f, 1], pts[f, 2]
    q = np.stack([xs + 0.5, ys + 0.5], axis=-1)
    v0, v1, v2 = b - a, c - a, q - a
    den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
    den = np.where(np.abs(den) < 1e-9, 1e-9, den)
    wb = np.clip((v2[:, 0] * v1[:, 1] - v1[:, 0] * v2[:, 1]) / den, 0, 1)
    wc = np.clip((v0[:, 0] * v2[:, 1] - v2[:, 0] * v0[:, 1]) / den, 0, 1 - wb)
    wa = 1 - wb - wc
    tuv = uv[f, 0] * wa[:, None] + uv[f, 1] * wb[:, None] + uv[f, 2] * wc[:, None]
    th, tw = texture.shape[:2]
    tex = texture[np.clip(((1 - tuv[:, 1]) * th).astype(int), 0, th - 1),
                  np.clip((tuv[:, 0] * tw).astype(int), 0, tw - 1)].astype(np.float64)
    img[ys, xs] = np.clip(tex * shade[f, None], 0, 255).astype(np.uint8)
    if supersample > 1:
        return np.asarray(cv2.resize(img, size, interpolation=cv2.INTER_AREA), dtype=np.uint8)
    return img


def contact_sheet(lib: ZebraLibrary, texture: NDArray[np.uint8], morph: int = 0,
                  clips: Sequence[str] | None = None, frames_per_clip: int = 4,
                  cell: int = 220) -> NDArray[np.uint8]:
    """RGB sheet: one row per clip; per frame a side view above a top view."""
    clips = list(clips or lib.clip_names)
    faces, uv = lib.faces(0), lib.uv(0)
    boxes = lib.boxes()[morph]
    lo, hi = boxes[:, 0].min(axis=0), boxes[:, 1].max(axis=0)
    span = float(max(hi[0] - lo[0], hi[2] - lo[2], hi[1] - lo[1])) * 1.05
    cx, cy = float(lo[0] + hi[0]) / 2, 0.0
    label_w = 120
    rows = []
    for name in clips:
        c = lib.clip_names.index(name)
        n = int(lib.clip_frames[c])
        picks = np.linspace(0, n - 1, frames_per_clip).round().astype(int)
        cells = []
        for f in picks:
            v = lib.vertices(morph, lib.frame_index(name, int(f))).astype(np.float64)
            side = render_orthographic(v, faces, uv, texture, "side", (cell, cell),
                                       (cx - span / 2, cx + span / 2, -0.05, span - 0.05))
            top = render_orthographic(v, faces, uv, texture, "top", (cell, cell // 2),
                                      (cx - span / 2, cx + span / 2, cy - span / 4, cy + span / 4))
            block = np.concatenate([side, top], axis=0)
            cv2.putText(block, f"frame {f}", (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (90, 90, 90), 1, cv2.LINE_AA)
            cv2.rectangle(block, (0, 0), (block.shape[1] - 1, block.shape[0] - 1), (200, 200, 200), 1)
            cells.append(block)
        label = np.full((cells[0].shape[0], label_w, 3), 255, dtype=np.uint8)
        cv2.putText(label, name, (8, cells[0].shape[0] // 2), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (20, 20, 20), 1,
                    cv2.LINE_AA)
        rows.append(np.concatenate([label] + cells, axis=1))
    return np.concatenate(rows, axis=0)


def individuals_strip(lib: ZebraLibrary, first_seed: int, width: int, cell: int) -> NDArray[np.uint8]:
    """One row of individuals standing idle, side view: each morph with two coats, to scale."""
    from zebra_sim_ros.zebra.coat import bake_coat, random_coat
    from zebra_sim_ros.zebra.skeleton import MORPHS

    faces, uv = lib.faces(0), lib.uv(0)
    span = float(lib.boxes()[:, :, 1, [0, 2]].max() - min(0.0, float(lib.boxes()[:, :, 0, 0].min()))) * 1.1
    frame = lib.frame_index("idle", 0)
    tiles = []
    cell = min(cell, width // (2 * len(lib.morphs)))
    for m, name in enumerate(lib.morphs):
        for k in range(2):
            seed = first_seed + 2 * m + k
            tex = bake_coat(MORPHS[name], random_coat(seed, MORPHS[name]), 256)
            v = lib.vertices(m, frame).astype(np.float64)
            tile = render_orthographic(v, faces, uv, tex, "side", (cell, cell),
                                       (-span / 2 + 0.2, span / 2 + 0.2, -0.05, span - 0.05))
            cv2.putText(tile, f"{name} seed {seed}", (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (60, 60, 60), 1,
                        cv2.LINE_AA)
            tiles.append(tile)
    row = np.concatenate(tiles, axis=1)
    out = np.full((cell, width, 3), 255, dtype=np.uint8)
    w = min(width, row.shape[1])
    out[:, :w] = row[:, :w]
    return out
