"""End to end: ``zebra-sim up`` runs the whole graph over real DDS (eight processes), records it and scores the
shipped detector; the bag replayed into a fresh detector scores the same. Also: a node that dies, and Ctrl-C."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
import yaml
from cli_helpers import CliRun
from ros_helpers import Peer, detection_array_class, fresh_domain_id, node_process, ros_env

from zebra_sim_ros.graph.spec import UpConfig, graph_spec

DRONES = ("drone_0", "drone_1", "drone_2")


def _up_command(out: Path, domain: int, *extra: str) -> list[str]:
    return [sys.executable, "-m", "zebra_sim_ros.cli", "up", "--frames", "3", "--size", "320x180", "--out", str(out),
            "--domain-id", str(domain), "--json", *extra]


def _up(out: Path, domain: int, *extra: str, timeout: float = 420) -> subprocess.CompletedProcess[str]:
    return subprocess.run(_up_command(out, domain, *extra), env=ros_env(domain), capture_output=True, text=True,
                          timeout=timeout)


def _processes_in(domain: int) -> list[str]:
    """Command lines of live processes (other than this one) running on ``domain``."""
    found = []
    for p in Path("/proc").iterdir():
        if not p.name.isdigit() or int(p.name) == os.getpid():
            continue
        try:
            env = (p / "environ").read_bytes().split(b"\0")
            if f"ROS_DOMAIN_ID={domain}".encode() in env and (p / "stat").read_text().split()[2] != "Z":
                found.append((p / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace"))
        except OSError:
            continue
    return found


def _last_json(stdout: str) -> dict[str, Any]:
    return dict(json.loads(stdout.strip().splitlines()[-1]))


def test_up_runs_the_graph_and_a_replay_into_a_fresh_detector_scores_the_same(tmp_path: Path, cli: CliRun) -> None:
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus

    domain = fresh_domain_id()
    # A node beside the graph reports on /diagnostics stamped on wall time (as a node without use_sim_time does):
    # the recorder logs its reports on the bag's simulated time all the same (_check_time_base_...).
    peer = Peer(domain, "test_up_wall_clock")
    pub = peer.node.create_publisher(DiagnosticArray, "/diagnostics", 10)

    def report() -> None:
        msg = DiagnosticArray(status=[DiagnosticStatus(name="test: wall clock", message="beside the graph")])
        msg.header.stamp = peer.node.get_clock().now().to_msg()
        pub.publish(msg)
    peer.node.create_timer(0.5, report)
    try:
        with open(tmp_path / "up.out", "w") as out:
            proc = subprocess.Popen(_up_command(tmp_path / "up", domain, "--locate"), env=ros_env(domain), stdout=out,
                                    stderr=subprocess.STDOUT, text=True)
            try:
                assert peer.spin(lambda: proc.poll() is not None, 420), "up did not finish"
            finally:
                proc.kill()
                proc.wait()
    finally:
        peer.close()
    stdout = (tmp_path / "up.out").read_text()
    assert proc.returncode == 0, stdout[-6000:]
    live = _last_json(stdout)
    # the graph's scorer scored every frame live, by the rules up applies to its bag at the end
    scorer = live["live_scores"]
    assert scorer["frames"] == 9 and scorer["complete"], scorer
    for name in ("mAP50", "mAP50-95", "precision", "recall"):
        assert scorer["all"][name] == pytest.approx(live["scores"]["all"][name], abs=2e-4), name
    count = live["scores"]["all"]["count"]  # the same zebras counted live and from the bag
    assert {k: scorer["all"]["count"][k] for k in ("counted", "true")} == {k: count[k] for k in ("counted", "true")}
    assert scorer["all"]["count"]["mae"] == pytest.approx(count["mae"], abs=2e-4)
    assert count["true"] == live["scores"]["all"]["instances"] and "[up] count at conf 0.25: " in stdout
    assert "the scorer node, live over its last 9 frames:" in stdout
    assert live["steps"] == 3
    assert live["frames"] == {d: {"image_raw": 3, "labels": 3, "detections": 3} for d in DRONES}
    assert all(code == 0 for code in live["exit_status"].values()), live["exit_status"]
    assert _processes_in(domain) == []
    assert live["damaged"] == []
    a = live["scores"]["all"]
    assert a["images"] == 9 and a["instances"] > 0
    assert 0.0 <= a["mAP50-95"] <= a["mAP50"] <= 1.0
    assert live["median_ms"]["end_to_end"] > live["median_ms"]["render"] > 0
    preview = cv2.imread(live["preview"])
    assert preview is not None and preview.shape == (180, 960, 3)
    assert "mAP50" in stdout and live["bag"] in stdout
    # --locate: every frame's zebra detections placed on the map, near the zebras the placer put there
    located = live["located"]
    assert located["frames"] == located["frames_with_placed"] == 9, located
    # every published zebra box but those with no depth in their core; the count leaves out boxes on don't-care zebras
    assert located["detections"] >= 0.9 * a["count"]["counted"] > 0, (located, a["count"])
    assert located["median_m"] < 1.0 and located["within_1_m"] > 0.5, located
    assert "[up] locator: " in stdout
    # the census: each step's zebras counted once across the three drones; joining never adds, and the drones overlap
    census = live["census"]
    assert census["steps"] == 3 and census["true"] > 0 and 0 < census["animals"] < census["summed"], census
    assert census["summed"] == located["detections"] and "[up] census: " in stdout
    # counted again from the bag by the locator's rule: the census it recorded, to the animal; without the
    # separation, one camera's two boxes on a zebra count twice; a rule out of range is refused by name
    again = cli(["bag", "census", live["bag"], "--json", "--geojson", str(tmp_path / "recount.geojson")])
    assert again.returncode == 0, again.stderr
    recount = _last_json(again.stdout)
    assert recount["recounted"] == census and recount["recorded"] == census and recount["stamps_counted"] == 3
    assert recount["followed"]["pose"] == "camera/pose" and recount["followed"]["drones"] == list(DRONES)
    # the census on the Earth: up's (the locator's, as published) and the recount's, by the scenes' datum (the
    # placer's defaults), the same animals at the same places
    serengeti = {"latitude_deg": -2.3, "longitude_deg": 34.8, "altitude_m": 1550.0}
    assert recount["datum"] == serengeti and "[up] census on the Earth: " in stdout
    published = json.loads(Path(live["census_geojson"]).read_text())
    recounted = json.loads((tmp_path / "recount.geojson").read_text())
    assert published["zebra_sim"]["datum"] == recounted["zebra_sim"]["datum"] == serengeti
    assert published["zebra_sim"]["per_class"]["zebra"] == len(recounted["features"]) == census["animals"]
    assert published["zebra_sim"]["pose"] == recounted["zebra_sim"]["pose"] == located["pose"] == "camera/pose"

    def places(doc: dict[str, Any]) -> list[tuple[int, str, tuple[float, ...]]]:  # the zebras: the recount's class
        zebras = [f for f in doc["features"] if f["properties"]["class"] == "zebra"]
        return sorted((f["properties"]["stamp_ns"], ",".join(sorted(f["properties"]["detections"].split(","))),
                       tuple(f["geometry"]["coordinates"])) for f in zebras)

    for (t1, d1, at1), (t2, d2, at2) in zip(places(published), places(recounted), strict=True):
        assert (t1, d1) == (t2, d2)  # the same detections joined into the same animal
        assert at1[:2] == pytest.approx(at2[:2], abs=2e-8) and at1[2] == pytest.approx(at2[2], abs=2e-3)  # rounding
        assert at1[1] == pytest.approx(-2.3, abs=0.01) and at1[0] == pytest.approx(34.8, abs=0.01)
    apart = cli(["bag", "census", live["bag"], "--census-separation", "0", "--json"])
    assert _last_json(apart.stdout)["recounted"]["animals"] > census["animals"]
    refused = cli(["bag", "census", live["bag"], "--census-gate", "0"])
    assert refused.returncode != 0 and "--census-gate" in refused.stderr
    # every node reported on /diagnostics, and nothing went wrong (the placer may resend a step on a slow machine)
    health = live["health"]
    assert set(health) == {f"{s.label}: {s.executable}" for s in graph_spec(UpConfig(locate=True))}, health
    assert all(h["reports"].get("OK", 0) > 0 for h in health.values()), health
    assert all(set(h["reports"]) == {"OK"} for n, h in health.items() if n != "placer: placer"), health
    _check_time_base_tf_and_typed_detections(Path(live["bag"]), steps=3)
    # the run as a YOLO dataset (lossless PNG): val on it gives the live scores, its labels those of the bag
    ex = cli(["bag", "export", live["bag"], "--out", str(tmp_path / "exported"), "--format", "png",
              "--val-fraction", "0", "--json"])
    assert ex.returncode == 0, ex.stderr
    exported = _last_json(ex.stdout)
    assert exported["frames"] == {"train": 9, "val": 0} and exported["images_without_labels"] == 0
    assert len(list((tmp_path / "exported" / "images" / "train").glob("*.png"))) == 9
    from zebra_sim_ros.detection.evaluate import evaluate

    # at the live detector's threshold (val's own, 0.001, would score more of the curve than it published)
    m, facts = evaluate(None, tmp_path / "exported" / "dataset.yaml", split="train", device="cpu", conf=0.25)
    assert facts["imgsz"] == 544 and m.images == 9
    assert m.instances == live["scores"]["all"]["instances"] == exported["zebras_labelled"]
    assert abs(m.map50 - live["scores"]["all"]["mAP50"]) <= 0.01, (m.to_dict(), live["scores"]["all"])

    # Replay the recorded images (and labels) into a fresh detector with the live one's settings (the checkpoint's
    # rule: the shipped weights serve 640 px frames at 1088, so 320 px frames at 544); record its detections.
    live_detector = next(n for n in graph_spec(UpConfig(width=320, height=180)) if n.executable == "detector")
    detector_params = {k: v for k, v in live_detector.overrides.items() if k != "ack_name"}
    assert detector_params["scale"] == 0 and "imgsz" not in detector_params
    assert live["detect_imgsz"] == 544  # 1.7 x 320, a multiple of 32
    bag2 = tmp_path / "replayed.mcap"
    images = [f"/{d}/image_raw" for d in DRONES]
    labels = [f"/{d}/labels" for d in DRONES]
    peer = Peer(domain)
    got: dict[str, int] = {d: 0 for d in DRONES}
    def counter(drone: str) -> Any:
        def on_detections(msg: Any) -> None:  # one parameter: rclpy passes message info to two
            got[drone] += 1
        return on_detections

    for d in DRONES:
        peer.node.create_subscription(detection_array_class(), f"/{d}/detections", counter(d), 10)
    try:
        with node_process("recorder", {"output": str(bag2), "topic_regex": r"^/drone_\d+/(labels|detections)$",
                                       "discovery_period_s": 0.1}, domain, tmp_path / "recorder.log"), \
             node_process("detector", detector_params, domain, tmp_path / "detector.log"):
            outputs = [f"/{d}/detections" for d in DRONES]  # matched with this test and with the recorder first

            def matched() -> bool:
                return all(peer.node.count_publishers(t) and any(
                    i.node_name == "recorder" for i in peer.node.get_subscriptions_info_by_topic(t)) for t in outputs)
            assert peer.spin(matched, 120), "the detector and the recorder did not come up"
            peer.spin(lambda: False, 0.5)
            # Half speed: the bag's steps are 1 s of simulated time apart, and a fresh detector's first batch (torch
            # warming up) may take longer, after which it keeps only each topic's newest frame, as live.
            with node_process("replay", {"bags": [live["bag"]], "topics": images + labels, "rate": 0.5,
                                         "wait_for_subscribers_s": 60.0}, domain, tmp_path / "replay.log") as rp:
                assert peer.spin(lambda: rp.poll() is not None, 120), "replay did not finish"
                assert rp.returncode == 0
            assert peer.spin(lambda: sum(got.values()) >= 9, 60), got
            peer.spin(lambda: False, 1.0)  # the recorder receives the last detections too
    finally:
        peer.close()
    ev = cli(["bag", "eval", bag2, "--json"])
    assert ev.returncode == 0, ev.stderr
    replayed = _last_json(ev.stdout)
    assert [replayed[d]["frames"] for d in DRONES] == [3, 3, 3]
    assert abs(replayed["all"]["mAP50"] - a["mAP50"]) <= 0.01, (replayed["all"], a)
    assert abs(replayed["all"]["mAP50-95"] - a["mAP50-95"]) <= 0.01, (replayed["all"], a)


def _check_time_base_tf_and_typed_detections(bag: Path, steps: int) -> None:
    """The bag, read by rosbags (an independent reader): /clock once per step, /tf with one transform per drone
    per step (map -> drone_i/base_link) and /tf_static base_link -> camera_optical, typed detections, the placed
    animals' typed 3D boxes once per step, and every
    message's log time equal to its header stamp, but for /diagnostics: logged at the recorder's (simulated) clock
    whatever clock its reporter stamped it with (the test's own reporter runs on wall time). A camera's /tf body
    composed with its /tf_static link is its recorded camera/pose, position and orientation."""
    from rosbags.highlevel import AnyReader

    from zebra_sim_ros.geometry.frames import xyzw_to_matrix
    from zebra_sim_ros.recording.stamps import REPORT_TYPES

    clocks, tf, static, stamped, detections, reports, animals = [], [], [], 0, 0, [], []
    poses: dict[tuple[str, int], Any] = {}
    reporters: set[str] = set()
    with AnyReader([bag]) as reader:
        for conn, t, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic == "/clock":
                clocks.append(msg.clock.sec * 10**9 + msg.clock.nanosec)
                assert t == clocks[-1]
            elif conn.topic in ("/tf", "/tf_static"):
                assert conn.msgtype == "tf2_msgs/msg/TFMessage"
                (tf if conn.topic == "/tf" else static).append((t, msg))
            elif conn.topic.endswith("/camera/pose"):
                poses[(conn.topic.split("/")[1], t)] = msg.pose
            elif conn.topic == "/zebra_sim/zebras":  # the placed animals, typed, in map
                assert conn.msgtype.endswith("/msg/Detection3DArray"), conn.msgtype
                animals.append(msg)
            elif conn.topic.endswith("/detections"):
                assert conn.msgtype.endswith("/msg/Detection2DArray"), conn.msgtype
                detections += 1
                for d in msg.detections:
                    assert d.results[0].hypothesis.class_id == "zebra" and 0 < d.results[0].hypothesis.score <= 1
            header = getattr(msg, "header", None)
            if conn.msgtype in REPORT_TYPES:
                reports.append(t)
                reporters.update(x.name for x in msg.status)
            elif header is not None:
                assert t == header.stamp.sec * 10**9 + header.stamp.nanosec, (conn.topic, t, header.stamp)
                stamped += 1
    assert len(clocks) == steps and clocks == sorted(clocks)
    assert "test: wall clock" in reporters and "scorer: scorer" in reporters, reporters
    assert all(0 <= t <= clocks[-1] + 10**9 for t in reports), (min(reports), max(reports), clocks)
    assert [t for t, _ in tf] == clocks
    from mcap.reader import make_reader

    with open(bag, "rb") as f:  # /clock latched (depth 1): a recorder whose reader matched late still has step 0
        summary = make_reader(f).get_summary()
    assert summary is not None
    offered = {c.topic: c.metadata["offered_qos_profiles"] for c in summary.channels.values()}
    assert "transient_local" in offered["/clock"] and "transient_local" not in offered["/tf"]
    assert all(sorted(x.child_frame_id for x in m.transforms) == [f"{d}/base_link" for d in DRONES] and
               all(x.header.frame_id == "map" for x in m.transforms) for _, m in tf)
    links = {(x.header.frame_id, x.child_frame_id) for _, m in static for x in m.transforms}
    assert links == {(f"{d}/base_link", f"{d}/camera_optical") for d in DRONES}

    def rotation(q: Any) -> np.ndarray:
        return xyzw_to_matrix((q.x, q.y, q.z, q.w))

    link = {x.header.frame_id.split("/")[0]: rotation(x.transform.rotation) for _, m in static for x in m.transforms}
    for t, m in tf:  # map -> base_link -> camera_optical is the camera's pose
        for x in m.transforms:
            drone = x.child_frame_id.split("/")[0]
            pose = poses[(drone, t)]
            at = x.transform.translation
            assert [at.x, at.y, at.z] == pytest.approx([pose.position.x, pose.position.y, pose.position.z], abs=1e-9)
            assert np.abs(rotation(x.transform.rotation) @ link[drone] - rotation(pose.orientation)).max() < 1e-9
    assert detections == steps * len(DRONES) and stamped > 20
    assert len(animals) == steps and all(m.header.frame_id == "map" and m.detections for m in animals)
    zebras = [d for m in animals for d in m.detections if d.results[0].hypothesis.class_id == "zebra"]
    # longer than wide, and the box's centre above the animal's origin on the ground
    assert zebras and all(d.bbox.size.x > d.bbox.size.y > 0 and d.bbox.size.z > 0.3 and
                          d.bbox.center.position.z > d.results[0].pose.pose.position.z for d in zebras)


def test_up_stops_everything_and_names_the_node_that_died(tmp_path: Path) -> None:
    import torch

    from zebra_sim_ros.detection.checkpoint import save_checkpoint
    from zebra_sim_ros.detection.model import ModelConfig, build_model

    domain = fresh_domain_id()
    unreadable = tmp_path / "unreadable.pt"
    unreadable.write_bytes(b"not a checkpoint" * 100)
    run = _up(tmp_path / "up0", domain, "--weights", str(unreadable), timeout=240)
    # up reads the checkpoint's serving rule before it starts anything: a file that is no checkpoint stops it there
    assert run.returncode == 2 and "unreadable.pt" in run.stderr, run.stderr[-3000:]
    assert not (tmp_path / "up0" / "logs").exists() and _processes_in(domain) == []
    # A checkpoint whose weights do not fit its own config reads as one, so only the detector node finds out.
    bad = tmp_path / "broken.pt"
    save_checkpoint(bad, build_model(ModelConfig(size="n")))
    broken = torch.load(bad, weights_only=True)
    broken["config"]["size"] = "s"
    torch.save(broken, bad)
    run = _up(tmp_path / "up", domain, "--weights", str(bad), timeout=240)
    assert run.returncode == 1, run.stdout[-3000:]
    summary = _last_json(run.stdout)
    assert summary["died"] == "detector" and summary["died_status"] == 2
    assert "node detector died (exit status 2)" in run.stdout and "broken.pt" in run.stdout
    assert all(code is not None for code in summary["exit_status"].values())
    assert _processes_in(domain) == []


def test_ctrl_c_stops_the_graph_with_a_complete_bag(tmp_path: Path) -> None:
    domain = fresh_domain_id()
    out = tmp_path / "up"
    proc = subprocess.Popen([sys.executable, "-m", "zebra_sim_ros.cli", "up", "--frames", "500", "--size", "160x96",
                             "--out", str(out), "--domain-id", str(domain), "--json"], env=ros_env(domain),
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # as a terminal's
    try:                                                       # foreground job, even if pytest runs in background
        assert proc.stdout is not None
        lines = []
        end = time.monotonic() + 240
        while time.monotonic() < end:
            line = proc.stdout.readline()
            lines.append(line)
            if line.startswith("[up] step ") or not line:  # the first step shown (a fast step may go unprinted)
                break
        assert lines[-1].startswith("[up] step "), "".join(lines)
        proc.send_signal(signal.SIGINT)
        rest, _ = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, rest[-3000:]
    summary = _last_json(rest)
    assert "interrupted" in rest
    assert summary["damaged"] == [] and 1 <= summary["steps"] < 500
    assert all(code is not None for code in summary["exit_status"].values())
    assert _processes_in(domain) == []


def test_two_graphs_in_two_namespaces_share_a_domain_without_crosstalk(tmp_path: Path) -> None:
    """Two whole graphs on one domain, in /g1 and /g2: /g1 records its own topics only (its /g1/tf, /g1/clock
    included), with its own three steps, its images as jpeg (``--bag-images jpeg``); each graph's scorer scores its
    own frames. /g2 runs two drones and no recorder: no bag, and the scorer's figures (six frames) are its scores."""
    from rosbags.highlevel import AnyReader

    domain = fresh_domain_id()
    procs = {ns: subprocess.Popen([sys.executable, "-m", "zebra_sim_ros.cli", "up", "--frames", "3", "--size",
                                   "256x144", "--out", str(tmp_path / ns), "--domain-id", str(domain), "--namespace",
                                   f"/{ns}", "--seed", str(k), "--json",
                                   *(["--no-record", "--drones", "2"] if ns == "g2" else ["--bag-images", "jpeg"])],
                                  env=ros_env(domain), text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
             for k, ns in enumerate(("g1", "g2"))}
    try:
        outs = {}
        for ns, p in procs.items():
            try:
                outs[ns] = p.communicate(timeout=300)
            except subprocess.TimeoutExpired:  # where it is stuck: its threads' stacks (SIGUSR1), then its output
                p.send_signal(signal.SIGUSR1)
                time.sleep(2)
                p.kill()
                stdout, stderr = p.communicate()
                pytest.fail(f"up in /{ns} did not end in 300 s:\n{stdout[-3000:]}\n{stderr[-6000:]}")
    finally:
        for p in procs.values():
            if p.poll() is None:
                p.kill()
    for ns, (stdout, stderr) in outs.items():
        assert procs[ns].returncode == 0, stdout[-3000:] + stderr[-2000:]
        s = _last_json(stdout)
        live = s["live_scores"]
        cfg = UpConfig(record=ns == "g1", drones=3 if ns == "g1" else 2)
        assert live["frames"] == 3 * cfg.drones and live["complete"] and 0 < live["all"]["mAP50"] <= 1, live
        assert set(live) - {"frames", "complete", "all"} == set(cfg.drone_names), live
        assert set(s["health"]) == {f"{ns}/{n.label}: {n.executable}" for n in graph_spec(cfg)}
        # the RViz file written for this graph: its own drones' detection images, in its namespace
        rviz = yaml.safe_load(Path(s["rviz"]).read_text())["Visualization Manager"]["Displays"]
        images = [t for d in rviz if (t := d.get("Topic", {}).get("Value", "")).endswith("/detections/image")]
        assert images == [f"/{ns}/{d}/detections/image" for d in cfg.drone_names], images
        assert f"-r /tf:=/{ns}/tf" in stdout and s["rviz"] in stdout  # the command that opens it
        if ns == "g2":
            assert "steps" not in s and not (tmp_path / ns / "zebra_sim.mcap").exists()
            assert "the scorer node, live over its last 6 frames" in stdout
            continue
        assert live["all"]["mAP50"] == pytest.approx(s["scores"]["all"]["mAP50"], abs=2e-4)
        assert s["steps"] == 3 and s["frames"] == {d: {"image_raw": 3, "labels": 3, "detections": 3} for d in DRONES}
        with AnyReader([Path(s["bag"])]) as reader:
            topics = {c.topic for c in reader.connections}
            clocks = [t for c, t, _ in reader.messages() if c.topic == f"/{ns}/clock"]
        assert all(t.startswith(f"/{ns}/") for t in topics), sorted(topics)
        assert {f"/{ns}/tf", f"/{ns}/tf_static", f"/{ns}/zebra_sim/scene", f"/{ns}/drone_0/detections"} <= topics
        assert len(clocks) == 3  # its own steps only: the other graph's clock never reached it
        # jpeg in the bag, not the raw images nor the detector's annotated copies; the summary reads them
        assert {f"/{ns}/{d}/image_raw/compressed" for d in DRONES} <= topics
        assert not {t for t in topics if t.endswith(("/image_raw", "/detections/image"))}, sorted(topics)
        preview = cv2.imread(s["preview"])
        assert preview is not None and preview.shape == (144, 768, 3)
        # exported as recorded (the jpeg bytes), a step's three frames in one split
        ex = subprocess.run([sys.executable, "-m", "zebra_sim_ros.cli", "bag", "export", s["bag"], "--out",
                             str(tmp_path / "ex"), "--val-fraction", "0.5", "--seed", "3", "--json"],
                            capture_output=True, text=True, timeout=120)
        assert ex.returncode == 0, ex.stderr
        assert sum(_last_json(ex.stdout)["frames"].values()) == 9
        files = sorted((tmp_path / "ex" / "images").glob("*/*.jpg"))
        with AnyReader([Path(s["bag"])]) as reader:
            payloads = {bytes(reader.deserialize(raw, c.msgtype).data) for c, _, raw in reader.messages()
                        if c.topic.endswith("/image_raw/compressed")}
        assert len(files) == 9 and {f.read_bytes() for f in files} == payloads
        split_of_step: dict[str, set[str]] = {}
        for f in files:
            split_of_step.setdefault(f.stem.rsplit("_", 1)[1], set()).add(f.parent.name)
        assert len(split_of_step) == 3 and all(len(v) == 1 for v in split_of_step.values()), split_of_step
    assert _processes_in(domain) == []


def test_up_on_a_full_disk_ends_with_one_line_and_a_finalised_bag(tmp_path: Path) -> None:
    """On a 6 MB tmpfs the recorder stops before the disk is full: the bag is finalised (summary and indexes)
    with every message the recorder reported written, and up ends with one error line and a failure status."""
    import shutil

    from mcap.reader import make_reader
    from rosbags.highlevel import AnyReader

    disk = tmp_path / "disk"
    disk.mkdir()
    if shutil.which("mount") is None or subprocess.run(["mount", "-t", "tmpfs", "-o", "size=6m", "tmpfs", str(disk)],
                                                       capture_output=True).returncode != 0:
        pytest.skip("cannot mount a tmpfs here (needs root): the full-disk check needs a small file system")
    try:
        run = _up(disk / "up", fresh_domain_id(), "--frames", "8", timeout=600)
        assert run.returncode == 1, run.stdout[-3000:]
        assert "Traceback" not in run.stdout + run.stderr
        last = [ln for ln in run.stdout.splitlines() if ln.startswith("[up]")][-1]
        assert last.startswith("[up] error: the recording stopped early: disk nearly full"), last
        reported = int(last.split("finalised with the ")[1].split(" messages")[0])
        with open(disk / "up" / "zebra_sim.mcap", "rb") as f:
            summary = make_reader(f).get_summary()
        assert summary is not None and summary.statistics is not None  # finalised: a summary section
        assert summary.statistics.message_count == reported > 50
        with AnyReader([disk / "up" / "zebra_sim.mcap"]) as reader:
            assert sum(1 for _ in reader.messages()) == reported
    finally:
        subprocess.run(["umount", str(disk)], capture_output=True)
