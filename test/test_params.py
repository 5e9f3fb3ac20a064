"""Parameters declared once: config/*.yaml, ROS descriptors and run-time changes all follow the declarations."""

from __future__ import annotations

import argparse
import re
import textwrap
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from ros_helpers import call_service, set_parameter

from zebra_sim_ros.detection.config import DetectorConfig
from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.graph.spec import NODE_PARAMS
from zebra_sim_ros.labels.config import LabelFilters, LabellerConfig
from zebra_sim_ros.params import (
    StageConfig,
    config_yaml,
    declaration,
    diagnostics_param,
    load_params_file,
    node_pattern,
    param,
    write_config,
    yaml_header,
)
from zebra_sim_ros.placement.config import PlacerConfig
from zebra_sim_ros.rendering.config import CameraConfig
from zebra_sim_ros.zebra.lod import DETAIL_DISTANCE_M

REPO = Path(__file__).resolve().parents[1]


# -- one declaration, everything derived ------------------------------------------------------------------------
@pytest.mark.parametrize("executable", sorted(NODE_PARAMS))
def test_config_file_is_what_the_declarations_write(executable: str) -> None:
    """Regenerate with ``python -m zebra_sim_ros.graph.spec --write-config config/`` when this fails."""
    text = (REPO / "config" / f"{executable}.yaml").read_text(encoding="utf-8")
    assert text == config_yaml(NODE_PARAMS[executable], yaml_header(executable, text)), \
        f"config/{executable}.yaml differs from its declarations: run " \
        "python -m zebra_sim_ros.graph.spec --write-config config/"


def test_written_config_reads_back_as_the_defaults_and_keeps_its_header(tmp_path: Path) -> None:
    (tmp_path / "placer.yaml").write_text("# my notes\n/**:\n  ros__parameters:\n    seed: 5\n")
    assert {p.name for p in write_config(tmp_path, NODE_PARAMS)} == {f"{n}.yaml" for n in NODE_PARAMS}
    assert write_config(tmp_path, NODE_PARAMS) == []  # nothing changes a second time
    assert (tmp_path / "placer.yaml").read_text().startswith("# my notes\n/**:\n")
    for executable, specs in NODE_PARAMS.items():
        values = load_params_file(str(tmp_path / f"{executable}.yaml"), executable)
        assert values == {s.name: s.default for s in specs}
        assert all(type(values[s.name]) is type(s.default) for s in specs), executable  # 1.0 stays a float


