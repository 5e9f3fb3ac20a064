"""Scores of a run's frames: detections against the labels of the same frames, per camera and over all.

Pure: it takes typed labels (:class:`~zebra_sim_ros.messages.Labels`) and detection arrays keyed by stamp, from a
bag (``bag eval``, ``up``'s summary) or anywhere else. Only kept zebras are ground truth, as in the datasets;
zebras the labeller saw but dropped are don't-care regions (a detection on one is neither right nor wrong), as in
``zebra-sim val``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.detection.metrics import evaluate_detections
from zebra_sim_ros.messages import Labels


@dataclass
class DroneFrames:
    """One camera's frames: labels and detections (rows ``[x0, y0, x1, y1, score]``, pixels) by stamp (ns)."""

    labels: dict[int, Labels] = field(default_factory=dict)
    detections: dict[int, NDArray[np.float64]] = field(default_factory=dict)

    def truth(self, stamp: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The kept zebras' visible boxes (n, 4) and the don't-care boxes (k, 4) of a stamp's labels."""
        labels = self.labels.get(stamp)
        if labels is None:
            return np.zeros((0, 4)), np.zeros((0, 4))
        return (np.array([z.box_visible for z in labels.kept], np.float64).reshape(-1, 4),
                np.array([z.box_visible for z in labels.dont_care], np.float64).reshape(-1, 4))


def score_drones(drones: dict[str, DroneFrames]) -> dict[str, Any]:
    """mAP50 and mAP50-95 per camera and over all (``"all"``, None without labelled frames), on the frames that
    have both labels and detections; unmatched frames are counted."""
    result: dict[str, Any] = {}
    all_p, all_g, all_i = [], [], []
    for drone, d in sorted(drones.items()):
        stamps = sorted(set(d.labels) & set(d.detections))
        preds = [d.detections[s] for s in stamps]
        truths = [d.truth(s) for s in stamps]
        gts, ignores = [g for g, _ in truths], [i for _, i in truths]
        all_p += preds
        all_g += gts
        all_i += ignores
        m = evaluate_detections(preds, gts, ignores=ignores)
        result[drone] = {"frames": len(stamps), "unmatched_labels": len(set(d.labels) - set(stamps)),
                         "unmatched_detections": len(set(d.detections) - set(stamps)), **m.to_dict()}
    result["all"] = evaluate_detections(all_p, all_g, ignores=all_i).to_dict() if all_g else None
    return result
