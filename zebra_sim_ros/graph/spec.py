"""What the whole graph is: which executables run, under which names and namespaces, with which parameter files
and overrides, and which topics each one publishes. ``zebra-sim up`` starts exactly this list, and
``launch/zebra_sim.launch.py`` mirrors it for ``ros2 launch`` (a test compares the two).
"""

from __future__ import annotations

import argparse
import os
import re
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

from zebra_sim_ros.detection.config import DetectorConfig, LocatorConfig, ScorerConfig
from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.geometry.lens import lens_distortion, lens_params
from zebra_sim_ros.labels.config import LabellerConfig
from zebra_sim_ros.params import ParamSpec, StageConfig, load_params_file, replace_tables, validate, write_config
from zebra_sim_ros.placement.config import PLACER_CAMERA_TOPICS, PLACER_TOPICS, PlacerConfig
from zebra_sim_ros.recording.config import RecorderConfig, ReplayConfig
from zebra_sim_ros.rendering.config import CameraConfig

PACKAGE = "zebra_sim_ros"
DRONES = ("drone_0", "drone_1", "drone_2")  # the default graph's cameras (UpConfig.drones: 3)
CAMERA_TOPICS = ("image_raw", "depth", "instances", "camera_info")
POINTS_TOPIC = "points"  # a camera's point cloud, with its points_stride
LABELLER_TOPICS = ("labels", "labels/markers", "labels/boxes3d", "labels/boxes2d")
DETECTOR_TOPICS = ("detections", "detections/image", "detections/markers")
# up --locate: the census, under the graph's namespace, as the locator's defaults name it (the RViz view's census
# display, off without the locator; the graph's locator publishes what its parameter file names: census_topics)
def census_topics(locator: LocatorConfig) -> tuple[str, ...]:
    """What ``locator`` publishes of its census, relative to its namespace (nothing with ``census`` false)."""
    return (f"/{locator.census_output}", f"/{locator.census_output}/markers") if locator.census else ()


CENSUS_TOPICS = census_topics(LocatorConfig())


def rviz_census(located: LocatorConfig | None) -> tuple[tuple[str, ...], dict[str, str]]:
    """What the RViz view's census displays (drawn on the locator's default topics, ``CENSUS_TOPICS``) need in a
    graph whose locator starts with ``located`` (None: a graph without the locator): the topics whose displays are
    switched off (no locator, or its ``census`` false) and those moved to where this locator publishes its census
    (a ``census_output`` of its own), both absolute and relative to the graph's namespace."""
    if located is None or not located.census:
        return CENSUS_TOPICS, {}
    return (), {a: b for a, b in zip(CENSUS_TOPICS, census_topics(located), strict=True) if a != b}
# By convention absolute (tf2 listeners and every node's time source use them); a namespaced graph remaps them.
GLOBAL_TOPICS = ("/tf", "/tf_static", "/clock")
BAG_NAME = "zebra_sim.mcap"
# What the bag holds of the cameras' images (up --bag-images): raw records image_raw; jpeg and png make the cameras
# publish image_raw/compressed and record that instead, leaving out image_raw and the detector's annotated copy
# (detections/image: the image with the detections, both in the bag). The detector still reads the raw images live.
BAG_IMAGES = ("raw", "jpeg", "png")
BAG_RAW_IMAGES = r"/drone_\d+/(?:image_raw|detections/image)$"  # what the recorder leaves out then (exclude_regex)


def recorder_excludes(config: Path, bag_images: str, node: str = "/recorder") -> str:
    """The recorder's ``exclude_regex`` in a graph whose bag holds ``bag_images``: its own (``config``/recorder.yaml's
    for the recorder ``node``, its fully qualified name; the node's default where the file or the entry is missing)
    with raw, and also the cameras' raw images and the detector's annotated copies (:data:`BAG_RAW_IMAGES`) with
    jpeg or png. ``zebra-sim up`` and the launch file both ask here."""
    path = Path(config) / "recorder.yaml"
    base = RecorderConfig().exclude_regex
    if path.is_file():
        base = str(load_params_file(str(path), node).get("exclude_regex", base))
    if bag_images == "raw":
        return base
    return f"(?:{base})|{BAG_RAW_IMAGES}" if base else BAG_RAW_IMAGES


