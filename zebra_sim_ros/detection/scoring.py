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


class LiveScores:
    """Scores of a running graph (the ``scorer`` node): labels and detections as they arrive, per camera, matched by
    stamp, over the last ``window`` stamps of each camera to arrive (0: every stamp since the start). Detections of
    a stamp whose labels never come (or the other way round) are counted, not scored."""

    def __init__(self, window: int = 0) -> None:
        if window < 0:
            raise ValueError(f"window {window}: 0 (every frame) or a number of frames")
        self.window = window
        self.drones: dict[str, DroneFrames] = {}
        self.order: dict[str, list[int]] = {}  # per camera, its stamps in order of first arrival

    def _frames(self, drone: str, stamp: int) -> DroneFrames:
        frames = self.drones.setdefault(drone, DroneFrames())
        order = self.order.setdefault(drone, [])
        if stamp not in frames.labels and stamp not in frames.detections:
            order.append(stamp)
            while self.window and len(order) > self.window:
                old = order.pop(0)
                frames.labels.pop(old, None)
                frames.detections.pop(old, None)
        return frames

    def add_labels(self, drone: str, labels: Labels) -> None:
        """A camera's labels (their stamp is the image's)."""
        self._frames(drone, labels.stamp.ns).labels[labels.stamp.ns] = labels

    def add_detections(self, drone: str, stamp: int, rows: NDArray[np.float64]) -> None:
        """A camera's zebra detections of the image of ``stamp`` (ns): rows ``[x0, y0, x1, y1, score]``."""
        self._frames(drone, stamp).detections[stamp] = np.asarray(rows, np.float64).reshape(-1, 5)

    def scores(self) -> dict[str, Any]:
        """:func:`score_drones` over the window."""
        return score_drones(self.drones)
