"""The whole-graph description, the launch file that mirrors it, and the process supervisor (no DDS here)."""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import textwrap
import time
import types
from pathlib import Path
from typing import Any

import pytest
import yaml

from zebra_sim_ros.cli.up import _graph_environment
from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.graph.spec import (
    BAG_RAW_IMAGES,
    DDS_PROFILE,
    DRONES,
    NODE_ENVIRONMENT,
    NODE_PARAMS,
    NodeSpec,
    UpConfig,
    command,
    config_dir,
    dds_environment,
    graph_cameras,
    graph_spec,
    ros_value,
)
from zebra_sim_ros.graph.supervisor import NodeDied, Supervisor
from zebra_sim_ros.params import ROS_BUILTIN_PARAMS, load_params_file, validate

REPO = Path(__file__).resolve().parents[1]
SPECS = NODE_PARAMS


@pytest.mark.parametrize("executable", sorted(SPECS))
def test_config_file_holds_every_parameter_at_its_default(executable: str) -> None:
    values = load_params_file(str(REPO / "config" / f"{executable}.yaml"), executable)
    assert values == {s.name: s.default for s in SPECS[executable]}


def test_config_classes_default_as_their_parameter_specs() -> None:
    """Each node's defaults are written twice (ParamSpec for ROS, the dataclass for the core): they must agree."""
    from zebra_sim_ros.detection.config import DetectorConfig
    from zebra_sim_ros.labels.config import LabelFilters, LabellerConfig
    from zebra_sim_ros.placement.config import PlacerConfig
    from zebra_sim_ros.rendering.config import CameraConfig

    for cls in (CameraConfig, DetectorConfig, LabellerConfig, PlacerConfig):
        assert cls.from_params({}) == cls(), cls.__name__
    assert LabellerConfig().filters() == LabelFilters()


def test_graph_overrides_are_declared_parameters_with_allowed_values(tmp_path: Path) -> None:
    specs = graph_spec(UpConfig(out=str(tmp_path), weights=str(tmp_path / "w.pt")))
    assert [s.executable for s in specs] == ["camera"] * 3 + ["labeller", "detector", "scorer", "recorder", "placer"]
    # before the first step the scorer subscribes what it scores, the recorder every topic up to it
    readers = {s.executable: s.subscribes for s in specs if s.subscribes}
    assert set(readers) == {"scorer", "recorder"}
    assert set(readers["scorer"]) == {f"/{d}/{t}" for d in DRONES for t in ("labels", "detections")}
    assert set(readers["recorder"]) == {t for s in specs[:5] for t in s.publishes} > set(readers["scorer"])
    for s in specs:
        known = {p.name for p in SPECS[s.executable]} | set(ROS_BUILTIN_PARAMS)
        assert set(s.overrides) <= known, (s.label, set(s.overrides) - known)
        # the placer is the clock; every other node runs on its simulated time
        assert s.overrides.get("use_sim_time", False) is (s.executable != "placer"), s.label
        validate(SPECS[s.executable], s.overrides)  # raises naming a bad value
        assert (config_dir() / s.params_file).is_file()
    assert len({s.fqn for s in specs}) == len(specs)
    placer = specs[-1].overrides
    assert placer["mode"] == "lockstep" and placer["wait_for_subscribers"] == 1
    assert set(placer["lockstep_ack_from"]) == {specs[3].overrides["ack_name"], specs[4].overrides["ack_name"]}
    assert not any(s.executable == "recorder" for s in graph_spec(UpConfig(record=False)))
    for n in (1, 16):  # --drones: that many cameras, every override still allowed by its node
        specs = graph_spec(UpConfig(drones=n))
        assert [s.name for s in specs if s.executable == "camera"] == [f"drone_{i}_camera" for i in range(n)]
        for s in specs:
            validate(SPECS[s.executable], s.overrides)
    for bad in (0, 17):
        with pytest.raises(ParameterError, match=f"'--drones' = {bad} is invalid: allowed 1..16"):
            UpConfig(drones=bad).check()


def test_a_namespace_moves_every_topic_and_the_global_ones_are_remapped() -> None:
    root = graph_spec(UpConfig())
    g1 = graph_spec(UpConfig(namespace="/g1"))
    assert all(s.namespace == "" and not s.remaps for s in root)
    assert all(s.namespace == "/g1" for s in g1)
    assert all(dict(s.remaps) == {"/tf": "/g1/tf", "/tf_static": "/g1/tf_static", "/clock": "/g1/clock"} for s in g1)
    for a, b in zip(root, g1, strict=True):
        assert b.publishes == tuple("/g1" + t for t in a.publishes), b.label
        assert b.subscribes == tuple("/g1" + t for t in a.subscribes), b.label
        assert all(t.startswith("/") for t in a.publishes)
    assert "/tf" in root[-1].publishes and "/clock" in root[-1].publishes
    cmd = command(g1[0], Path("cfg"))
    assert cmd[cmd.index("-r", 6) + 1] == "__ns:=/g1" and "/tf:=/g1/tf" in cmd and "/clock:=/g1/clock" in cmd
    for bad in ("g1", "/1g", "/g 1", "/g1/"):
        with pytest.raises(ParameterError, match="--namespace"):
            UpConfig(namespace=bad).check()


def test_command_line_passes_names_files_and_overrides() -> None:
    spec = NodeSpec("camera", "camera", "/drone_1", "camera.yaml", {"drone_index": 1, "ack": False, "name": "a b"})
    args = command(spec, Path("/cfg"), python="py")
    assert args[:3] == ["py", "-m", "zebra_sim_ros.nodes.camera"]
    assert args[3:] == ["--ros-args", "-r", "__node:=camera", "-r", "__ns:=/drone_1", "--params-file",
                        "/cfg/camera.yaml", "-p", "drone_index:=1", "-p", "ack:=false", "-p", "name:='a b'"]
    assert ros_value(["labeller", "detector"]) == "['labeller', 'detector']"
    assert ros_value("") == "''" and ros_value("yes") == "'yes'" and ros_value("-1") == "'-1'"
    assert ros_value("it's") == "'it''s'" and ros_value(2.5) == "2.5" and ros_value(True) == "true"


def test_config_dir_errors_name_the_folder(tmp_path: Path) -> None:
    from zebra_sim_ros.errors import ParameterError

    with pytest.raises(ParameterError, match=str(tmp_path)):
        config_dir(str(tmp_path))
    assert config_dir(str(REPO / "config")) == REPO / "config"


# -- the launch file is a mirror of `up` ---------------------------------------------------------------
class _Recorder:
    """Stand-ins for the launch API that record what the launch file builds (launch is not installable here)."""

    def __init__(self) -> None:
        self.nodes: list[dict[str, Any]] = []
        self.args: dict[str, str] = {}
        self.env: dict[str, str] = {}
        self.functions: list[Any] = []  # OpaqueFunction's, called with the arguments' values (launch_configurations)
        self.returned: list[Any] = []  # the actions they return, in order
        self.logs: list[str] = []  # LogInfo's messages

    def modules(self, share: Path) -> dict[str, types.ModuleType]:
        rec = self

        class Node:
            def __init__(self, **kw: Any) -> None:
                rec.nodes.append(kw)

        class DeclareLaunchArgument:
            def __init__(self, name: str, default_value: str = "", description: str = "") -> None:
                rec.args[name] = default_value

        class SetEnvironmentVariable:
            def __init__(self, name: str, value: str) -> None:
                rec.env[name] = value

        class LaunchConfiguration:
            def __init__(self, name: str) -> None:
                self.name = name

            def perform(self, context: Any) -> str:
                return str(context.launch_configurations[self.name])

        class OpaqueFunction:
            def __init__(self, function: Any) -> None:
                rec.functions.append(function)

        class LogInfo:
            def __init__(self, msg: str) -> None:
                rec.logs.append(msg)

        class IfCondition:
            def __init__(self, predicate: Any) -> None:
                self.predicate = predicate

        def evaluate_condition_expression(context: Any, expression: list[Any]) -> bool:
            """launch's rule: true or 1, false or 0, any case, spaces around ignored; anything else refused."""
            text = "".join(e.perform(context) for e in expression).strip().lower()
            if text not in ("true", "1", "false", "0"):
                raise ValueError(f"invalid condition expression {text!r}: want true, 1, false or 0")
            return text in ("true", "1")

        class ParameterValue:
            def __init__(self, value: Any, value_type: type = str) -> None:
                self.value, self.value_type = value, value_type

        mods = {}
        for name, attrs in {
            "launch": {"LaunchDescription": lambda items: items},
            "launch.actions": {"DeclareLaunchArgument": DeclareLaunchArgument, "OpaqueFunction": OpaqueFunction,
                               "SetEnvironmentVariable": SetEnvironmentVariable, "LogInfo": LogInfo},
            "launch.substitutions": {"LaunchConfiguration": LaunchConfiguration},
            "launch.conditions": {"IfCondition": IfCondition,
                                  "evaluate_condition_expression": evaluate_condition_expression},
            "launch_ros": {}, "launch_ros.actions": {"Node": Node},
            "launch_ros.parameter_descriptions": {"ParameterValue": ParameterValue},
            "ament_index_python": {},
            "ament_index_python.packages": {"get_package_share_directory": lambda p: str(share)},
        }.items():
            m = types.ModuleType(name)
            m.__dict__.update(attrs)
            mods[name] = m
        return mods


