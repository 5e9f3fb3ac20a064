"""Generalised winding numbers: is a point inside a closed triangle mesh?

For a closed, outward-wound surface the winding number is 1 inside, 0 outside and 1/2 on the surface;
for a union of overlapping closed parts it adds up (2 where two parts overlap). Robust to the
self-intersections ray parity tests trip over, and needs no spatial index.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def winding_numbers(points: FloatArray, vertices: FloatArray, faces: NDArray[np.int64],
                    chunk: int = 64) -> FloatArray:
    """Winding number of each of ``points`` (P, 3) with respect to the mesh, shape (P,).

    Uses the solid angle of every triangle (Van Oosterom and Strackee, 1983), in chunks of points.
    """
    tri = np.asarray(vertices, dtype=np.float64)[faces]  # (F, 3, 3)
    out = np.empty(len(points))
    for s in range(0, len(points), chunk):
        p = np.asarray(points[s:s + chunk], dtype=np.float64)
        r = tri[None, :, :, :] - p[:, None, None, :]  # (P, F, 3, 3)
        a, b, c = r[..., 0, :], r[..., 1, :], r[..., 2, :]
        la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
        det = np.einsum("pfi,pfi->pf", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("pfi,pfi->pf", a, b) * lc + np.einsum("pfi,pfi->pf", b, c) * la
               + np.einsum("pfi,pfi->pf", c, a) * lb)
        out[s:s + chunk] = np.arctan2(det, den).sum(axis=1) / (2 * np.pi)
    return out