def test_a_parameter_files_sections_apply_to_a_node_as_ros_applies_them(tmp_path: Path) -> None:
    """Sections are matched against the node's fully qualified name (``/**`` and ``/**/name`` everywhere, ``*`` one
    namespace, a key without a leading slash in the root namespace only, another namespace's section never), every
    matching one in file order, the later overriding: what rclpy itself gives a node of that name for the file."""
    import rclpy
    from ros_helpers import fresh_domain_id

    (tmp_path / "scorer.yaml").write_text(textwrap.dedent("""\
        /g1/scorer:
          ros__parameters: {window: 11, qos_depth: 7}
        /**:
          ros__parameters: {window: 1, qos_depth: 1, diagnostics_period_s: 2.0}
        /g2/scorer:
          ros__parameters: {window: 0}
        /**/scorer:
          ros__parameters: {window: 3, qos_depth: 3}
        /g1/*:
          ros__parameters: {qos_depth: 4}
        scorer:
          ros__parameters: {window: 2}
        /g1/labeller:
          ros__parameters: {window: 99}
        """))
    path = str(tmp_path / "scorer.yaml")
    expected = {"/g1/scorer": {"window": 3, "qos_depth": 4, "diagnostics_period_s": 2.0},
                "/scorer": {"window": 2, "qos_depth": 3, "diagnostics_period_s": 2.0},
                "/g3/deep/scorer": {"window": 3, "qos_depth": 3, "diagnostics_period_s": 2.0},
                "/g1/recorder": {"window": 1, "qos_depth": 4, "diagnostics_period_s": 2.0}}
    for fqn, want in expected.items():
        assert load_params_file(path, fqn) == pytest.approx(want), fqn
        ns, name = fqn.rsplit("/", 1)
        ctx = rclpy.Context()
        rclpy.init(args=["--ros-args", "--params-file", path, "-r", f"__ns:={ns or '/'}"], context=ctx,
                   domain_id=fresh_domain_id())
        try:
            node = rclpy.create_node(name, context=ctx, automatically_declare_parameters_from_overrides=True)
            ros = {k: node.get_parameter(k).value for k in want}
            node.destroy_node()
        finally:
            rclpy.shutdown(context=ctx)
        assert ros == pytest.approx(want), (fqn, ros)  # rclpy's own reading of the same file
    # no leading slash: the root namespace
    assert load_params_file(path, "scorer") == pytest.approx(expected["/scorer"])
    # the nested form (a namespace holding node names), as rclpy reads it
    (tmp_path / "nested.yaml").write_text(textwrap.dedent("""\
        /**:
          scorer:
            ros__parameters: {window: 5}
        g1:
          scorer:
            ros__parameters: {qos_depth: 9}
          "*":
            ros__parameters: {diagnostics_period_s: 3.0}
        """))
    nested = str(tmp_path / "nested.yaml")
    assert load_params_file(nested, "/g1/scorer") == pytest.approx({"window": 5, "qos_depth": 9,
                                                                    "diagnostics_period_s": 3.0})
    ctx = rclpy.Context()
    rclpy.init(args=["--ros-args", "--params-file", nested, "-r", "__ns:=/g1"], context=ctx,
               domain_id=fresh_domain_id())
    try:
        node = rclpy.create_node("scorer", context=ctx, automatically_declare_parameters_from_overrides=True)
        ros = {k: node.get_parameter(k).value for k in ("window", "qos_depth", "diagnostics_period_s")}
        node.destroy_node()
    finally:
        rclpy.shutdown(context=ctx)
    assert ros == pytest.approx(load_params_file(nested, "/g1/scorer"))
    # what ROS refuses is refused, named, whichever node asks
    for bad in ("/**/:\n  ros__parameters: {a: 1}\n", "//scorer:\n  ros__parameters: {a: 1}\n",
                "/g*/scorer:\n  ros__parameters: {a: 1}\n", "/g1/scorer: 5\n",
                "/**:\n  ros__parameters: [1, 2]\n", "/**:\n  ros__parameters: {a: 1}\n  other: {b: 2}\n"):
        (tmp_path / "bad.yaml").write_text(bad)
        with pytest.raises(ParameterError, match="params_file"):
            load_params_file(str(tmp_path / "bad.yaml"), "/recorder")
    with pytest.raises(ParameterError, match="'node'"):
        load_params_file(path, "/g1/scorer/")
    assert node_pattern("/**").fullmatch("/a/b/c") and not node_pattern("/g1/*").fullmatch("/g1/a/b")


def test_every_number_has_its_range_as_data_and_validation_keeps_to_it() -> None:
    for executable, specs in NODE_PARAMS.items():
        assert len({s.name for s in specs}) == len(specs), executable
        for s in specs:
            if isinstance(s.default, int | float) and not isinstance(s.default, bool):
                assert s.lo is not None and s.hi is not None and s.lo <= s.default <= s.hi, (executable, s.name)
                assert s.check(s.lo) and s.check(s.hi) and not s.check(s.hi + 1) and not s.check(s.lo - 1)
            required = (executable, s.name) == ("replay", "bags")  # no default: the bags to play must be named
            assert (s.check(s.default) or required) and s.allowed and s.description, (executable, s.name)


def test_shared_parameters_are_declared_once() -> None:
    for f in fields(LabelFilters):  # the label filters: one declaration for the dataclass and the labeller
        assert declaration(LabellerConfig, f.name) == declaration(LabelFilters, f.name)
    assert LabellerConfig().filters() == LabelFilters()
    assert "hfov_deg" not in {s.name for s in LabellerConfig.specs()}  # its intrinsics come with CameraInfo
    for cam, placer in (("width", "camera_width"), ("height", "camera_height"), ("hfov_deg", "camera_hfov_deg")):
        a, b = declaration(CameraConfig, cam), declaration(PlacerConfig, placer)
        assert (a.default, a.unit, a.lo, a.hi) == (b.default, b.unit, b.lo, b.hi), cam
    assert LabellerConfig().zebra_detail_distance_m == DETAIL_DISTANCE_M