def bag_image_overrides(bag_images: str, excludes: str) -> tuple[dict[str, str], dict[str, str]]:
    """What a graph whose bag holds ``bag_images`` sets on top of the parameter files: the cameras' overrides and the
    recorder's. Raw sets nothing (the files' settings hold); jpeg or png make the cameras publish
    image_raw/compressed in that format and the recorder leave out ``excludes`` (:func:`recorder_excludes`, which
    adds the raw images). ``zebra-sim up`` and the launch file both ask here."""
    if bag_images == "raw":
        return {}, {}
    return {"compressed": bag_images}, {"exclude_regex": excludes}


C = TypeVar("C", bound=StageConfig)


def node_config(conf: Path, params_file: str, fqn: str, overrides: dict[str, Any], cls: type[C]) -> C:
    """The settings of the graph's node ``fqn`` as it starts with them: ``conf``/``params_file``'s sections for it,
    then ``overrides``, validated as the node validates them (``ParameterError`` naming a bad value and its file)."""
    path = Path(conf) / params_file
    try:
        return cls.from_params({**load_params_file(str(path), fqn), **overrides})
    except ParameterError as exc:  # named by its file: qos_depth, diagnostics_period_s are in every node's
        if exc.name == "params_file":
            raise
        raise ParameterError(f"{path}: {exc.name}", exc.value, exc.allowed) from None


# each executable's validated settings (its parameters and the rules between them), and its parameters
NODE_CONFIGS: dict[str, type[StageConfig]] = {
    "placer": PlacerConfig, "camera": CameraConfig, "labeller": LabellerConfig, "detector": DetectorConfig,
    "recorder": RecorderConfig, "replay": ReplayConfig, "scorer": ScorerConfig, "locator": LocatorConfig}
NODE_PARAMS: dict[str, tuple[ParamSpec, ...]] = {name: cls.specs() for name, cls in NODE_CONFIGS.items()}


@dataclass(frozen=True)
class NodeSpec:
    """One process of the graph."""

    executable: str  # console script and module zebra_sim_ros.nodes.<executable>
    name: str  # node name
    namespace: str  # "" or the graph's namespace, e.g. "/g1"
    params_file: str  # file name in the config folder
    overrides: dict[str, Any] = field(default_factory=dict)  # -p name:=value after the file
    publishes: tuple[str, ...] = ()  # absolute topic names this node publishes (readiness and docs)
    remaps: tuple[tuple[str, str], ...] = ()  # -r from:=to (a namespaced graph's /tf, /tf_static, /clock)
    subscribes: tuple[str, ...] = ()  # absolute topic names it must subscribe before the first step (readiness)
    # its settings as it starts with them (file and overrides, validated), where the graph read them for its topics
    config: StageConfig | None = field(default=None, compare=False)

    @property
    def fqn(self) -> str:
        """Fully qualified node name, e.g. ``/drone_0_camera`` or ``/g1/placer``."""
        return f"{self.namespace}/{self.name}"

    @property
    def label(self) -> str:
        """Short unique label for logs and messages: ``placer``, ``drone_0_camera``, ``g1/placer``."""
        return self.fqn.lstrip("/")