def _launch(monkeypatch: pytest.MonkeyPatch, share: Path, **arguments: str) -> _Recorder:
    """What the launch file builds in this environment, its package's share folder ``share``, with these launch
    arguments (``name:=value``; the others at their defaults)."""
    rec = _Recorder()
    for name, mod in rec.modules(share).items():
        monkeypatch.setitem(sys.modules, name, mod)
    ns: dict[str, Any] = {}
    exec(compile((REPO / "launch" / "zebra_sim.launch.py").read_text(), "zebra_sim.launch.py", "exec"), ns)
    ns["generate_launch_description"]()
    context = types.SimpleNamespace(launch_configurations={**rec.args, **arguments})
    for function in rec.functions:
        rec.returned += function(context) or []
    return rec


def test_launch_file_reads_the_config_folder_it_is_given(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """``config:=DIR`` as ``up --config DIR``: every node's parameter file, the cameras' settings the placer aims
    with, the recorder's exclusions and the Fast DDS profile from that folder; one without placer.yaml refused by
    name."""
    for var in ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE"):
        monkeypatch.delenv(var, raising=False)
    (tmp_path / "share" / "config").mkdir(parents=True)
    shutil.copy(REPO / "config" / "camera.yaml", tmp_path / "share" / "config")
    mine = tmp_path / "mine"
    shutil.copytree(REPO / "config", mine)
    camera = (mine / "camera.yaml").read_text()
    assert camera.count("hfov_deg: 80.0") == 1
    (mine / "camera.yaml").write_text(camera.replace("hfov_deg: 80.0", "hfov_deg: 50.0"))
    (mine / "recorder.yaml").write_text("/**:\n  ros__parameters:\n    exclude_regex: /mine$\n")
    rec = _launch(monkeypatch, tmp_path / "share", config=str(mine), bag_images="jpeg")
    assert {Path(n["parameters"][0]).parent for n in rec.nodes} == {mine}
    assert rec.env["FASTRTPS_DEFAULT_PROFILES_FILE"] == str(mine / DDS_PROFILE)
    kinds = [type(a).__name__ for a in rec.returned]  # launch runs them in order: the profile before every node
    assert "SetEnvironmentVariable" in kinds and kinds.index("Node") > max(
        k for k, kind in enumerate(kinds) if kind == "SetEnvironmentVariable")
    (placer,) = [n["parameters"][1] for n in rec.nodes if n["executable"] == "placer"]
    assert placer["camera_hfov_deg"] == pytest.approx(50.0)  # aimed with this folder's cameras
    (recorder,) = [n["parameters"][1] for n in rec.nodes if n["executable"] == "recorder"]
    assert recorder["exclude_regex"] == f"(?:/mine$)|{BAG_RAW_IMAGES}"
    default = _launch(monkeypatch, tmp_path / "share")
    (placer,) = [n["parameters"][1] for n in default.nodes if n["executable"] == "placer"]
    assert placer["camera_hfov_deg"] == pytest.approx(80.0)  # the package's cameras without config:=
    (mine / "placer.yaml").unlink()
    with pytest.raises(ParameterError, match=f"'config'.*{re.escape(str(mine))}.*placer.yaml"):
        _launch(monkeypatch, tmp_path / "share", config=str(mine))


def _locator_yaml(**changes: str) -> str:
    """The package's locator.yaml with each named parameter's value changed (each must be in it once)."""
    text = (REPO / "config" / "locator.yaml").read_text()
    for key, value in changes.items():
        text, n = re.subn(rf"^(    {key}:) \S+", rf"\1 {value}", text, flags=re.M)
        assert n == 1, key
    return text


def test_launch_file_starts_what_up_starts(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    for var in ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE", *NODE_ENVIRONMENT):
        monkeypatch.delenv(var, raising=False)
    (tmp_path / "share" / "config").mkdir(parents=True)  # the cameras' file: the placer aims with their lens
    shutil.copy(REPO / "config" / "camera.yaml", tmp_path / "share" / "config")
    rec = _launch(monkeypatch, tmp_path / "share")
    up = graph_spec(UpConfig(locate=True))  # the launch file holds the nodes that its arguments may leave out
    launched = [(n["executable"], n["name"], "/" + n["namespace"] if n["namespace"] else "",
                 Path(n["parameters"][0]).name, Path(n["parameters"][0]).parent, set(n["parameters"][1]))
                for n in rec.nodes]
    assert [n["package"] for n in rec.nodes] == ["zebra_sim_ros"] * len(up)
    assert [x[:4] for x in launched] == [(s.executable, s.name, s.namespace, s.params_file) for s in up]
    assert {x[4] for x in launched} == {tmp_path / "share" / "config"}
    assert [x[5] for x in launched] == [set(s.overrides) for s in up]
    # Constant overrides are equal; those from launch arguments default to up's defaults.
    for n, s in zip(rec.nodes, up, strict=True):
        for k, v in n["parameters"][1].items():
            if hasattr(v, "value"):
                default = v.value_type(rec.args[v.value.name]) if rec.args[v.value.name] else ""
                if k not in ("weights", "output"):
                    assert default == s.overrides[k], (s.label, k)
            else:
                assert v == s.overrides[k], (s.label, k)
    assert int(rec.args["frames"]) == UpConfig().frames and rec.args["world"] == UpConfig().world
    # drones:=N as up --drones N: N cameras, and the labeller, detector, scorer and placer told of them
    five = _launch(monkeypatch, tmp_path / "share", drones="5")
    up5 = graph_spec(UpConfig(drones=5, locate=True))
    assert [(n["executable"], n["name"]) for n in five.nodes] == [(s.executable, s.name) for s in up5]
    for n, s in zip(five.nodes, up5, strict=True):
        for k in ("drones", "image_topics", "num_cameras", "drone_index"):
            assert n["parameters"][1].get(k) == s.overrides.get(k), (s.label, k)
    by = {s.executable: s.overrides for s in up5}
    assert by["placer"]["num_cameras"] == 5 and by["detector"]["image_topics"][-1] == "drone_4/image_raw"
    assert by["labeller"]["drones"] == by["scorer"]["drones"] == by["locator"]["drones"] == [
        f"drone_{i}" for i in range(5)]
    with pytest.raises(ValueError, match="'drones' = 0 is invalid: allowed 1..16"):
        _launch(monkeypatch, tmp_path / "share", drones="0")
    with pytest.raises(ValueError, match="'drones' = 'two' is invalid: allowed a number of cameras"):
        _launch(monkeypatch, tmp_path / "share", drones="two")
    # bag_images:=jpeg as up --bag-images jpeg: the cameras publish image_raw/compressed, the recorder keeps that
    jpeg = _launch(monkeypatch, tmp_path / "share", bag_images="jpeg")
    for n, s in zip(jpeg.nodes, graph_spec(UpConfig(bag_images="jpeg", locate=True)), strict=True):
        for k in ("compressed", "exclude_regex"):
            assert n["parameters"][1].get(k) == s.overrides.get(k), (s.label, k)
    recorder = next(s for s in graph_spec(UpConfig(bag_images="jpeg")) if s.executable == "recorder")
    rec_jpeg = recorder.overrides
    # up waits for the recorder to subscribe what it records: the compressed images, not the raw ones
    assert {f"/{d}/image_raw/compressed" for d in DRONES} <= set(recorder.subscribes)
    assert not {t for t in recorder.subscribes if t.endswith(("/image_raw", "/detections/image"))}
    for topic in ("/drone_0/image_raw", "/g1/drone_12/image_raw", "/drone_0/detections/image", "/rosout"):
        assert re.search(rec_jpeg["exclude_regex"], topic), topic
    for topic in ("/drone_0/image_raw/compressed", "/my_cam/image_raw", "/drone_0/depth", "/drone_0/detections"):
        assert not re.search(rec_jpeg["exclude_regex"], topic), topic
    # raw (the default): the parameter files decide, up overrides neither
    raw = {s.executable: s.overrides for s in graph_spec(UpConfig())}
    assert "compressed" not in raw["camera"] and "exclude_regex" not in raw["recorder"]
    with pytest.raises(ValueError, match="'bag_images' = 'gif' is invalid: allowed one of raw, jpeg, png"):
        _launch(monkeypatch, tmp_path / "share", bag_images="gif")
    # rviz:=true adds RViz on the package's view drawn for the drones (here five), written beside the bag; nothing
    # else changes
    assert not [n for n in rec.nodes if n["package"] == "rviz2"] and rec.args["rviz"] == "false"
    bag = tmp_path / "run" / "zebra_sim.mcap"
    with pytest.raises(ValueError, match=f"no zebra_sim.rviz in {tmp_path / 'share' / 'config'}"):
        _launch(monkeypatch, tmp_path / "share", rviz="true", bag=str(bag))
    assert not bag.parent.exists()  # refused before anything is written
    shutil.copy(REPO / "config" / "zebra_sim.rviz", tmp_path / "share" / "config")
    for flag in ("true", "1", " True"):  # launch's own spellings of true, as score:= takes them
        viewed = _launch(monkeypatch, tmp_path / "share", rviz=flag, drones="5", bag=str(bag))
        (viewer,) = [n for n in viewed.nodes if n["package"] == "rviz2"]
        assert [(n["executable"], n["name"]) for n in viewed.nodes if n is not viewer] == [
            (s.executable, s.name) for s in up5]
        assert viewer["arguments"] == ["-d", str(bag.parent / "zebra_sim.rviz")]
        assert viewer["parameters"] == [{"use_sim_time": True}]
    view = yaml.safe_load((bag.parent / "zebra_sim.rviz").read_text())["Visualization Manager"]["Displays"]
    assert [t for d in view if (t := d.get("Topic", {}).get("Value", "")).endswith("/detections/image")] == [
        f"/drone_{i}/detections/image" for i in range(5)]
    census = [d for d in view if "census" in d["Name"]]
    assert [(d["Topic"]["Value"], d["Enabled"]) for d in census] == [("/census/animals/markers", False)]  # no locator
    # locate:=true: the census display on the census the locator's file names (its census_output), as up draws it
    (tmp_path / "share" / "config" / "locator.yaml").write_text(_locator_yaml(census_output="herd/count"))
    _launch(monkeypatch, tmp_path / "share", rviz="true", locate="true", bag=str(bag))
    view = yaml.safe_load((bag.parent / "zebra_sim.rviz").read_text())["Visualization Manager"]["Displays"]
    assert [(d["Topic"]["Value"], d["Enabled"]) for d in view if "census" in d["Name"]] == [
        ("/herd/count/markers", True)]
    assert not [n for n in _launch(monkeypatch, tmp_path / "share", rviz="0").nodes if n["package"] == "rviz2"]
    # cameras whose file has them publish points: RViz shows each camera's cloud, and the placer aims through the
    # file's lens
    (tmp_path / "share" / "config" / "camera.yaml").write_text(
        (REPO / "config" / "camera.yaml").read_text().replace("points_stride: 0", "points_stride: 4")
        .replace("lens_k1: 0.0", "lens_k1: -0.1"))
    lensed = _launch(monkeypatch, tmp_path / "share", rviz="true", bag=str(bag))
    view = yaml.safe_load((bag.parent / "zebra_sim.rviz").read_text())["Visualization Manager"]["Displays"]
    assert [d["Topic"]["Value"] for d in view if d["Class"] == "rviz_default_plugins/PointCloud2"] == [
        f"/drone_{i}/points" for i in range(3)]
    (placer_node,) = [n for n in lensed.nodes if n["executable"] == "placer"]
    assert placer_node["parameters"][1]["camera_lens_k1"] == pytest.approx(-0.1) and not lensed.logs
    # a camera whose own section gives it another lens: the placer still aims with drone_0's, and says so
    with open(tmp_path / "share" / "config" / "camera.yaml", "a") as f:
        f.write("/drone_2_camera:\n  ros__parameters:\n    lens_k1: -0.05\n")
    assert [m for m in _launch(monkeypatch, tmp_path / "share").logs if "/drone_2 differ from /drone_0" in m]
    shutil.copy(REPO / "config" / "camera.yaml", tmp_path / "share" / "config")
    with pytest.raises(ValueError, match="'maybe'"):
        _launch(monkeypatch, tmp_path / "share", rviz="maybe")
    # in a namespace (PushRosNamespace around the file), the recorder's own section of its file is read
    (tmp_path / "share" / "config" / "recorder.yaml").write_text(
        "/**:\n  ros__parameters:\n    exclude_regex: /rosout$\n"
        "/g1/recorder:\n  ros__parameters:\n    exclude_regex: /depth$\n")
    for ns, base in (("/g1", "/depth$"), ("", "/rosout$"), ("/g2", "/rosout$")):
        moved = _launch(monkeypatch, tmp_path / "share", bag_images="jpeg", **({"ros_namespace": ns} if ns else {}))
        (recorder_node,) = [n for n in moved.nodes if n["executable"] == "recorder"]
        assert recorder_node["parameters"][1]["exclude_regex"] == f"(?:{base})|{BAG_RAW_IMAGES}", ns
    with pytest.raises(ParameterError, match="--bag-images"):
        UpConfig(bag_images="gif").check()
    # the locator and the scorer, and only they, may be left out: locate:=true as up --locate (off by default in
    # both), score:=false as up --no-score (on by default in both)
    conditional = [(n["executable"], n["condition"].predicate.name) for n in rec.nodes if "condition" in n]
    assert conditional == [("locator", "locate"), ("scorer", "score")]
    assert rec.args["score"] == "true" and UpConfig().score and rec.args["locate"] == "false" and not UpConfig().locate
    assert [s.executable for s in graph_spec(UpConfig(score=False, locate=True))] == [s.executable for s in up
                                                                                       if s.executable != "scorer"]
    assert [s.executable for s in graph_spec(UpConfig())] == [s.executable for s in up if s.executable != "locator"]
    share = tmp_path / "share" / "config"
    assert rec.env == NODE_ENVIRONMENT  # no fastdds.xml in this share folder: as up, no profile named
    assert NODE_ENVIRONMENT == {"OMP_WAIT_POLICY": "PASSIVE"}
    # up gives its nodes the same, but what the caller set (its profile is set here, in this process, as up sets it)
    monkeypatch.setenv("FASTRTPS_DEFAULT_PROFILES_FILE", str(REPO / "config" / DDS_PROFILE))
    assert _graph_environment(REPO / "config", None)["OMP_WAIT_POLICY"] == "PASSIVE"
    monkeypatch.setenv("OMP_WAIT_POLICY", "ACTIVE")
    assert _graph_environment(REPO / "config", None)["OMP_WAIT_POLICY"] == "ACTIVE"
    assert _launch(monkeypatch, tmp_path / "share").env == {}  # the caller's kept there too, its profile as well
    monkeypatch.delenv("FASTRTPS_DEFAULT_PROFILES_FILE")
    assert dds_environment(share, {}) == {}  # no such file there: up leaves the environment alone
    shutil.copy(REPO / "config" / DDS_PROFILE, share)  # with one, both name it
    assert _launch(monkeypatch, tmp_path / "share").env == {"FASTRTPS_DEFAULT_PROFILES_FILE": str(share / DDS_PROFILE)}
    ours = str(REPO / "config" / DDS_PROFILE)
    assert dds_environment(REPO / "config", {}) == {"FASTRTPS_DEFAULT_PROFILES_FILE": ours}
    assert dds_environment(REPO / "config", {"FASTDDS_DEFAULT_PROFILES_FILE": "mine.xml"}) == \
        {"FASTDDS_DEFAULT_PROFILES_FILE": "mine.xml"}  # the user's own profile wins


# -- the supervisor --------------------------------------------------------------------------------------
def _spec(label: str) -> NodeSpec:
    return NodeSpec("x", label, "", "x.yaml")


def _py(code: str) -> list[str]:
    return [sys.executable, "-c", textwrap.dedent(code)]


def test_supervisor_names_the_node_that_died_and_stops_the_rest(tmp_path: Path) -> None:
    with Supervisor(tmp_path, dict(os.environ)) as sup:
        alive = sup.start(_spec("alive"), _py("import time; time.sleep(60)"))
        sup.start(_spec("dies"), _py("import sys; print('weights are broken', flush=True); sys.exit(3)"))
        end = time.monotonic() + 20
        with pytest.raises(NodeDied) as err:
            while time.monotonic() < end:
                sup.check()
                time.sleep(0.05)
        assert err.value.child.label == "dies" and err.value.code == 3
        assert "exit status 3" in str(err.value) and "weights are broken" in str(err.value)
        codes = sup.stop()
    assert codes["dies"] == 3 and codes["alive"] == -signal.SIGINT  # python's default SIGINT: KeyboardInterrupt
    assert alive.proc.poll() is not None


def test_supervisor_escalates_to_sigterm_and_sigkill(tmp_path: Path) -> None:
    with Supervisor(tmp_path, dict(os.environ)) as sup:
        stubborn = sup.start(_spec("stubborn"), _py("""
            import signal, time
            signal.signal(signal.SIGINT, signal.SIG_IGN)
            signal.signal(signal.SIGTERM, signal.SIG_IGN)
            print('ready', flush=True)
            time.sleep(60)"""))
        end = time.monotonic() + 20
        while "ready" not in stubborn.log_tail() and time.monotonic() < end:
            time.sleep(0.05)
        t0 = time.monotonic()
        codes = sup.stop(grace_s=0.5, kill_after_s=0.5)
    assert codes["stubborn"] == -signal.SIGKILL
    assert time.monotonic() - t0 < 10


@pytest.mark.parametrize("bad", [{"kill_after_s": -1.0}, {"grace_s": float("nan")}, {"kill_after_s": float("inf")}])
def test_supervisor_stop_refuses_a_bad_wait_and_stops_nothing(tmp_path: Path, bad: dict[str, float]) -> None:
    with Supervisor(tmp_path, dict(os.environ)) as sup:
        child = sup.start(_spec("sleeper"), _py("""
            import time
            time.sleep(60)"""))
        with pytest.raises(ValueError, match=next(iter(bad))):
            sup.stop(**bad)
        assert child.proc.poll() is None
    assert child.proc.poll() is not None


def test_nodes_die_with_a_supervisor_killed_outright(tmp_path: Path) -> None:
    script = f"""
        import os, sys, time
        from pathlib import Path
        from zebra_sim_ros.graph.spec import NodeSpec
        from zebra_sim_ros.graph.supervisor import Supervisor
        sup = Supervisor(Path({str(tmp_path)!r}), dict(os.environ))
        c = sup.start(NodeSpec("x", "child", "", "x.yaml"), [sys.executable, "-c", "import time; time.sleep(120)"])
        print(c.proc.pid, flush=True)
        time.sleep(120)
    """
    parent = subprocess.Popen(_py(script), stdout=subprocess.PIPE, text=True)
    try:
        assert parent.stdout is not None
        pid = int(parent.stdout.readline())
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait(timeout=10)
        end = time.monotonic() + 10
        while time.monotonic() < end and Path(f"/proc/{pid}").exists() and \
                Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z":
            time.sleep(0.05)
        gone = not Path(f"/proc/{pid}").exists() or Path(f"/proc/{pid}/stat").read_text().split()[2] == "Z"
        assert gone, "the node outlived its supervisor"
    finally:
        if parent.poll() is None:
            parent.kill()


# -- the README documents what the code does -------------------------------------------------------------
def test_readme_parameter_tables_equal_the_specs() -> None:
    from zebra_sim_ros.params import markdown_table

    readme = (REPO / "README.md").read_text()
    for executable, specs in SPECS.items():
        assert markdown_table(specs) + "\n" in readme, f"README's {executable} table differs from its ParamSpecs"


def test_tables_of_nodes_with_the_same_first_parameter_are_found_in_their_own_sections() -> None:
    """The labeller's and the scorer's tables both start with `drones`: each is found after its node's heading, and
    two nodes that would find one table are refused, naming the node."""
    from zebra_sim_ros.errors import ParameterError
    from zebra_sim_ros.params import markdown_table, replace_tables

    stub = "| parameter | default | meaning (unit) | allowed |\n| --- | --- | --- | --- |\n| `drones` | x | x | x |\n"
    text = f"### The `labeller` node\n\n{stub}\n### The `scorer` node\n\n{stub}\nend\n"
    out = replace_tables(text, {"scorer": SPECS["scorer"], "labeller": SPECS["labeller"]})
    labeller_part, scorer_part = out.split("### The `scorer` node")
    assert markdown_table(SPECS["labeller"]) in labeller_part and markdown_table(SPECS["scorer"]) in scorer_part
    with pytest.raises(ParameterError, match="'README table' = 'scorer'.*labeller found the same one; give "
                                             "labeller and scorer a section"):
        replace_tables(f"{stub}\n", {"labeller": SPECS["labeller"], "scorer": SPECS["scorer"]})


def test_readme_names_the_other_species_the_asset_bakes_wherever_it_lists_them() -> None:
    """The README lists the other species in prose, a parameter table and the dataset layout: every list that starts
    with the asset's first one (a run of species names, wrapped or not; shorter runs such as the real photos'
    "buffalo, elephant, rhino" are not the generator's list) names them all, in the asset's order, so a species
    added or dropped in code shows up here as a failing list."""
    from zebra_sim_ros.zebra.skeleton import OTHER_SPECIES

    readme = " ".join((REPO / "README.md").read_text().split())  # lines unwrapped, code-block margins gone
    name = "|".join(OTHER_SPECIES)
    lists = [re.findall(r"[a-z]+", m.group(0))
             for m in re.finditer(rf"'?\b{OTHER_SPECIES[0]}\b'?(?:(?:,\s*)'?\b(?:{name})\b'?)+", readme)]
    assert len(lists) >= 6, lists
    for found in lists:
        assert found == list(OTHER_SPECIES), found


def test_readme_starts_with_the_two_commands_and_lists_every_topic_of_the_graph() -> None:
    readme = (REPO / "README.md").read_text()
    first_block = readme.split("```bash\n", 1)[1].split("```", 1)[0].splitlines()
    assert [line.split("#")[0].strip() for line in first_block] == ["bash scripts/main.sh", "bash scripts/test.sh"]
    assert "scripts/test.sh" in (REPO / ".ci" / "run").read_text()
    topics = {re.sub(r"drone_\d+", "drone_{i}", t) for s in graph_spec(UpConfig()) for t in s.publishes}
    for t in sorted(topics | {"/zebra_sim/frame_done", "/clock", "/diagnostics"}):
        assert f"| `{t}` |" in readme, t


def test_fast_dds_accepts_our_profile(tmp_path: Path) -> None:
    """Fast DDS ignores a profile it cannot parse (with an XMLPARSER error on stderr) and runs with defaults."""
    code = ("import rclpy; from std_msgs.msg import String; rclpy.init(); n = rclpy.create_node('profile_check'); "
            "n.create_publisher(String, '/profile_check', 10); print('created', flush=True)")
    broken = tmp_path / "broken.xml"
    broken.write_text("<profiles><data_writer")
    outputs = {}
    for name, path in (("ours", REPO / "config" / DDS_PROFILE), ("broken", broken)):
        env = dict(os.environ, FASTRTPS_DEFAULT_PROFILES_FILE=str(path), ROS_DOMAIN_ID="231",
                   ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
        env.pop("FASTDDS_DEFAULT_PROFILES_FILE", None)
        run = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=60)
        outputs[name] = run.stdout + run.stderr
    assert "created" in outputs["ours"] and "XMLPARSER" not in outputs["ours"], outputs["ours"]
    assert "XMLPARSER" in outputs["broken"]


@pytest.mark.parametrize(("setting", "named"), [({"world": "moon"}, "'world'"), ({"device": "tpu"}, "'device'"),
                                                ({"frames": 0}, "'--frames'"), ({"strategy": "up"}, "'--strategy'"),
                                                ({"width": 8, "height": 20}, "'--size'"),
                                                ({"detect_scale": 0.1}, "'--detect-scale'"),
                                                ({"detect_scale": -1.3}, "'--detect-scale'"),
                                                ({"verifier": "/no/such/verifier.pt"}, "'--verifier'"),
                                                ({"detect_amp": "half"}, "'amp'")])
def test_up_rejects_a_bad_setting_before_starting_any_node(setting: dict[str, Any], named: str) -> None:
    from zebra_sim_ros.errors import ParameterError

    with pytest.raises(ParameterError, match=named):
        UpConfig(**setting).check()


def test_up_passes_the_verifier_to_the_detector(tmp_path: Path) -> None:
    def detector(cfg: UpConfig) -> dict[str, Any]:
        return next(s for s in graph_spec(cfg) if s.executable == "detector").overrides

    assert detector(UpConfig())["verifier"] == "" and detector(UpConfig(verifier="shipped"))["verifier"] == "shipped"
    assert detector(UpConfig())["amp"] == "off" and detector(UpConfig(detect_amp="bf16"))["amp"] == "bf16"
    (tmp_path / "v.pt").write_bytes(b"")
    cfg = UpConfig(verifier=str(tmp_path / "v.pt"))
    cfg.check()
    assert detector(cfg)["verifier"] == str((tmp_path / "v.pt").resolve())


def test_up_detector_size_follows_the_cameras() -> None:
    detector = next(s for s in graph_spec(UpConfig(detect_scale=1.5)) if s.executable == "detector")
    assert detector.overrides["scale"] == 1.5 and "imgsz" not in detector.overrides
    default = next(s for s in graph_spec(UpConfig()) if s.executable == "detector")
    assert default.overrides["scale"] == 0  # by default the node applies the checkpoint's rule, as val does
    assert UpConfig().detect_imgsz == 2176  # the shipped weights serve 640 px frames at 1088: 1.7 x 1280
    assert UpConfig(width=640, height=360).detect_imgsz == 1088
    assert UpConfig(detect_scale=1.3).detect_imgsz == 1664
    assert UpConfig(detect_scale=1.0).detect_imgsz == 1280  # native
    assert UpConfig(width=360, height=640, detect_scale=1.0).detect_imgsz == 640  # the long side, portrait too
    assert UpConfig(width=1000, height=500, detect_scale=1.0).detect_imgsz == 1024  # up to a multiple of 32
    assert UpConfig(width=4000, height=3000, detect_scale=2.0).detect_imgsz == 4096  # within the model's range
    assert UpConfig(width=32, height=16, detect_scale=0.25).detect_imgsz == 64


def test_the_rviz_config_shows_topics_the_graph_publishes_in_its_fixed_frame() -> None:
    """config/zebra_sim.rviz (installed with the package): every display's topic is one the graph publishes (with
    ``--locate``: the census), with the QoS its publisher offers, and the fixed frame is the placer's ``map``."""
    import yaml

    from zebra_sim_ros.graph.spec import GLOBAL_TOPICS

    rviz = yaml.safe_load((REPO / "config" / "zebra_sim.rviz").read_text())
    manager = rviz["Visualization Manager"]
    assert manager["Global Options"]["Fixed Frame"] == "map"
    published = {t for s in graph_spec(UpConfig(locate=True)) for t in s.publishes} | set(GLOBAL_TOPICS)
    topics = {d["Topic"]["Value"]: d["Topic"] for d in manager["Displays"] if "Topic" in d}
    assert len(topics) >= 5 and set(topics) <= published, sorted(set(topics) - published)
    assert all(q["Reliability Policy"] == "Reliable" and q["Durability Policy"] == "Volatile" for q in topics.values())
    kinds = {d["Class"] for d in manager["Displays"]}
    assert {"rviz_default_plugins/TF", "rviz_default_plugins/Image", "rviz_default_plugins/MarkerArray"} <= kinds
    assert "config/*.rviz" in (REPO / "setup.py").read_text()  # installed beside the parameter files


def test_a_graph_whose_cameras_publish_points_records_and_shows_them() -> None:
    """``up --set camera.points_stride=4``: each camera's spec publishes its ``points``, the recorder waits to
    record them (every frame's cloud in the bag), and up's RViz view draws each camera's cloud in the namespace, in
    its colours; without it, no camera publishes points."""
    from zebra_sim_ros.cli import up

    cfg = UpConfig(namespace="/g1", sets=up.parse_sets(["camera.points_stride=4"]))
    specs = cfg.check()
    clouds = [f"/g1/{d}/points" for d in cfg.drone_names]
    assert [t for s in specs if s.executable == "camera" for t in s.publishes if t.endswith("/points")] == clouds
    (recorder,) = [s for s in specs if s.executable == "recorder"]
    assert set(clouds) <= set(recorder.subscribes)
    view = up._rviz_view(cfg, REPO / "config", up._located(specs), graph_cameras(specs))
    assert view is not None
    shown = [d for d in view["Visualization Manager"]["Displays"] if d["Class"] == "rviz_default_plugins/PointCloud2"]
    assert [d["Topic"]["Value"] for d in shown] == clouds
    assert all(d["Color Transformer"] == "RGB8" and d["Enabled"] for d in shown)
    assert not [t for s in graph_spec(UpConfig()) for t in s.publishes if t.endswith("/points")]


def test_the_rviz_config_is_drawn_again_for_each_graphs_drones_and_namespace(tmp_path: Path) -> None:
    """``up`` writes the package's RViz file for its own graph: a detection image per camera (five here), drone_0's
    other displays and the world's kept, every topic in the namespace and published by that graph with the QoS the
    file asked; the default graph gets the package file's displays back, in its order. Displays of two classes on
    one topic are both drawn per drone; relative and empty topics, a display with no topic, a file with no drone's
    display are handled; a file that is not an RViz configuration is refused by name. The command remaps RViz's TF
    and clock into the namespace, its path quoted for a shell."""
    import shlex

    from zebra_sim_ros.graph.rviz import RVIZ_FILE, rviz_command, rviz_config, rviz_view, write_rviz
    from zebra_sim_ros.graph.spec import CENSUS_TOPICS, GLOBAL_TOPICS

    base = yaml.safe_load((REPO / "config" / RVIZ_FILE).read_text())
    assert rviz_config(base, UpConfig().drone_names) == base  # the file is drawn for the default graph
    cfg = UpConfig(drones=5, namespace="/g1", locate=True)
    view = rviz_view(REPO / "config", cfg.drone_names, cfg.namespace)
    assert view is not None
    path = write_rviz(view, tmp_path / "new" / RVIZ_FILE)
    assert path == tmp_path / "new" / RVIZ_FILE
    displays = yaml.safe_load(path.read_text())["Visualization Manager"]["Displays"]
    topics = [d["Topic"]["Value"] for d in displays if "Topic" in d]
    published = {t for s in graph_spec(cfg) for t in s.publishes}
    assert set(topics) <= published and len(topics) == len(set(topics)), sorted(set(topics) - published)
    assert [t for t in topics if t.endswith("/detections/image")] == [
        f"/g1/drone_{i}/detections/image" for i in range(5)]
    assert {"/g1/drone_0/labels/boxes3d", "/g1/drone_0/image_raw", "/g1/zebra_sim/zebras/markers"} <= set(topics)
    by_topic = {d["Topic"]["Value"]: d for d in displays if "Topic" in d}
    assert by_topic["/g1/drone_4/detections/image"]["Name"] == "drone_4 detections (detector)"
    assert by_topic["/g1/drone_4/detections/image"]["Enabled"] and not by_topic["/g1/drone_0/image_raw"]["Enabled"]
    # the census's display is on where the graph has the locator, off where it has not (as up and the launch file
    # ask without the locator)
    assert by_topic["/g1/census/animals/markers"]["Enabled"]
    off = rviz_view(REPO / "config", cfg.drone_names, cfg.namespace, CENSUS_TOPICS)
    assert off is not None
    changed = [(a["Name"], b["Enabled"]) for a, b in zip(view["Visualization Manager"]["Displays"],
                                                          off["Visualization Manager"]["Displays"], strict=True)
               if a != b]
    assert len(changed) == 1 and "census" in changed[0][0] and changed[0][1] is False, changed
    assert [d["Class"] for d in displays][:2] == ["rviz_default_plugins/Grid", "rviz_default_plugins/TF"]
    assert yaml.safe_load(path.read_text())["Visualization Manager"]["Global Options"]["Fixed Frame"] == "map"
    assert rviz_view(tmp_path / "no_rviz_here", cfg.drone_names) is None
    assert rviz_command(path, "/g1").endswith(" ".join(f"-r {t}:=/g1{t}" for t in GLOBAL_TOPICS))
    assert rviz_command(path) == f"rviz2 -d {path} --ros-args -p use_sim_time:=true"
    spaced = tmp_path / "my run" / RVIZ_FILE
    assert shlex.split(rviz_command(spaced))[:3] == ["rviz2", "-d", str(spaced)]
    one = rviz_config(base, UpConfig(drones=1).drone_names)["Visualization Manager"]["Displays"]
    assert [d["Topic"]["Value"] for d in one if "Topic" in d and "detections" in d["Topic"]["Value"]] == [
        "/drone_0/detections/image"]

    def with_displays(*extra: dict[str, Any]) -> dict[str, Any]:
        return {**base, "Visualization Manager": {**base["Visualization Manager"], "Displays": [
            *base["Visualization Manager"]["Displays"], *extra]}}

    def drawn(config: dict[str, Any], drones: int, namespace: str = "") -> list[dict[str, Any]]:
        return rviz_config(config, UpConfig(drones=drones).drone_names, namespace)["Visualization Manager"][
            "Displays"]

    def drawn_names(config: dict[str, Any], drones: int) -> list[tuple[str, str]]:
        return [(d["Name"], d["Topic"]["Value"]) for d in drawn(config, drones)
                if d.get("Topic", {}).get("Value", "").endswith("/depth")]

    # a display of one drone alone (here drone_2's depth, added) stays where the graph has that drone
    depth = {"Class": "rviz_default_plugins/Image", "Name": "drone_2 depth", "Enabled": False,
             "Topic": {"Value": "/drone_2/depth"}}
    for n, kept in ((3, True), (5, True), (2, False)):
        got = drawn(with_displays(depth), n)
        assert (depth in got) == kept and sum("/detections/image" in d.get("Topic", {}).get("Value", "")
                                              for d in got) == n
    # a second class on the same topics (a Camera display beside each Image display): both drawn for each drone
    cameras = [{"Class": "rviz_default_plugins/Camera", "Name": f"drone_{i} camera view",
                "Topic": {"Value": f"/drone_{i}/detections/image"}} for i in range(3)]
    got = drawn(with_displays(*cameras), 4)
    assert [d["Topic"]["Value"] for d in got if d["Class"] == "rviz_default_plugins/Camera"] == [
        f"/drone_{i}/detections/image" for i in range(4)]
    assert sum(d["Class"] == "rviz_default_plugins/Image" and "detections" in d["Topic"]["Value"] for d in got) == 4
    # relative and empty topics, and a display with a Topic but no Value, under a namespace
    odd = [{"Class": "rviz_default_plugins/MarkerArray", "Name": "relative", "Topic": {"Value": "zebra_sim/zebras"}},
           {"Class": "rviz_default_plugins/MarkerArray", "Name": "empty", "Topic": {"Value": ""}},
           {"Class": "rviz_default_plugins/MarkerArray", "Name": "none", "Topic": {"Depth": 5}}]
    got = {d["Name"]: d["Topic"] for d in drawn(with_displays(*odd), 3, "/g1") if d["Name"] in ("relative", "empty",
                                                                                                 "none")}
    assert got == {"relative": {"Value": "/g1/zebra_sim/zebras"}, "empty": {"Value": ""}, "none": {"Depth": 5}}
    # no drone's display at all: the world's displays, namespaced
    world = {**base, "Visualization Manager": {**base["Visualization Manager"], "Displays": [
        d for d in base["Visualization Manager"]["Displays"] if not d.get("Topic", {}).get("Value", "").startswith(
            "/drone_")]}}
    assert [d["Topic"]["Value"] for d in drawn(world, 2, "/g1") if "Topic" in d] == [
        "/g1/zebra_sim/zebras/markers", "/g1/census/animals/markers"]
    # the census switched off as the file spells it or relative, inside a group too; nothing else
    spelled = [{"Class": "rviz_default_plugins/MarkerArray", "Name": "census relative", "Enabled": True,
                "Topic": {"Value": "census/animals/markers"}},
               {"Class": "rviz_common/Group", "Name": "census group", "Enabled": True, "Displays": [
                   {"Class": "rviz_default_plugins/MarkerArray", "Name": "census in a group", "Enabled": True,
                    "Topic": {"Value": "/census/animals/markers"}}]}]
    got = rviz_config(with_displays(*spelled), UpConfig().drone_names, "/g1", CENSUS_TOPICS)
    shown = got["Visualization Manager"]["Displays"]
    by_name = {d["Name"]: d for d in shown} | {d["Name"]: d for d in shown[-1]["Displays"]}
    assert not by_name["census relative"]["Enabled"] and not by_name["census in a group"]["Enabled"]
    assert by_name["census group"]["Enabled"] and by_name["census in a group"]["Topic"]["Value"] == (
        "/g1/census/animals/markers")
    # ... or moved to where the graph's locator publishes it, as spelled or relative, inside a group too; the
    # others stay
    moved = rviz_config(with_displays(*spelled), UpConfig().drone_names, "/g1", (),
                        {"census/animals/markers": "herd/count/markers"})["Visualization Manager"]["Displays"]
    by_name = {d["Name"]: d for d in moved} | {d["Name"]: d for d in moved[-1]["Displays"]}
    assert [by_name[n]["Topic"]["Value"] for n in ("census relative", "census in a group",
                                                   "census, each zebra counted once across the drones (locator, "
                                                   "up --locate)")] == ["/g1/herd/count/markers"] * 3
    assert by_name["census relative"]["Enabled"] and by_name["census in a group"]["Enabled"]
    assert [d["Topic"]["Value"] for d in moved if "Topic" in d and "census" not in d["Name"]] == [
        d["Topic"]["Value"] for d in shown if "Topic" in d and "census" not in d["Name"]]
    # names that do not follow drone_N, relative drone topics: still one per camera; a name naming two drones keeps
    # the other; displays inside a group are moved into the namespace
    free = [{"Class": "rviz_default_plugins/Image", "Name": name, "Topic": {"Value": f"drone_{i}/depth"}}
            for i, name in enumerate(("Camera zero", "drone_1 (beside drone_12)", "depth of drone_2"))]
    group = {"Class": "rviz_common/Group", "Name": "group", "Displays": [
        {"Class": "rviz_default_plugins/Image", "Name": "in a group", "Topic": {"Value": "/drone_0/image_raw"}}]}
    got = drawn(with_displays(*free, group), 4, "/g1")
    depths = [(d["Name"], d["Topic"]["Value"]) for d in got if d.get("Topic", {}).get("Value", "").endswith("/depth")]
    assert [t for _, t in depths] == [f"/g1/drone_{i}/depth" for i in range(4)]
    assert depths[0][0] == "Camera zero"  # the first copy's name, no drone in it to change
    grouped = next(d for d in got if d["Name"] == "group")["Displays"]
    assert grouped[0]["Topic"]["Value"] == "/g1/drone_0/image_raw"
    named = [n for n, _ in drawn_names(with_displays(*[{**f, "Name": f"drone_{i} (beside drone_12)"}
                                                       for i, f in enumerate(free)]), 2)]
    assert named == ["drone_0 (beside drone_12)", "drone_1 (beside drone_12)"]
    # not an RViz configuration: refused, the file named
    (tmp_path / "bad").mkdir()
    for text in ("Panels: []\n", "Visualization Manager: [1, 2\n"):
        (tmp_path / "bad" / RVIZ_FILE).write_text(text)
        with pytest.raises(ValueError, match=str(tmp_path / "bad" / RVIZ_FILE)):
            rviz_view(tmp_path / "bad", cfg.drone_names)


def _scorer(cfg: UpConfig) -> NodeSpec:
    """The scorer of ``cfg``'s graph, as up starts it."""
    return next(s for s in graph_spec(cfg) if s.executable == "scorer")


def test_up_options_reach_its_graph_and_the_scorer_report_reads_back(tmp_path: Path) -> None:
    """``--no-score`` and ``--drones`` reach the graph; the scorer's last report becomes ``live_scores``, complete
    only when it scored every frame of the run (a run no longer than its window); up waits for that report two of
    the scorer's periods and a second, 10 s at least. Window and period are the config folder's."""
    import argparse
    import shutil

    from zebra_sim_ros.cli import up

    parser = argparse.ArgumentParser()
    up.register(parser.add_subparsers())
    cfg, specs = up._up_config(parser.parse_args(["up", "--no-score", "--drones", "2", "--bag-images", "png"]))
    assert not cfg.score and cfg.drones == 2 and cfg.bag_images == "png" and specs == graph_spec(cfg)
    assert [s.executable for s in specs] == ["camera"] * 2 + ["labeller", "detector", "recorder", "placer"]
    assert up._up_config(parser.parse_args(["up"])) == (UpConfig(), graph_spec(UpConfig()))
    shipped = REPO / "config"
    run = up.ScorerRun.read(shipped, _scorer(UpConfig()))
    assert (run.window, run.drones) == (300, 3) and run.period_s == pytest.approx(1.0)
    assert run.count_conf == pytest.approx(0.25)  # the bag's summary counts the zebras at the scorer's threshold
    assert run.expected(10) == 30 and run.whole(10) and run.wait_s == pytest.approx(10.0)
    two = up.ScorerRun.read(shipped, _scorer(UpConfig(drones=2)))
    assert two.expected(500) == 600 and not two.whole(500)  # its last 300 steps of two cameras
    conf = tmp_path / "config"
    shutil.copytree(shipped, conf)
    text = (conf / "scorer.yaml").read_text()
    (conf / "scorer.yaml").write_text(text.replace("diagnostics_period_s: 1.0", "diagnostics_period_s: 30.0")
                                      .replace("window: 300", "window: 1000").replace("count_conf: 0.25",
                                                                                      "count_conf: 0.4"))
    run = up.ScorerRun.read(conf, _scorer(UpConfig()))
    assert run.expected(500) == 1500 and run.whole(500) and run.wait_s == pytest.approx(61.0)
    assert run.count_conf == pytest.approx(0.4)
    # a bad value in the scorer's file is refused by name, as the node would refuse it (up reads it before any
    # node starts)
    (conf / "scorer.yaml").write_text(text.replace("window: 300", "window: 0"))
    with pytest.raises(ParameterError, match=re.escape(f"{conf / 'scorer.yaml'}: window")):
        up.ScorerRun.read(conf, _scorer(UpConfig()))
    # another graph's section is not this graph's: /g2's bad window stops /g2 only, as its node would refuse it
    (conf / "scorer.yaml").write_text(text + "/g2/scorer:\n  ros__parameters:\n    window: 0\n")
    assert up.ScorerRun.read(conf, _scorer(UpConfig(namespace="/g1"))).window == 300
    with pytest.raises(ParameterError, match="window"):
        up.ScorerRun.read(conf, _scorer(UpConfig(namespace="/g2")))
    (conf / "scorer.yaml").write_text(text)
    # a config folder whose recorder leaves out the depth images: up waits for the rest only, and with jpeg in the
    # bag the recorder leaves out both the raw images and what its file says
    text = (conf / "recorder.yaml").read_text()
    (conf / "recorder.yaml").write_text(re.sub(r"exclude_regex: .*", "exclude_regex: /depth$", text))
    for bag_images in ("raw", "jpeg"):
        rec = next(s for s in graph_spec(UpConfig(config_dir=str(conf), bag_images=bag_images))
                   if s.executable == "recorder")
        assert "/drone_0/depth" not in rec.subscribes and "/drone_0/labels" in rec.subscribes
        assert ("/drone_0/image_raw" in rec.subscribes) == (bag_images == "raw")
        assert rec.overrides.get("exclude_regex") == (None if bag_images == "raw" else
                                                      "(?:/depth$)|/drone_\\d+/(?:image_raw|detections/image)$")
    values = {"frames scored": "9", "labels": "9", "all mAP50": "0.5000", "all recall": "0.2500",
              "drone_0 mAP50": "0.4000", "drone_0 frames": "3", "detections per second": "1.2",
              "all count": "40/52", "all count MAE": "1.3333"}
    live = up._live_scores(values, up.ScorerRun(300, 1.0, 3, 0.25), 3)
    assert live["frames"] == 9 and live["complete"] and set(live) == {"frames", "complete", "all", "drone_0"}
    assert live["all"].pop("count") == pytest.approx({"counted": 40, "true": 52, "mae": 1.3333})
    assert live["all"] == pytest.approx({"mAP50": 0.5, "recall": 0.25}) and live["drone_0"] == pytest.approx(
        {"mAP50": 0.4})
    assert not up._live_scores(values, up.ScorerRun(300, 1.0, 3, 0.25), 4)["complete"]  # frames missing
    assert not up._live_scores(values, up.ScorerRun(3, 1.0, 3, 0.25), 4)["complete"]  # a longer run than its window
    assert not up._live_scores({}, up.ScorerRun(300, 1.0, 3, 0.25), 0)["complete"]  # no step at all


def test_up_sets_a_nodes_parameters_for_one_run() -> None:
    """``up --set NODE.NAME=VALUE``: the value (YAML) goes to that node's overrides (every camera's for camera),
    and the graph follows it (a locator set to place from the navigated poses subscribes those, and up waits for
    them); a parameter up sets itself, a node the graph does not run, a name the node does not declare, a value out
    of its range or against another parameter's rule and a malformed item are each refused by name before anything
    starts."""
    from zebra_sim_ros.cli.up import parse_sets

    sets = parse_sets(["placer.fix_sigma_m=2.5", "placer.nav_heading_sigma_deg=1", "locator.pose=camera/pose_nav",
                       "camera.jpeg_quality=80"])
    assert sets == (("placer", "fix_sigma_m", 2.5), ("placer", "nav_heading_sigma_deg", 1),
                    ("locator", "pose", "camera/pose_nav"), ("camera", "jpeg_quality", 80))
    nodes = {s.name: s for s in UpConfig(locate=True, sets=sets).check()}
    assert nodes["placer"].overrides["fix_sigma_m"] == pytest.approx(2.5, abs=1e-12)
    assert nodes["placer"].overrides["mode"] == "lockstep"
    assert all(nodes[f"drone_{i}_camera"].overrides["jpeg_quality"] == 80 for i in range(3))
    assert "/drone_1/camera/pose_nav" in nodes["locator"].subscribes
    assert "/drone_1/camera/pose" not in nodes["locator"].subscribes
    assert "fix_sigma_m" not in {s.name: s for s in graph_spec(UpConfig(locate=True))}["placer"].overrides
    # the placer aims with the cameras' field of view and lens, as their file and the run set them
    lens = {s.name: s.overrides for s in UpConfig(sets=parse_sets(
        ["camera.lens_k1=-0.2", "camera.lens_k2=0.05", "camera.hfov_deg=70"])).check()}["placer"]
    assert (lens["camera_lens_k1"], lens["camera_lens_k2"], lens["camera_hfov_deg"]) == pytest.approx((-0.2, 0.05, 70))
    # what shapes up's waits follows the set values too: the recorder's selection, the scorer's detections
    waits = {s.name: s.subscribes for s in UpConfig(sets=parse_sets(
        ["recorder.exclude_regex=/depth$", "scorer.detections=dets"])).check()}
    assert "/drone_0/depth" not in waits["recorder"] and "/drone_0/image_raw" in waits["recorder"]
    assert "/drone_2/dets" in waits["scorer"] and "/drone_2/detections" not in waits["scorer"]
    for bad, needle in ((["placer.mode=rate"], "'--set' = 'placer.mode=rate' is invalid: allowed a parameter up "
                                               "does not set itself"),
                        # the cameras' field of view is the placer's: set on the cameras, not on it alone
                        (["placer.camera_hfov_deg=60"], "placer.camera_hfov_deg=60' is invalid: allowed a parameter "
                                                        "up does not set itself"),
                        (["locator.pose=camera/pose_nav"], "a node this graph runs"),  # no --locate
                        (["placer.fix_sigma=2"], "'fix_sigma'"),
                        (["placer.fix_sigma_m=-1"], "'fix_sigma_m' = -1"),
                        # a rule between parameters, the file's values with the set one
                        (["placer.fix_correlation_s=5000"], "placer.yaml: fix_correlation_s' = 5000"),
                        (["placer.count_min=300"], "placer.yaml: count_min"),
                        (["fix_sigma_m=2"], "NODE.NAME=VALUE"), (["placer.fix_sigma_m"], "NODE.NAME=VALUE"),
                        (["placer.fix_sigma_m=[1"], "a YAML value")):
        with pytest.raises(ParameterError, match=re.escape(needle)):
            UpConfig(sets=parse_sets(bad)).check()


def test_ups_locator_waits_for_the_topics_its_file_names(tmp_path: Path) -> None:
    """A config folder whose locator.yaml renames the locator's input and outputs, or switches its census off: the
    graph's locator publishes and subscribes what its file names, so up waits for those topics, the recorder
    records them (up once waited on the default names and timed out) and up's RViz view shows the census where it
    is published (once it showed the default topic), off with the census off or no locator; a bad value there is
    refused before any node starts, named with its file."""
    from zebra_sim_ros.cli import up

    conf = tmp_path / "config"
    shutil.copytree(REPO / "config", conf)
    cfg = UpConfig(config_dir=str(conf), locate=True, namespace="/g1")
    specs: list[NodeSpec] = []

    def locator(**changes: str) -> tuple[NodeSpec, NodeSpec]:
        (conf / "locator.yaml").write_text(_locator_yaml(**changes))
        specs[:] = graph_spec(cfg)
        return next(s for s in specs if s.executable == "locator"), next(s for s in specs if s.executable == "recorder")

    def census_display(view: dict[str, Any] | None = None) -> tuple[str, bool]:
        """The census display of ``view``, or of up's view of the graph ``specs`` holds now."""
        view = view or up._rviz_view(cfg, conf, up._located(specs), graph_cameras(specs))
        assert view is not None
        (d,) = [d for d in view["Visualization Manager"]["Displays"] if "census" in d["Name"]]
        return d["Topic"]["Value"], d["Enabled"]

    default, _ = locator()
    assert "/g1/drone_0/detections/located" in default.publishes and "/g1/census/animals" in default.publishes
    assert default == next(s for s in graph_spec(UpConfig(locate=True, namespace="/g1")) if s.executable == "locator")
    loc, rec = locator(detections="dets", output="placed", census_output="herd/count")
    assert loc.publishes == ("/g1/drone_0/placed", "/g1/drone_1/placed", "/g1/drone_2/placed", "/g1/herd/count",
                             "/g1/herd/count/markers")
    assert "/g1/drone_2/dets" in loc.subscribes and "/g1/drone_2/detections" not in loc.subscribes
    assert set(loc.publishes) <= set(rec.subscribes) and "/g1/census/animals" not in rec.subscribes
    # up's RViz view: the census display on the census this locator publishes (its markers), on
    view = census_display()
    assert view == ("/g1/herd/count/markers", True) and view[0] in loc.publishes
    off, rec = locator(census="false")
    assert off.publishes == default.publishes[:3] and "/g1/census/animals" not in rec.subscribes
    assert census_display() == ("/g1/census/animals/markers", False)
    locator()
    assert census_display() == ("/g1/census/animals/markers", True)
    no_locator = UpConfig(config_dir=str(conf), namespace="/g1")
    assert up._located(graph_spec(no_locator)) is None
    no_view = up._rviz_view(no_locator, conf, None, graph_cameras(graph_spec(no_locator)))
    assert census_display(no_view) == ("/g1/census/animals/markers", False)
    with pytest.raises(ParameterError, match=re.escape(f"{conf / 'locator.yaml'}: output")):
        locator(output="depth")  # one of its inputs


def test_ups_locator_line_reads_every_summary_the_bag_can_give(capsys: pytest.CaptureFixture[str]) -> None:
    """The printed locator line of up's summary: the figures; a 90th percentile past every placed zebra (a step
    with none placed), which once ended the run before summary.json; no placed zebras recorded at all; detections
    placed from the drones' navigation (said; the exact poses are not)."""
    from zebra_sim_ros.cli import up

    base = {"frames": {}, "scores": {}, "median_ms": {}, "bag": "b.mcap", "damaged": [], "skipped": []}
    for located, want in (
            ({"frames": 9, "detections": 87, "frames_with_placed": 9, "scored": 87, "median_m": 0.42, "p90_m": 2.9,
              "within_1_m": 0.72}, "87 zebra detections placed on the map in 9 frames, 0.42 m from the nearest placed "
                                   "zebra (median; 90th percentile 2.90 m), 72% within 1 m\n"),
            ({"frames": 9, "detections": 20, "frames_with_placed": 9, "scored": 20, "median_m": 0.3, "p90_m": None,
              "within_1_m": 0.6}, "(median; 90th percentile none placed near), 60% within 1 m"),
            ({"frames": 9, "detections": 20, "frames_with_placed": 0, "scored": 0, "median_m": None, "p90_m": None,
              "within_1_m": None}, "20 zebra detections placed on the map in 9 frames (no placed zebras in the bag"),
            # placed from the drones' navigation: said
            ({"frames": 9, "detections": 87, "frames_with_placed": 9, "scored": 87, "median_m": 2.27, "p90_m": 3.6,
              "within_1_m": 0.03, "pose": "camera/pose_nav"}, "3% within 1 m (from <drone>/camera/pose_nav)\n")):
        up._print_summary({**base, "located": located}, ())
        assert want in capsys.readouterr().out, located
