"""The scorer node over real DDS: labels and typed detections in, live figures out on /diagnostics."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from ros_helpers import (
    Peer,
    collect_diagnostics,
    detection_array_class,
    fresh_domain_id,
    node_process,
    run_node_once,
    spin_until,
)
from std_msgs.msg import Header, String

from zebra_sim_ros.detection.scoring import DroneFrames, LiveScores, score_drones
from zebra_sim_ros.messages import Detection, Detections, Labels, Stamp
from zebra_sim_ros.nodes.ros_adapter import detection_array_msg, detection_array_type, stamp

pytestmark = pytest.mark.integration


def _labels(sec: int, boxes: list[list[float]]) -> str:
    """A labels message with only what scoring reads: kept zebras' visible boxes."""
    return json.dumps({"schema": "zebra_sim_ros/labels", "version": 1, "stamp": {"sec": sec, "nanosec": 0},
                       "zebras": [{"id": i, "box_visible": b, "kept": True, "visible_pixels": 900}
                                  for i, b in enumerate(boxes)]})


def _detections(sec: int, rows: list[list[float]]) -> object:
    dets = Detections(Stamp(sec, 0), "cam", 0, 0, tuple(Detection(tuple(r[:4]), r[4]) for r in rows))  # type: ignore
    return detection_array_msg(detection_array_type(), Header(stamp=stamp(sec * 10**9), frame_id="cam"), dets)


def test_live_scores_keep_a_window_of_each_cameras_latest_frames() -> None:
    live = LiveScores(window=2)
    for sec in range(3):
        live.add_labels("a", Labels.from_json(_labels(sec, [[10.0, 10, 50, 40]])))
        hit = [10.0, 10, 50, 40, 0.9] if sec else [200.0, 200, 240, 230, 0.9]  # frame 0: a miss and a false box
        live.add_detections("a", sec * 10**9, np.array([hit]))
    s = live.scores()
    assert s["a"]["frames"] == 2 and s["a"]["mAP50"] == pytest.approx(1.0)  # frame 0 fell out of the window
    assert live.scores() is s  # nothing new: not computed again
    live.resize(0)
    live.add_labels("a", Labels.from_json(_labels(3, [[10.0, 10, 50, 40]])))
    assert live.scores()["a"]["unmatched_labels"] == 1  # labels without detections yet: counted, not scored
    live.add_detections("a", 3 * 10**9, np.array([[300.0, 300, 340, 330, 0.95]]))  # a false box, a miss
    assert live.scores()["a"]["frames"] == 3 and live.scores()["a"]["recall"] == pytest.approx(2 / 3, abs=1e-4)
    live.resize(1)
    assert live.scores()["a"]["frames"] == 1 and live.scores()["a"]["recall"] == pytest.approx(0.0, abs=1e-4)
    with pytest.raises(ValueError, match="window -1"):
        LiveScores(-1)


def test_a_stamp_older_than_the_last_on_its_topic_starts_a_new_run_for_that_camera() -> None:
    """A restarted graph's simulated time starts again at 0: the camera's frames of the run before are dropped, so a
    new run's labels are never paired with the old run's detections of the same stamp."""
    live = LiveScores(window=0)
    for sec in range(3):  # run 1: every zebra found, on both cameras
        for drone in ("a", "b"):
            live.add_labels(drone, Labels.from_json(_labels(sec, [[10.0, 10, 50, 40]])))
            live.add_detections(drone, sec * 10**9, np.array([[10.0, 10, 50, 40, 0.9]]))
    live.add_labels("a", Labels.from_json(_labels(2, [[10.0, 10, 50, 40]])))  # a re-sent step: not a new run
    assert live.restarts == 0 and live.scores()["a"]["frames"] == 3
    # run 2 on camera a: labels of stamps 0 and 1, detections (late) of stamp 1 only, elsewhere
    live.add_labels("a", Labels.from_json(_labels(0, [[300.0, 300, 340, 330]])))
    live.add_labels("a", Labels.from_json(_labels(1, [[300.0, 300, 340, 330]])))
    live.add_detections("a", 1 * 10**9, np.array([[300.0, 300, 340, 330, 0.9]]))
    s = live.scores()
    assert live.restarts == 1 and s["a"]["frames"] == 1 and s["a"]["mAP50"] == pytest.approx(1.0)
    assert s["a"]["unmatched_labels"] == 1 and s["b"]["frames"] == 3  # camera b's run goes on


def test_a_lagging_topics_last_frames_of_the_old_run_are_dropped_not_paired_with_the_new() -> None:
    """A looping replay into a detector two frames behind: the new run's labels start again while the old run's last
    detections still come. They are dropped as leftovers (not a second restart that would lose the new labels), and
    the new run's detections, stepping back to 0, are scored against the new labels."""
    live = LiveScores(window=0)
    hit = np.array([[10.0, 10, 50, 40, 0.9]])
    for sec in range(5):  # run 1
        live.add_labels("a", Labels.from_json(_labels(sec, [[10.0, 10, 50, 40]])))
        if sec >= 2:
            live.add_detections("a", (sec - 2) * 10**9, hit)
    for sec in range(3):  # run 2's labels (a box elsewhere) while run 1's detections of stamps 3 and 4 come
        live.add_labels("a", Labels.from_json(_labels(sec, [[300.0, 300, 340, 330]])))
        if sec < 2:
            live.add_detections("a", (sec + 3) * 10**9, hit)
    for sec in range(3):
        live.add_detections("a", sec * 10**9, np.array([[300.0, 300, 340, 330, 0.9]]))
    s = live.scores()
    assert (live.restarts, live.leftovers) == (1, 2)
    assert s["a"]["frames"] == 3 and s["a"]["mAP50"] == pytest.approx(1.0)