@dataclass(frozen=True)
class UpConfig:
    """Settings of one ``zebra-sim up`` run."""

    frames: int = 10
    drones: int = 3  # cameras, drone_0 .. drone_<n-1> (the placer's num_cameras)
    world: str = "savanna"
    seed: int = 0
    out: str = "out/up"
    width: int = 1280
    height: int = 720
    weights: str = ""  # "" = the shipped weights
    device: str = "auto"
    strategy: str = "far"
    config_dir: str = ""  # "" = the installed config folder (see config_dir())
    ready_timeout_s: float = 180.0
    step_timeout_s: float = 120.0
    record: bool = True
    score: bool = True  # the scorer node: the detector's figures live on /diagnostics (up keeps its last ones)
    locate: bool = False  # the locator node: each drone's detections placed on the map (detections/located)
    bag_images: str = "raw"  # the cameras' images in the bag: raw, or jpeg / png (image_raw/compressed; see BAG_IMAGES)
    # The detector's input long side as a multiple of the cameras' (0: the checkpoint's rule, the scale its
    # serving size has to its training frames: 1.7 for the shipped weights, 2176 on 1280x720 frames). On 84
    # frames at 1280x720 of the training worlds (seed 777): 1.0 (1280) mAP50 0.797 / mAP50-95 0.533, 1.3 (1664)
    # 0.833 / 0.578, 1.7 (2176) 0.843 / 0.581 at twice 1.3's cost.
    detect_scale: float = 0.0
    detect_amp: str = "off"  # the detector's ``amp``: its features in mixed precision (bf16: 1.7x on AVX512-BF16)
    verifier: str = ""  # the detector's crop verifier ("" off, "shipped" or a path): for photographs, off by default
    namespace: str = ""  # the graph's namespace ("" = the root): every topic moves under it
    # (executable, parameter, value): a node's parameter set for this run over its file (``up --set``); every
    # camera's for "camera"; a parameter up sets itself cannot be (its lockstep, topics and sizes)
    sets: tuple[tuple[str, str, Any], ...] = ()

    def check(self) -> list[NodeSpec]:
        """Raise :class:`ParameterError` naming the first bad setting; the graph's nodes (:func:`graph_spec`), each
        checked by its own parameters' rules, when there is none."""
        if self.frames < 1:
            raise ParameterError("--frames", self.frames, ">= 1")
        check_drones(self.drones)
        if not (16 <= self.width <= 8192 and 16 <= self.height <= 8192):
            raise ParameterError("--size", f"{self.width}x{self.height}", "WxH with 16..8192 each")
        from zebra_sim_ros.placement.config import STRATEGY_CHOICES

        if self.strategy not in STRATEGY_CHOICES:
            raise ParameterError("--strategy", self.strategy, f"one of {', '.join(STRATEGY_CHOICES)}")
        from zebra_sim_ros.detection.checkpoint import check_scale

        check_scale("--detect-scale", self.detect_scale)
        if self.verifier not in ("", "shipped") and not Path(self.verifier).is_file():
            raise ParameterError("--verifier", self.verifier, "empty, shipped or an existing verifier checkpoint")
        check_namespace(self.namespace)
        check_bag_images(self.bag_images)
        if self.ready_timeout_s <= 0 or self.step_timeout_s <= 0:
            raise ParameterError("--timeout", min(self.ready_timeout_s, self.step_timeout_s), "> 0 s")
        from zebra_sim_ros.world.world import check_world_source

        check_world_source(self.world)
        nodes = graph_spec(self)
        running = sorted({n.executable for n in nodes})
        for executable, name, value in self.sets:
            if executable not in running:
                raise ParameterError("--set", f"{executable}.{name}={value}", f"NODE.NAME=VALUE of a node this graph "
                                     f"runs ({', '.join(running)})")
        set_for = {executable for executable, _, _ in self.sets}
        for node in nodes:  # each node's own rules, before any process starts
            if node.config is not None:  # read by the graph for its topics: validated then, its file with them
                continue
            validate(NODE_PARAMS[node.executable], node.overrides)
            if node.executable in set_for:  # and the rules between its parameters, its file's values with the sets
                node_config(config_dir(self.config_dir), node.params_file, node.fqn, node.overrides,
                            NODE_CONFIGS[node.executable])
        return nodes

    @property
    def drone_names(self) -> tuple[str, ...]:
        """The cameras' names, ``drone_0`` .. ``drone_<drones - 1>``: their namespaces and tf frames."""
        return tuple(f"drone_{i}" for i in range(self.drones))

    @property
    def bag_path(self) -> Path:
        return Path(self.out) / BAG_NAME

    def bag_files(self) -> list[Path]:
        """The recording's files in the order written: the bag, or its pieces (``zebra_sim_<k>.mcap``) where the
        recorder split it (by size, duration or its ``~/split_bagfile`` service)."""
        from zebra_sim_ros.recording.reader import recording_files

        return recording_files(self.bag_path)

    @property
    def detect_imgsz(self) -> int:
        """The detector's inference size on the cameras' frames: ``detect_scale`` times their long side, or the
        checkpoint's rule (its ``scale`` parameter is ``detect_scale``, 0 by default)."""
        from zebra_sim_ros.detection.checkpoint import checkpoint_config
        from zebra_sim_ros.detection.predict import inference_size

        return inference_size(checkpoint_config(self.weights or None), max(self.width, self.height),
                              scale=self.detect_scale)


