"""The ``scorer`` node: how well the detector does, live, against the labeller's ground truth
(``ros2 run zebra_sim_ros scorer``).

Subscribes, per camera in ``drones``, ``<drone>/labels`` (the label JSON) and ``<drone>/<detections>``
(Detection2DArray, the detector's type: vision_msgs or zebra_sim_msgs), matches them by the image's stamp and
scores the last ``window`` frames of each camera as ``zebra-sim bag eval`` scores a bag
(:func:`zebra_sim_ros.detection.scoring.score_drones`: COCO mAP50 and mAP50-95, and the precision and recall at the
best-F1 confidence, with the zebras the labeller saw but dropped as don't-care regions; zebra detections only),
and counts the zebras with the detections at ``count_conf`` or above, as an aerial census would (counted against
true, and the mean absolute error of a frame's count: :func:`zebra_sim_ros.detection.metrics.count_errors`; a
detector publishes nothing under its own ``conf``, so a count at a lower ``count_conf`` is a count at that). A
camera's stamp older than the last on its topic starts a new run (a restarted graph): its frames so far are dropped
and counted in ``restarts``.

Every ``diagnostics_period_s`` it publishes the figures on ``/diagnostics`` (status ``scorer: scorer``): over all
cameras in the message and the values (``all mAP50``, ``drone_0 recall``, ``all count``, ...), with the frames
scored. A message that does not parse is logged, counted and skipped (WARN in its period). Change the detector's
``conf`` with ``ros2 param set`` and watch the figures follow; ``window`` and ``count_conf`` may change while it
runs.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from std_msgs.msg import String

from zebra_sim_ros.detection.config import SCORER_PARAMS, ScorerConfig
from zebra_sim_ros.detection.scoring import LiveScores
from zebra_sim_ros.errors import ZebraSimError
from zebra_sim_ros.health import Activity
from zebra_sim_ros.messages import Labels
from zebra_sim_ros.nodes.ros_adapter import (
    ZebraNode,
    describe_qos,
    detection_array_type,
    help_text,
    message_class,
    qos,
    run_node,
)
from zebra_sim_ros.recording.cdr import MALFORMED, cdr_detections


class ScorerNode(ZebraNode[ScorerConfig]):
    """Thin adapter around :class:`zebra_sim_ros.detection.scoring.LiveScores`."""

    def __init__(self) -> None:
        super().__init__("scorer", ScorerConfig)

    def start(self) -> None:
        """Subscribe each camera's labels and detections."""
        c = self.cfg
        self.live = LiveScores(c.window, c.count_conf)
        self.counts = {"labels": 0, "detections": 0, "bad_messages": 0}
        q = qos(c.qos_reliability, c.qos_depth)
        self.det_type = detection_array_type()
        det_class = message_class(self.det_type)
        self.det_topics = []
        for d in c.drones:
            self.create_subscription(String, f"{d}/labels", self._on_labels(d), q)
            # raw: the CDR bytes read by the same reader as bag eval's (cdr_detections); DDS still matches publishers
            # of this type only (activity() says when a topic's publishers offer another)
            sub = self.create_subscription(det_class, f"{d}/{c.detections}", self._on_detections(d), q, raw=True)
            self.det_topics.append((d, sub.topic_name))
        self.figures: dict[str, Any] = {}
        self.get_logger().info(f"scoring {list(c.drones)}: <drone>/labels against <drone>/{c.detections}, window "
                               f"{c.window} frames each; QoS {describe_qos(q)}")

    def on_config(self, cfg: ScorerConfig) -> None:
        """A new window or count threshold applies at once (a smaller window drops the oldest frames)."""
        self.cfg = cfg
        self.live.resize(cfg.window)
        self.live.recount(cfg.count_conf)

    def _on_labels(self, drone: str) -> Any:
        def on_labels(msg: String) -> None:
            try:
                self.live.add_labels(drone, Labels.from_json(msg.data))
            except (ZebraSimError, *MALFORMED) as exc:
                self.skip_bad(self.counts, f"{drone}/labels", exc)
                return
            self.counts["labels"] += 1
        return on_labels

    def _on_detections(self, drone: str) -> Any:
        def on_detections(data: bytes) -> None:
            try:
                dets = cdr_detections(data)
                rows = np.array([[*x.box_xyxy, x.score] for x in dets.detections if x.class_name == "zebra"],
                                np.float64)
                self.live.add_detections(drone, dets.stamp.ns, rows)
            except (ZebraSimError, *MALFORMED) as exc:
                self.skip_bad(self.counts, f"{drone}/{self.cfg.detections}", exc)
                return
            self.counts["detections"] += 1
        return on_detections

    def activity(self) -> Activity:
        """Frames scored in the window; the figures over all cameras in the message, per camera in the values."""
        s = self.live.scores()
        frames = sum(v["frames"] for k, v in s.items() if k != "all")
        info: dict[str, str] = {}
        note = "no frame with both labels and detections yet"
        for key, v in s.items():
            if v is None or (key != "all" and not v["frames"]):
                continue
            for name in ("mAP50", "mAP50-95", "precision", "recall"):
                info[f"{key} {name}"] = f"{v[name]:.4f}"
            count = v["count"]
            info[f"{key} count"] = f"{count['counted']}/{count['true']}"
            info[f"{key} count MAE"] = f"{count['mae']:.4f}"
            if key != "all":
                info[f"{key} frames"] = str(v["frames"])
        a = s.get("all")
        if a is not None and frames:
            note = (f"mAP50 {a['mAP50']:.3f}, mAP50-95 {a['mAP50-95']:.3f}, P {a['precision']:.3f}, "
                    f"R {a['recall']:.3f} over {frames} frames ({a['instances']} zebras); counted "
                    f"{a['count']['counted']} at conf {self.live.count_conf:g}, mean absolute error "
                    f"{a['count']['mae']:.2f} a frame")
        waiting = ""
        # a camera with nothing yet: a topic whose publishers offer another type never matches this subscription
        mine = self.det_type.replace("/msg/", "/")
        other = sorted({(t, i.topic_type) for d, t in self.det_topics
                        if (d, "detections") not in self.live.latest
                        for i in self.get_publishers_info_by_topic(t) if i.topic_type.replace("/msg/", "/") != mine})
        if other:
            waiting = (f"{other[0][0]} is published as {other[0][1]}, which this scorer (reading {self.det_type}) "
                       "cannot subscribe: build both nodes against the same message package")
        counts = {**self.counts, "frames scored": frames, "restarts": self.live.restarts,
                  "leftovers": self.live.leftovers}
        return Activity(counts, "detections", ("bad_messages",), info=info, note=note, waiting=waiting)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ros2 run zebra_sim_ros scorer``; returns the exit status."""
    return run_node("scorer", ScorerNode, argv, help_text("scorer", __doc__ or "", SCORER_PARAMS))


if __name__ == "__main__":
    raise SystemExit(main())