def test_bad_values_name_the_parameter_the_value_and_what_is_allowed() -> None:
    with pytest.raises(ParameterError, match=r"'conf' = 1\.5 is invalid: allowed 0\.\.1"):
        DetectorConfig.from_params({"conf": 1.5})
    with pytest.raises(ParameterError, match=r"'scale' = 0\.1 .*0 \(off\) or 0\.25\.\.4"):
        DetectorConfig.from_params({"scale": 0.1})
    with pytest.raises(ParameterError, match=r"'camera_width' = 9000 .*16\.\.8192 px"):
        PlacerConfig.from_params({"camera_width": 9000})
    with pytest.raises(ParameterError, match=r"'image_topics' .*'d/image_raw' and 'd/image_raw/compressed' both "
                       r"publish d/detections"):
        DetectorConfig.from_params({"image_topics": ["d/image_raw", "d/image_raw/compressed"]})
    cfg = DetectorConfig().with_changes({"conf": 0.5, "imgsz": 640})
    assert (cfg.conf, cfg.imgsz, cfg.iou) == (0.5, 640, DetectorConfig().iou)
    assert [s.name for s in DetectorConfig.specs() if s.runtime] == ["conf", "iou", "imgsz", "scale"]


def test_cli_options_mirror_the_declarations(capsys: pytest.CaptureFixture[str]) -> None:
    import argparse

    from zebra_sim_ros.params import add_option

    specs = {s.name: s for s in PlacerConfig.specs()}
    p = argparse.ArgumentParser(prog="t")
    add_option(p, specs["rate_hz"])
    add_option(p, specs["strategy"], default=None)
    add_option(p, specs["morph_weights"], "--weights")
    assert vars(p.parse_args([])) == {"rate_hz": 1.0, "strategy": None, "morph_weights": [0.6, 0.25, 0.15]}
    args = p.parse_args(["--rate-hz", "2", "--strategy", "closeby", "--weights", "[1, 0, 0]"])
    assert (args.rate_hz, args.strategy, args.morph_weights) == (2.0, "closeby", [1, 0, 0])
    text = " ".join(p.format_help().split())
    assert "steps per second" in text and "0.001..1000 Hz" in text
    with pytest.raises(SystemExit):
        p.parse_args(["--rate-hz", "0"])
    assert "--rate-hz" in capsys.readouterr().err


# (subcommand, flag, node, parameter) for every zebra-sim option that mirrors a node parameter.
MIRRORED = [
    ("generate", "--min-visible-pixels", "labeller", "min_visible_pixels"),
    ("generate", "--min-box-px", "labeller", "min_box_px"),
    ("generate", "--hfov", "camera", "hfov_deg"),
    ("generate", "--world-seed", "placer", "world_seed"),
    ("render", "--width", "camera", "width"),
    ("render", "--strategy", "placer", "strategy"),
    ("place", "--start-step", "placer", "start_step"),
    ("up", "--detect-scale", "detector", "scale"),
    ("up", "--seed", "placer", "seed"),
    ("val", "--imgsz", "detector", "imgsz"),
    ("val", "--iou", "detector", "iou"),
    ("val", "--amp", "detector", "amp"),
    ("val", "--count-conf", "scorer", "count_conf"),
    ("up", "--detect-amp", "detector", "amp"),
]


@pytest.mark.parametrize(("command", "flag", "node", "name"), MIRRORED)
def test_zebra_sim_options_are_derived_from_the_declarations(command: str, flag: str, node: str, name: str) -> None:
    """The option's help carries the parameter's description and range; a value outside the range is refused by
    the option, naming it, as the node would refuse it at start."""
    from zebra_sim_ros.cli import build_parser

    spec = {s.name: s for s in NODE_PARAMS[node]}[name]
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    parser = sub.choices[command]
    action = next(a for a in parser._actions if flag in a.option_strings)
    assert action.dest == name
    help_text = " ".join((action.help or "").split())
    assert spec.description.split(",")[0].split("(")[0].strip() in help_text and spec.allowed in help_text
    bad = str(int(spec.lo) - 7) if spec.lo is not None else "'not a value'"
    assert callable(action.type)
    with pytest.raises(argparse.ArgumentTypeError, match="allowed"):
        action.type(bad)
    assert action.type(repr(spec.default) if not isinstance(spec.default, str) else spec.default) == spec.default