def test_live_scores_match_each_frame_once_and_score_as_a_bag_is_scored() -> None:
    """Frames matched as they come, kept while in the window, give what score_drones gives the same frames at once
    (the scores of bag eval and up), to the digit."""
    rng = np.random.default_rng(5)
    live = LiveScores(window=4)
    for sec in range(7):
        for drone in ("a", "b"):
            xy = rng.uniform(0, 600, (12, 2))
            boxes = np.c_[xy, xy + rng.uniform(8, 40, (12, 2))]
            live.add_labels(drone, Labels.from_json(_labels(sec, boxes.tolist())))
            dets = np.c_[boxes + rng.normal(0, 3, boxes.shape), rng.uniform(0.1, 1, 12)][rng.random(12) < 0.8]
            live.add_detections(drone, sec * 10**9, dets)
            if sec % 2:
                live.scores()  # scored while frames come: the cache grows and drops frames as the window moves
    frames = {d: DroneFrames(dict(f.labels), dict(f.detections)) for d, f in live.drones.items()}
    fresh = score_drones(frames)
    assert live.scores() == fresh and fresh["all"]["images"] == 8
    live.recount(0.6)  # a new count threshold: the same matches, counted again
    assert live.scores() == score_drones(frames, count_conf=0.6)
    assert live.scores()["all"]["count"]["counted"] < fresh["all"]["count"]["counted"]
    # matched: exactly the window's frames (the older ones dropped as it moved)
    assert {d: sorted(m) for d, m in live.matched.items()} == {d: [s * 10**9 for s in range(3, 7)] for d in "ab"}


def test_the_scorer_reports_live_figures_per_camera_and_warns_on_a_bad_message(tmp_path: Path) -> None:
    domain = fresh_domain_id()
    peer = Peer(domain, "test_scorer")
    node, ex = peer.node, peer.ex
    status = collect_diagnostics(node, "scorer: scorer")
    pubs = {(d, k): node.create_publisher(String if k == "labels" else detection_array_class(), f"/{d}/{k}", 10)
            for d in ("drone_0", "drone_1") for k in ("labels", "detections")}
    log = tmp_path / "scorer.log"
    try:
        with node_process("scorer", {"drones": ["drone_0", "drone_1"], "diagnostics_period_s": 0.2,
                                     "count_conf": 0.92}, domain, log):
            assert spin_until(node, ex, lambda: all(node.count_subscribers(f"/{d}/{k}") for d, k in pubs), 60), \
                log.read_text()
            box = [10.0, 10, 50, 40]

            def complete() -> bool:
                return bool(status) and status[-1]["values"].get("drone_1 frames") == "3" and \
                    status[-1]["values"].get("drone_0 frames") == "3"
            # Our side may see the node's subscriptions before the node has matched our publishers, and what is sent
            # before that is lost: send the three frames again until all are scored (a frame sent again is the same
            # frame to the scorer).
            for _ in range(20):
                for sec in range(3):
                    for d in ("drone_0", "drone_1"):
                        pubs[(d, "labels")].publish(String(data=_labels(sec, [box, [100.0, 100, 140, 130]])))
                    # drone_0 finds both zebras; drone_1 one of them, and a box on nothing
                    pubs[("drone_0", "detections")].publish(
                        _detections(sec, [[*box, 0.9], [100.0, 100, 140, 130, 0.8]]))
                    pubs[("drone_1", "detections")].publish(
                        _detections(sec, [[*box, 0.9], [300.0, 300, 340, 330, 0.95]]))
                if spin_until(node, ex, complete, 1.0):
                    break
            assert complete(), (status[-2:], log.read_text())
            last = status[-1]
            for _ in range(20):
                pubs[("drone_0", "labels")].publish(String(data="{not json"))
                if spin_until(node, ex, lambda: any(s["level"] == 1 for s in status), 1.0):
                    break
            assert any(s["level"] == 1 for s in status), status[-2:]
    finally:
        peer.close()
    v = last["values"]
    assert float(v["drone_0 mAP50"]) == pytest.approx(1.0) and float(v["drone_0 recall"]) == pytest.approx(1.0)
    assert float(v["drone_1 recall"]) == pytest.approx(0.5) and float(v["drone_1 precision"]) == pytest.approx(0.5)
    assert 0.5 < float(v["all mAP50"]) < 1.0 and v["frames scored"] == "6"
    # counted at 0.92: none of drone_0's boxes (0.9, 0.8), drone_1's box on nothing (0.95) of its two a frame
    assert (v["drone_0 count"], v["drone_1 count"], v["all count"]) == ("0/6", "3/6", "3/12")
    assert float(v["all count MAE"]) == pytest.approx(1.5)
    assert last["level"] == 0 and last["message"].endswith(
        "over 6 frames (12 zebras); counted 3 at conf 0.92, mean absolute error 1.50 a frame"), last
    warn = next(s for s in status if s["level"] == 1)
    assert "bad_messages" in warn["message"] and "drone_0/labels skipped" in log.read_text()


def test_a_bad_scorer_parameter_stops_the_node() -> None:
    from zebra_sim_ros.detection.config import ScorerConfig
    from zebra_sim_ros.errors import ParameterError

    for bad, name in (({"detections": "/absolute"}, "'detections'"), ({"detections": "a//b"}, "'detections'"),
                      ({"drones": ["drone_0", "drone_0"]}, "'drones'"),
                      ({"drones": ["drone_0", "/drone_0"]}, "'drones'"), ({"window": 0}, "'window'")):
        with pytest.raises(ParameterError, match=name):
            ScorerConfig.from_params(bad)
    proc = run_node_once("scorer", {"detections": "a//b"})  # the node stops at start, naming it
    assert proc.returncode == 2 and "'detections'" in proc.stderr + proc.stdout, proc.stderr[-500:]
