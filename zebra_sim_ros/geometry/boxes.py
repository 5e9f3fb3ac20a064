"""Oriented boxes in the plane: overlap tests for footprints (separating axis theorem).

A 2D oriented box is (centre (2,), half extents (2,), heading angle in radians); its first axis points
along the heading. All functions broadcast: the usual use tests K candidates against M placed boxes.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def box_axes(heading: FloatArray) -> FloatArray:
    """Unit axes (..., 2, 2) of boxes: [..., 0, :] along the heading, [..., 1, :] to its left."""
    c, s = np.cos(heading), np.sin(heading)
    return np.stack([np.stack([c, s], -1), np.stack([-s, c], -1)], -2)


def obb_overlap(c1: FloatArray, e1: FloatArray, a1: FloatArray, c2: FloatArray, e2: FloatArray,
                a2: FloatArray) -> NDArray[np.bool_]:
    """Whether oriented boxes overlap (touching counts as apart).

    ``c``: centres (..., 2); ``e``: half extents (..., 2); ``a``: axes (..., 2, 2) from :func:`box_axes`.
    Shapes broadcast, e.g. candidates (K, 1, ...) against placed (1, M, ...) give (K, M).
    """
    d = c2 - c1
    overlap = np.ones(np.broadcast_shapes(d.shape[:-1], e1.shape[:-1], e2.shape[:-1]), dtype=bool)
    for axes in (a1, a2):
        for k in range(2):
            ax = axes[..., k, :]
            r1 = (e1[..., 0] * np.abs(np.sum(a1[..., 0, :] * ax, -1))
                  + e1[..., 1] * np.abs(np.sum(a1[..., 1, :] * ax, -1)))
            r2 = (e2[..., 0] * np.abs(np.sum(a2[..., 0, :] * ax, -1))
                  + e2[..., 1] * np.abs(np.sum(a2[..., 1, :] * ax, -1)))
            overlap &= np.abs(np.sum(d * ax, -1)) < r1 + r2
    return overlap


def obb_corners(c: FloatArray, e: FloatArray, a: FloatArray) -> FloatArray:
    """Corners (..., 4, 2) of oriented boxes, counter-clockwise."""
    signs = np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]], dtype=np.float64)  # (4, 2)
    offsets = signs[:, :, None] * (e[..., None, :, None] * a[..., None, :, :])  # (..., 4, 2 axes, 2 xy)
    return np.asarray(c[..., None, :] + offsets.sum(axis=-2))