def test_descriptors_carry_the_ranges() -> None:
    from zebra_sim_ros.nodes.ros_adapter import descriptor

    specs = {s.name: s for s in NODE_PARAMS["detector"]}
    conf = descriptor(specs["conf"])
    assert conf.dynamic_typing and not conf.integer_range
    assert (conf.floating_point_range[0].from_value, conf.floating_point_range[0].to_value) == (0.0, 1.0)
    assert "confidence threshold" in conf.description and conf.additional_constraints == "0..1"
    max_det = descriptor(specs["max_det"])
    assert (max_det.integer_range[0].from_value, max_det.integer_range[0].to_value) == (1, 10000)
    assert not max_det.floating_point_range
    weights = descriptor(specs["weights"])
    assert not weights.floating_point_range and not weights.integer_range
    assert not descriptor(specs["conf"], ranges=False).floating_point_range


# -- the node base class, in this process ------------------------------------------------------------------------
@dataclass(frozen=True)
class ToyConfig(StageConfig):
    rate: float = param(1.0, "speed", "Hz", lo=0.5, hi=10.0, runtime=True)
    count: int = param(3, "how many", lo=1, hi=5)
    label: str = param("a", "a name", allowed="any string")


def _toy_node(ctx: Any, **node_args: Any) -> Any:
    from zebra_sim_ros.nodes.ros_adapter import ZebraNode

    class ToyNode(ZebraNode[ToyConfig]):
        def start(self) -> None:
            self.started = self.cfg
            self.applied: list[ToyConfig] = []

        def on_config(self, cfg: ToyConfig) -> None:
            self.cfg = cfg
            self.applied.append(cfg)

    return ToyNode("toy", ToyConfig, context=ctx, **node_args)


@pytest.fixture
def ros_context():  # type: ignore[no-untyped-def]
    import rclpy
    from ros_helpers import fresh_domain_id

    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=fresh_domain_id())  # only this process's own calls, on a private domain
    yield ctx
    rclpy.shutdown(context=ctx)


def test_yaml_integer_for_a_float_parameter_and_the_ranges_in_the_descriptor(ros_context: Any, tmp_path: Path) -> None:
    params = tmp_path / "toy.yaml"
    params.write_text("/**:\n  ros__parameters:\n    rate: 2\n")
    node = _toy_node(ros_context, cli_args=["--ros-args", "--params-file", str(params)])
    try:
        assert node.cfg.rate == 2.0 and isinstance(node.cfg.rate, float) and node.started == node.cfg
        d = node.describe_parameter("rate")
        assert (d.floating_point_range[0].from_value, d.floating_point_range[0].to_value) == (0.5, 10.0)
        assert (node.describe_parameter("count").integer_range[0].to_value) == 5
    finally:
        node.destroy_node()


def test_a_bad_start_value_is_named_by_validation_not_rclpy(ros_context: Any) -> None:
    from rclpy.parameter import Parameter

    with pytest.raises(ParameterError, match=r"'rate' = 50\.0 is invalid: allowed 0\.5\.\.10 Hz"):
        _toy_node(ros_context, parameter_overrides=[Parameter("rate", value=50.0)])


