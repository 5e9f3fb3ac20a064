"""Levels of detail of the zebra mesh: which one a camera draws at which distance.

One rule for the renderer, the silhouette counter and the labeller, so a zebra's amodal box is always that of the
mesh the camera drew: full detail (level 0) nearer than ``detail_distance_m`` from the camera, the low-detail
mesh (level 1) from there on.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

DETAIL_DISTANCE_M = 35.0  # default distance from the camera beyond which the low-detail mesh is drawn, m


def lod_of(distance_m: ArrayLike, detail_distance_m: float = DETAIL_DISTANCE_M) -> NDArray[np.int64]:
    """The level of detail (0 full, 1 low) drawn at each distance from the camera, m."""
    return np.where(np.asarray(distance_m) < detail_distance_m, 0, 1).astype(np.int64)
