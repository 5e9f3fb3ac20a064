"""Scores of a run's frames: detections against the labels of the same frames, per camera and over all.

Pure: it takes typed labels (:class:`~zebra_sim_ros.messages.Labels`) and detection arrays keyed by stamp, from a
bag (``bag eval``, ``up``'s summary) or anywhere else. Only kept zebras are ground truth, as in the datasets;
zebras the labeller saw but dropped are don't-care regions (a detection on one is neither right nor wrong), as in
``zebra-sim val``.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.detection.config import DetectorConfig
from zebra_sim_ros.detection.metrics import MatchedImage, count_errors, match_images, metrics_of
from zebra_sim_ros.messages import Labels

COUNT_CONF = DetectorConfig().conf  # counted as the detector publishes: at its threshold


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


def score_drones(drones: dict[str, DroneFrames], cache: dict[str, dict[int, MatchedImage]] | None = None,
                 count_conf: float = COUNT_CONF) -> dict[str, Any]:
    """mAP50 and mAP50-95 per camera and over all (``"all"``, None without labelled frames), on the frames that
    have both labels and detections, and how well the detections at ``count_conf`` or above count the zebras
    (``count``: :func:`~zebra_sim_ros.detection.metrics.count_errors`); unmatched frames are counted. ``cache``:
    each camera's frames matched so far, by stamp; a frame found there is not matched again, the others are added
    (the caller drops a frame whose labels or detections change)."""
    result: dict[str, Any] = {}
    everything: list[MatchedImage] = []
    for drone, d in sorted(drones.items()):
        stamps = sorted(set(d.labels) & set(d.detections))
        known = cache.setdefault(drone, {}) if cache is not None else {}
        matched = []
        for s in stamps:
            if s not in known:
                gt, ignore = d.truth(s)
                known[s] = match_images([d.detections[s]], [gt], ignores=[ignore])[0]
            matched.append(known[s])
        everything += matched
        result[drone] = {"frames": len(stamps), "unmatched_labels": len(set(d.labels) - set(stamps)),
                         "unmatched_detections": len(set(d.detections) - set(stamps)), **metrics_of(matched).to_dict(),
                         "count": count_errors(matched, count_conf)}
    result["all"] = ({**metrics_of(everything).to_dict(), "count": count_errors(everything, count_conf)}
                     if everything else None)
    return result


class LiveScores:
    """Scores of a running graph (the ``scorer`` node): labels and detections as they arrive, per camera, matched by
    stamp, over the last ``window`` stamps of each camera to arrive (0: every stamp since the start). Detections of
    a stamp whose labels never come (or the other way round) are counted, not scored.

    A camera's labels, and its detections, come in the order of their stamps within a run. A stamp older than the
    last one on the same topic starts a new run (a restarted placer or ``up``, a looping replay: simulated time
    starts again at 0): that camera's frames so far are dropped (counted in ``restarts``), so no frame of one run is
    paired with a frame of another. The other topic of that camera may still bring the old run's last frames (a
    detector behind the labeller): until its stamps step back too, they are dropped as leftovers (counted in
    ``leftovers``). A stamp sent again (a re-sent step) is not older: it replaces its frame's part.
    """

    def __init__(self, window: int = 0, count_conf: float = COUNT_CONF) -> None:
        self.window = 0
        self.count_conf = count_conf  # zebras counted with the detections at this score or above
        self.drones: dict[str, DroneFrames] = {}
        self.order: dict[str, deque[int]] = {}  # per camera, its stamps in order of first arrival
        self.matched: dict[str, dict[int, MatchedImage]] = {}  # per camera, its frames matched so far
        self.latest: dict[tuple[str, str], int] = {}  # (camera, "labels" or "detections"): the last stamp
        self.awaiting: set[tuple[str, str]] = set()  # (camera, topic) whose new run has not begun: old leftovers
        self.restarts = 0
        self.leftovers = 0
        self.last: dict[str, Any] | None = None  # the scores, until a frame or the window changes
        self.resize(window)

    def resize(self, window: int) -> None:
        """Score the last ``window`` frames of each camera from now on (0: every frame kept so far and to come)."""
        if window < 0:
            raise ValueError(f"window {window}: 0 (every frame) or a number of frames")
        self.window, self.last = window, None
        for drone in self.order:
            self._trim(drone)

    def recount(self, count_conf: float) -> None:
        """Count the zebras with the detections at ``count_conf`` or above from now on."""
        self.count_conf, self.last = count_conf, None

    def _trim(self, drone: str) -> None:
        order = self.order[drone]
        while self.window and len(order) > self.window:
            old = order.popleft()
            self.drones[drone].labels.pop(old, None)
            self.drones[drone].detections.pop(old, None)
            self.matched[drone].pop(old, None)

    def _frames(self, drone: str, kind: str, stamp: int) -> DroneFrames | None:
        """The camera's frames to put this part in; None for a leftover of a run that has ended (dropped)."""
        key = (drone, kind)
        last = self.latest.get(key, stamp)
        if key in self.awaiting:
            if stamp >= last:  # the old run goes on on this topic: a leftover
                self.latest[key] = stamp
                self.leftovers += 1
                return None
            self.awaiting.discard(key)  # this topic's new run begins: the camera has been reset already
        elif stamp < last:  # a new run on this camera
            self.restarts += 1
            for d in (self.drones, self.order, self.matched):
                d.pop(drone, None)
            self.awaiting |= {k for k in self.latest if k[0] == drone and k != key}
        self.latest[key] = stamp
        frames = self.drones.setdefault(drone, DroneFrames())
        order = self.order.setdefault(drone, deque())
        self.matched.setdefault(drone, {}).pop(stamp, None)  # its labels or detections change: matched again
        self.last = None
        if stamp not in frames.labels and stamp not in frames.detections:
            order.append(stamp)
            self._trim(drone)
        return frames

    def add_labels(self, drone: str, labels: Labels) -> None:
        """A camera's labels (their stamp is the image's)."""
        frames = self._frames(drone, "labels", labels.stamp.ns)
        if frames is not None:
            frames.labels[labels.stamp.ns] = labels

    def add_detections(self, drone: str, stamp: int, rows: NDArray[np.float64]) -> None:
        """A camera's zebra detections of the image of ``stamp`` (ns): rows ``[x0, y0, x1, y1, score]``."""
        frames = self._frames(drone, "detections", stamp)
        if frames is not None:
            frames.detections[stamp] = np.asarray(rows, np.float64).reshape(-1, 5)

    def scores(self) -> dict[str, Any]:
        """:func:`score_drones` over the window; each frame is matched once, the first time it is scored, and the
        scores are computed again only after a frame arrived (the same dict until then: read it, do not change
        it)."""
        if self.last is None:
            self.last = score_drones(self.drones, self.matched, self.count_conf)
        return self.last