def test_set_parameters_applies_runtime_ones_and_refuses_the_rest_with_a_reason(ros_context: Any) -> None:
    from rclpy.parameter import Parameter

    node = _toy_node(ros_context)
    try:
        ok = node.set_parameters([Parameter("rate", value=4)])[0]  # an integer for a float, as `param set` sends 4
        assert ok.successful and node.cfg.rate == 4.0 and len(node.applied) == 1
        bad_type = node.set_parameters([Parameter("rate", value="abc")])[0]
        assert not bad_type.successful and "'rate'" in bad_type.reason and "'abc'" in bad_type.reason
        out_of_range = node.set_parameters([Parameter("rate", value=20.0)])[0]
        assert not out_of_range.successful and "rate" in out_of_range.reason
        fixed = node.set_parameters([Parameter("count", value=4)])[0]
        assert not fixed.successful and fixed.reason == "'count' cannot change while the node runs; restart it"
        assert node.set_parameters([Parameter("count", value=3)])[0].successful  # the same value: nothing to refuse
        assert node.get_parameter("rate").value == 4 and node.get_parameter("count").value == 3
        assert node.cfg == ToyConfig(rate=4.0) and len(node.applied) == 1
        assert node.set_parameters([Parameter("use_sim_time", value=False)])[0].successful  # rclpy's own
    finally:
        node.destroy_node()


@dataclass(frozen=True)
class ReportingConfig(StageConfig):
    diagnostics_period_s: float = diagnostics_param()


