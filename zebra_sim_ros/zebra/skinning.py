"""Linear-blend skinning.

``posed = sum_k w_k * (G_jk @ B_jk^-1) @ v``, with ``G`` the posed joint-to-asset transforms and ``B``
the bind ones. All bind orientations are identity here, so ``B^-1`` is a translation by ``-bind``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def skinning_matrices(global_xf: FloatArray, bind: FloatArray) -> FloatArray:
    """(..., J, 3, 4) matrices taking bind-pose points to posed points for each joint."""
    r = global_xf[..., :3, :3]
    t = global_xf[..., :3, 3] - np.einsum("...ij,...j->...i", r, np.broadcast_to(bind, r.shape[:-1]))
    return np.concatenate([r, t[..., None]], axis=-1)


def skin(vertices: FloatArray, joint_indices: NDArray[np.int64], joint_weights: FloatArray,
         matrices: FloatArray) -> FloatArray:
    """Posed vertices (..., V, 3) from bind vertices (V, 3) and skinning matrices (..., J, 3, 4).

    ``joint_indices`` and ``joint_weights`` are (V, 4); the weights of a vertex sum to 1.
    """
    m = matrices[..., joint_indices, :, :]  # (..., V, 4, 3, 4)
    blended = np.einsum("vk,...vkij->...vij", joint_weights, m)  # (..., V, 3, 4)
    return np.asarray(np.einsum("...vij,vj->...vi", blended[..., :3], vertices) + blended[..., 3])