def config_dir(explicit: str = "") -> Path:
    """The folder with placer.yaml, camera.yaml, ...: ``explicit`` if given, else the installed share folder
    (``<prefix>/share/zebra_sim_ros/config``, as colcon and pip install it), else the source tree's config/."""
    candidates = [Path(explicit)] if explicit else []
    if not explicit:
        prefixes = [Path(p) for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
        candidates += [p / "share" / PACKAGE / "config" for p in (*prefixes, Path(sys.prefix))]
        candidates.append(Path(__file__).resolve().parents[2] / "config")
    for c in candidates:
        if (c / "placer.yaml").is_file():
            return c
    raise ParameterError("--config", explicit or "(installed)", f"a folder with placer.yaml; looked in "
                         f"{[str(c) for c in candidates]}")


DDS_PROFILE = "fastdds.xml"
# What every node process of a graph gets unless its caller set it: OpenMP threads (torch's, in the detector) that
# sleep when they have no work instead of spinning. Spinning, they took the CPU the cameras and the labeller of the
# same graph needed: on 2 cores the detector's median step took 0.50 s against 0.20 on 320x180 frames, and the
# graph ran 1.07-1.12x the steps per second at 1280x720 (BENCHMARKS.md, "OpenMP threads that wait passively").
# The launch file imports it.
NODE_ENVIRONMENT = {"OMP_WAIT_POLICY": "PASSIVE"}
_PROFILE_VARS = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")


def dds_profile(config: Path, environ: Mapping[str, str]) -> dict[str, str]:
    """What our Fast DDS profile adds to ``environ`` (config/fastdds.xml: a 100 ms heartbeat, so a large image that
    lost a fragment arrives within 0.1 s instead of 3 s): nothing where the user already chose a profile file or
    ``config`` holds none. The launch file sets it."""
    if any(environ.get(v) for v in _PROFILE_VARS) or not (config / DDS_PROFILE).is_file():
        return {}
    return {"FASTRTPS_DEFAULT_PROFILES_FILE": str(config / DDS_PROFILE)}


def dds_environment(config: Path, environ: dict[str, str]) -> dict[str, str]:
    """``environ`` with our Fast DDS profile (:func:`dds_profile`)."""
    return {**environ, **dds_profile(config, environ)}


def global_remaps(namespace: str) -> tuple[tuple[str, str], ...]:
    """``/tf``, ``/tf_static`` and ``/clock`` moved into ``namespace`` (none without one): what every node of a
    namespaced graph, and a viewer of it, remaps."""
    return tuple((t, f"{namespace}{t}") for t in GLOBAL_TOPICS) if namespace else ()


def check_drones(count: int, name: str = "--drones") -> int:
    """``count`` if it is a number of cameras the graph can run (1..MAX_CAMERAS); ParameterError naming ``name``
    (up's option, the launch file's argument) otherwise."""
    from zebra_sim_ros.geometry.camera import MAX_CAMERAS

    if not 1 <= count <= MAX_CAMERAS:
        raise ParameterError(name, count, f"1..{MAX_CAMERAS}")
    return count


def check_bag_images(value: str, name: str = "--bag-images") -> str:
    """``value`` if it is one of :data:`BAG_IMAGES`; ParameterError naming ``name`` otherwise."""
    if value not in BAG_IMAGES:
        raise ParameterError(name, value, f"one of {', '.join(BAG_IMAGES)}")
    return value


def check_namespace(namespace: str) -> str:
    """``namespace`` if it is "" or an absolute ROS name (``/g1``, ``/site_a/g1``); ParameterError otherwise."""
    if namespace and not re.fullmatch(r"(/[A-Za-z][A-Za-z0-9_]*)+", namespace):
        raise ParameterError("--namespace", namespace, "empty or /name[/name...] (letters, digits, _; a letter first)")
    return namespace


def camera_topics(camera: CameraConfig) -> tuple[str, ...]:
    """The topics a camera node publishes under its drone with ``camera``'s settings (acknowledgements aside)."""
    return (*CAMERA_TOPICS, *(("image_raw/compressed",) if camera.compressed != "off" else ()),
            *((POINTS_TOPIC,) if camera.points_stride else ()))


def graph_cameras(nodes: Sequence[NodeSpec]) -> list[tuple[str, CameraConfig]]:
    """The graph's cameras as ``/ns/drone_i`` and their settings as they start (the camera specs' configs)."""
    return [(f"{n.namespace}/{n.config.name}", n.config) for n in nodes if isinstance(n.config, CameraConfig)]


def placer_aim(camera: CameraConfig) -> dict[str, Any]:
    """The placer's parameters that must equal the cameras' for its aim (the pivot in view): the field of view and
    lens of ``camera`` (a camera node's settings as it starts); up and the launch file give it the first camera's
    (the placer aims every camera with one: :func:`aim_warning`)."""
    return {"camera_hfov_deg": camera.hfov_deg, **lens_params(lens_distortion(camera), "camera_lens_")}


def aim_warning(cameras: Sequence[tuple[str, CameraConfig]]) -> str:
    """What to say where the graph's cameras (name, settings) differ in field of view or lens, which the placer,
    aiming every camera with the first one's, does not follow; "" where they agree."""
    first = placer_aim(cameras[0][1])
    others = [name for name, c in cameras[1:] if placer_aim(c) != first]
    return (f"{', '.join(others)} differ from {cameras[0][0]} in field of view or lens; the placer aims every camera "
            f"with {cameras[0][0]}'s ({first})") if others else ""


def cloud_topics(cameras: Sequence[tuple[str, CameraConfig]]) -> list[tuple[str, str]]:
    """The point cloud topics (absolute, under each camera's name ``/ns/drone_i``) of the cameras that publish
    them, with their reliability: what an RViz view draws."""
    return [(f"{name}/{POINTS_TOPIC}", c.qos_reliability) for name, c in cameras if c.points_stride]


def graph_spec(cfg: UpConfig) -> list[NodeSpec]:
    """The processes of the whole graph, in start order (the placer last: it starts the steps, once the scorer and
    the recorder subscribe what they need). Every node runs in ``cfg.namespace`` with relative topic names, so the
    namespace moves the whole graph; the placer is the clock (``/clock``), the others run on its simulated time
    (``use_sim_time``)."""
    ns = check_namespace(cfg.namespace)
    conf = config_dir(cfg.config_dir)
    remaps = global_remaps(ns)
    sim = {"use_sim_time": True}
    drones = cfg.drone_names
    nodes: list[NodeSpec] = []

    def own(executable: str, ups: dict[str, Any]) -> dict[str, Any]:
        """``ups`` (what up sets) with the run's ``--set`` values of ``executable``; one of up's own refused."""
        mine = {name: value for exe, name, value in cfg.sets if exe == executable}
        if clash := sorted(set(mine) & set(ups)):
            raise ParameterError("--set", f"{executable}.{clash[0]}={mine[clash[0]]}", f"a parameter up does not set "
                                 f"itself (it sets the {executable}'s {', '.join(sorted(ups))})")
        return {**ups, **mine}

    # what the recorder leaves out (up waits for the rest); its file is read only where a recorder runs
    excludes = (recorder_excludes(conf, cfg.bag_images, f"{ns}/recorder")
                if cfg.record and cfg.bag_images != "raw" else "")  # raw: the file's own, read with its settings
    camera_bag, recorder_bag = bag_image_overrides(cfg.bag_images, excludes)
    aimed: dict[str, Any] = {}
    for i, d in enumerate(drones):
        cam = own("camera", {"drone_index": i, "width": cfg.width, "height": cfg.height, "ack": False, **camera_bag,
                             **sim})
        camera = node_config(conf, "camera.yaml", f"{ns}/{d}_camera", cam, CameraConfig)
        if i == 0:  # what the placer aims every camera with: the first camera's field of view and lens
            aimed = placer_aim(camera)
        nodes.append(NodeSpec("camera", f"{d}_camera", ns, "camera.yaml", cam,
                              tuple(f"{ns}/{d}/{t}" for t in camera_topics(camera)), remaps, config=camera))
    # The graph's own cameras publish reliably and lockstep waits for every frame: subscribe reliably too.
    nodes.append(NodeSpec("labeller", "labeller", ns, "labeller.yaml",
                          own("labeller", {"drones": list(drones), "ack_name": "labeller",
                                           "image_reliability": "reliable", **sim}),
                          tuple(f"{ns}/{d}/{t}" for d in drones for t in LABELLER_TOPICS), remaps))
    # scale 0: the detector sizes the cameras' frames by the checkpoint's rule (far zebras are a few pixels tall).
    det = {"image_topics": [f"{d}/image_raw" for d in drones], "ack_name": "detector",
           "weights": str(Path(cfg.weights).resolve()) if cfg.weights else "", "device": cfg.device,
           "scale": cfg.detect_scale, "amp": cfg.detect_amp, "image_reliability": "reliable",
           "verifier": cfg.verifier if cfg.verifier in ("", "shipped") else str(Path(cfg.verifier).resolve()), **sim}
    nodes.append(NodeSpec("detector", "detector", ns, "detector.yaml", own("detector", det),
                          tuple(f"{ns}/{d}/{t}" for d in drones for t in DETECTOR_TOPICS), remaps))
    if cfg.locate:  # every frame placed: subscribed before the first step; its topics as its file names them
        loc = own("locator", {"drones": list(drones), "image_reliability": "reliable", "pose_transient_local": True,
                              **sim})
        located = node_config(conf, "locator.yaml", f"{ns}/locator", loc, LocatorConfig)
        nodes.append(NodeSpec("locator", "locator", ns, "locator.yaml", loc,
                              tuple(f"{ns}/{d}/{located.output}" for d in drones)
                              + tuple(f"{ns}{t}" for t in census_topics(located)), remaps,
                              tuple(f"{ns}/{d}/{t}" for d in drones for t in located.inputs), located))
    if cfg.score:  # every frame scored: subscribed before the first step; its detections as its file names them
        sco = own("scorer", {"drones": list(drones), **sim})
        scored = node_config(conf, "scorer.yaml", f"{ns}/scorer", sco, ScorerConfig)
        nodes.append(NodeSpec("scorer", "scorer", ns, "scorer.yaml", sco, (), remaps,
                              tuple(f"{ns}/{d}/{t}" for d in drones for t in ("labels", scored.detections)), scored))
    if cfg.record:  # up waits for what it records: its file's selection with up's and the run's settings
        rec = {"output": str(cfg.bag_path.resolve()), **recorder_bag, **sim}
        if ns:  # this graph's topics only, not another graph's on the same domain
            rec["topic_regex"] = f"^{ns}/"
        rec = own("recorder", rec)
        recorded = node_config(conf, "recorder.yaml", f"{ns}/recorder", rec, RecorderConfig)
        nodes.append(NodeSpec("recorder", "recorder", ns, "recorder.yaml", rec, (), remaps,
                              tuple(t for n in nodes for t in n.publishes if recorded.records(t)), recorded))
    nodes.append(NodeSpec("placer", "placer", ns, "placer.yaml", own("placer", {
        "world": cfg.world, "seed": cfg.seed, "strategy": cfg.strategy, "num_cameras": cfg.drones, "mode": "lockstep",
        "max_steps": cfg.frames, "lockstep_ack_from": ["labeller", "detector"],
        "lockstep_timeout_s": cfg.step_timeout_s,
        "camera_width": cfg.width, "camera_height": cfg.height, **aimed, "wait_for_subscribers": 1 if cfg.record else 0,
        "wait_for_nodes": ["recorder"] if cfg.record else [""]}),
        tuple(f"{ns}/{t}" for t in (*PLACER_TOPICS, *(f"{d}/{c}" for d in drones for c in PLACER_CAMERA_TOPICS)))
        + tuple(f"{ns}{t}" for t in GLOBAL_TOPICS), remaps))
    return nodes


def ros_value(value: Any) -> str:
    """A parameter value as ``-p name:=value`` wants it (YAML)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(ros_value(v) for v in value) + "]"
    if isinstance(value, str):  # always quoted: unquoted, YAML reads 'yes', 'on' or '-1' as bool or int
        return "'" + value.replace("'", "''") + "'"
    return repr(value)


def command(spec: NodeSpec, config: Path, python: str = sys.executable) -> list[str]:
    """The command line that starts ``spec`` (``python -m zebra_sim_ros.nodes.<executable> --ros-args ...``)."""
    args = [python, "-m", f"{PACKAGE}.nodes.{spec.executable}", "--ros-args", "-r", f"__node:={spec.name}"]
    if spec.namespace:
        args += ["-r", f"__ns:={spec.namespace}"]
    for src, dst in spec.remaps:
        args += ["-r", f"{src}:={dst}"]
    args += ["--params-file", str(config / spec.params_file)]
    for k, v in spec.overrides.items():
        args += ["-p", f"{k}:={ros_value(v)}"]
    return args


def main(argv: list[str] | None = None) -> int:
    """``python -m zebra_sim_ros.graph.spec --write-config config/``: regenerate the nodes' parameter files
    from their declarations (the test suite fails while a file and its declarations disagree)."""
    p = argparse.ArgumentParser(prog="python -m zebra_sim_ros.graph.spec", description=main.__doc__)
    p.add_argument("--write-config", type=Path, required=True, metavar="FOLDER",
                   help="folder of <node>.yaml files to (re)write from the declarations")
    p.add_argument("--write-readme", type=Path, default=None, metavar="README",
                   help="also rewrite the nodes' parameter tables in this README")
    args = p.parse_args(argv)
    if not args.write_config.is_dir():
        p.error(f"{args.write_config} is not a folder")
    for path in write_config(args.write_config, NODE_PARAMS):
        print(f"wrote {path}")
    if args.write_readme is not None:
        text = args.write_readme.read_text()
        new = replace_tables(text, NODE_PARAMS)
        args.write_readme.write_text(new)
        print(f"wrote {args.write_readme}" if new != text else f"{args.write_readme} was up to date")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