def test_reports_from_two_threads_are_made_one_at_a_time(ros_context: Any) -> None:
    """A node spun by two executor threads (the replay) may make its last report while a timer's report runs; each
    reads the activity and remembers its counters for the next, so the two must not interleave."""
    import threading
    import time

    from zebra_sim_ros.health import Activity
    from zebra_sim_ros.nodes.ros_adapter import ZebraNode

    class Reporting(ZebraNode[ReportingConfig]):
        def start(self) -> None:
            self.steps = 0
            self.inside = 0
            self.most_inside = 0
            self.reports: list[Any] = []

        def activity(self) -> Activity:
            self.inside += 1
            self.most_inside = max(self.most_inside, self.inside)
            self.steps += 1
            time.sleep(0.02)  # the counters read, the report not yet made: where another thread's report would land
            self.inside -= 1
            return Activity(counters={"steps": self.steps}, work="steps")

    from rclpy.parameter import Parameter

    node = Reporting("reporting", ReportingConfig, context=ros_context,  # a period that never fires in the test
                     parameter_overrides=[Parameter("diagnostics_period_s", value=3600.0)])
    try:
        go = threading.Barrier(2)

        def report() -> None:
            go.wait()
            for _ in range(10):
                node.reports.append(node.publish_diagnostics())

        threads = [threading.Thread(target=report) for _ in range(2)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(timeout=30)
        assert len(node.reports) == 20 and node.most_inside == 1
        assert sorted(int(dict(h.values)["steps"]) for h in node.reports) == list(range(1, 21))
        # each report counts from the one made before it: one step, never a later report's total (a negative rate)
        assert all(float(dict(h.values)["steps per second"]) > 0 for h in node.reports)
        # the node's last report (run_node's, as it ends) is the last: a timer's report after it makes none
        assert node.publish_diagnostics(last=True) is not None and node.publish_diagnostics() is None
        assert node.steps == 21
    finally:
        node.destroy_node()


# -- the detector node as a process: `ros2 param set /detector conf 0.9` -----------------------------------------
def _get_conf(peer: Any) -> float:
    from rcl_interfaces.srv import GetParameters

    return float(call_service(peer, GetParameters, "/detector/get_parameters",
                          GetParameters.Request(names=["conf"])).values[0].double_value)


@pytest.mark.integration
def test_param_set_changes_the_running_detector(tmp_path: Path) -> None:
    from builtin_interfaces.msg import Time
    from rcl_interfaces.srv import DescribeParameters
    from ros_helpers import Peer, detection_array_class, detections_dict, fresh_domain_id, node_process
    from sensor_msgs.msg import Image
    from std_msgs.msg import Header

    from zebra_sim_ros.detection.checkpoint import save_checkpoint
    from zebra_sim_ros.detection.model import ModelConfig, build_model

    weights = tmp_path / "random.pt"  # untrained: its scores are far below 0.9
    save_checkpoint(weights, build_model(ModelConfig(size="n", imgsz=320)).eval())
    peer = Peer(fresh_domain_id(), "test_params")
    got: dict[int, list[float]] = {}  # image stamp (s) -> detection scores

    def on_detections(msg: Any) -> None:
        d = detections_dict(msg)
        got[d["stamp"]["sec"]] = [x["score"] for x in d["detections"]]

    peer.node.create_subscription(detection_array_class(), "/drone_0/detections", on_detections, 10)
    pub = peer.node.create_publisher(Image, "/drone_0/image_raw", 10)
    rgb = np.random.default_rng(0).integers(0, 255, (180, 320, 3), dtype=np.uint8)

    def detect(sec: int) -> list[float]:
        pub.publish(Image(header=Header(stamp=Time(sec=sec), frame_id="drone_0/camera_optical"), height=180,
                          width=320, encoding="rgb8", step=960, data=rgb.tobytes()))
        assert peer.spin(lambda: sec in got, 60), log.read_text()
        return got[sec]

    log = tmp_path / "detector.log"
    params = {"image_topics": ["/drone_0/image_raw"], "weights": str(weights), "imgsz": 320, "conf": 0.0,
              "image_reliability": "reliable",
              "max_det": 50}
    try:
        with node_process("detector", params, peer.ctx.get_domain_id(), log) as proc:
            assert peer.spin(lambda: peer.node.count_subscribers("/drone_0/image_raw") > 0, 60), log.read_text()
            before = detect(1)
            assert before and min(before) < 0.9  # conf 0: every candidate, up to max_det
            assert set_parameter(peer, "/detector", "conf", 0.9).successful
            assert _get_conf(peer) == pytest.approx(0.9)
            after = detect(2)
            assert len(after) < len(before) and all(s >= 0.9 for s in after), after
            assert re.search(r"now conf 0\.9\b", log.read_text())
            for value in ("abc", 1.5):
                refused = set_parameter(peer, "/detector", "conf", value)
                assert not refused.successful and "conf" in refused.reason, refused.reason
            refused = set_parameter(peer, "/detector", "weights", "/elsewhere.pt")
            assert not refused.successful and "'weights' cannot change while the node runs" in refused.reason
            assert _get_conf(peer) == pytest.approx(0.9)
            desc = call_service(peer, DescribeParameters, "/detector/describe_parameters",
                            DescribeParameters.Request(names=["conf", "max_det"])).descriptors
            assert (desc[0].floating_point_range[0].from_value, desc[0].floating_point_range[0].to_value) == (0, 1)
            assert desc[1].integer_range[0].to_value == 10000
            assert proc.poll() is None, log.read_text()
    finally:
        peer.close()


@pytest.mark.integration
def test_replay_rate_changes_while_it_waits(tmp_path: Path) -> None:
    import time

    from rclpy.serialization import serialize_message
    from ros_helpers import Peer, fresh_domain_id, node_process
    from std_msgs.msg import String

    from zebra_sim_ros.recording.qos import profile_dict
    from zebra_sim_ros.recording.writer import BagWriter

    bag = tmp_path / "slow.mcap"
    w = BagWriter(bag)
    w.add_channel("/tick", "std_msgs/msg/String", [profile_dict()])
    for k in range(6):  # 2 s apart: 100 s at rate 0.1
        w.write("/tick", serialize_message(String(data=f"tick {k}")), 5_000_000_000 + k * 2_000_000_000)
    w.close()
    peer = Peer(fresh_domain_id(), "test_params")
    got: list[tuple[str, float]] = []
    peer.node.create_subscription(String, "/tick", lambda m: got.append((m.data, time.monotonic())), 10)
    log = tmp_path / "replay.log"
    params = {"bags": [str(bag)], "rate": 0.1, "wait_for_subscribers_s": 20.0}
    try:
        with node_process("replay", params, peer.ctx.get_domain_id(), log) as proc:
            assert peer.spin(lambda: len(got) == 1, 30), log.read_text()
            assert not set_parameter(peer, "/replay", "loop", True).successful
            assert not set_parameter(peer, "/replay", "rate", 0.0).successful
            assert set_parameter(peer, "/replay", "rate", 50.0).successful
            changed = time.monotonic()
            assert peer.spin(lambda: len(got) == 6, 10), log.read_text()
            assert got[-1][1] - changed < 2.0  # 8 s of bag at 50x, not the 80 s left at 0.1x
            assert [d for d, _ in got] == [f"tick {k}" for k in range(6)]
            assert proc.wait(timeout=20) == 0
    finally:
        peer.close()


@pytest.mark.integration
def test_recorder_records_topics_added_while_it_runs(tmp_path: Path) -> None:
    import signal

    from ros_helpers import Peer, fresh_domain_id, node_process
    from rosbags.highlevel import AnyReader
    from std_msgs.msg import String

    peer = Peer(fresh_domain_id(), "test_params")
    pubs = {t: peer.node.create_publisher(String, t, 10) for t in ("/a", "/b")}
    bag, log = tmp_path / "rec.mcap", tmp_path / "rec.log"
    subscribed = lambda t: lambda: peer.node.count_subscribers(t) > 0  # noqa: E731
    try:
        with node_process("recorder", {"output": str(bag), "topics": ["/a"], "discovery_period_s": 0.1},
                          peer.ctx.get_domain_id(), log) as rec:
            assert peer.spin(subscribed("/a"), 30), log.read_text()
            assert not peer.spin(subscribed("/b"), 0.5)
            assert not set_parameter(peer, "/recorder", "output", str(tmp_path / "other.mcap")).successful
            assert set_parameter(peer, "/recorder", "topics", ["/a", "/b"]).successful
            assert peer.spin(subscribed("/b"), 10), log.read_text()
            for k in range(3):
                pubs["/a"].publish(String(data=f"a {k}"))
                pubs["/b"].publish(String(data=f"b {k}"))
                peer.spin(lambda: False, 0.05)
            assert set_parameter(peer, "/recorder", "topics", ["/b"]).successful
            assert peer.spin(lambda: not subscribed("/a")(), 10), log.read_text()
            pubs["/b"].publish(String(data="b 3"))
            peer.spin(lambda: False, 0.5)
            rec.send_signal(signal.SIGINT)
            assert rec.wait(timeout=30) == 0, log.read_text()
        with AnyReader([bag]) as r:
            msgs = [(c.topic, r.deserialize(raw, c.msgtype).data) for c, _, raw in r.messages()]
        assert [d for t, d in msgs if t == "/a"] == [f"a {k}" for k in range(3)]
        assert [d for t, d in msgs if t == "/b"] == [f"b {k}" for k in range(4)]
    finally:
        peer.close()


_SHUTDOWN_BEFORE_THE_WAIT = """
import sys
import rclpy
from rclpy.executors import SingleThreadedExecutor
from zebra_sim_ros.nodes import recorder
real, calls = SingleThreadedExecutor.spin_once, []
def spin_once(self, timeout_sec=None):
    calls.append(1)
    if len(calls) == 5:  # as rclpy's SIGINT handler can: after the loop's rclpy.ok(), before the wait set is built
        rclpy.shutdown()
    real(self, timeout_sec=timeout_sec)
SingleThreadedExecutor.spin_once = spin_once
sys.exit(recorder.main(["recorder", "--ros-args", "-p", f"output:={sys.argv[1]}", "-p", "topics:=['/a']"]))
"""


@pytest.mark.integration
def test_a_shutdown_between_the_check_and_the_wait_ends_the_node_cleanly(tmp_path: Path) -> None:
    """The race a Ctrl-C can hit: rclpy's signal handler shuts the context down after the spin loop's
    ``rclpy.ok()`` and before ``spin_once`` builds its wait set, which then raises. The node stops as on any
    Ctrl-C: exit status 0 and a finalised bag (read back by rosbags), not a traceback."""
    import subprocess
    import sys

    from ros_helpers import fresh_domain_id, ros_env
    from rosbags.highlevel import AnyReader

    bag = tmp_path / "rec.mcap"
    proc = subprocess.run([sys.executable, "-c", _SHUTDOWN_BEFORE_THE_WAIT, str(bag)], env=ros_env(fresh_domain_id()),
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "Traceback" not in proc.stderr and "finalised in" in proc.stdout, proc.stdout + proc.stderr
    with AnyReader([bag]) as reader:  # a complete MCAP file: summary and footer written
        assert [c.topic for c in reader.connections] in ([], ["/a"])
