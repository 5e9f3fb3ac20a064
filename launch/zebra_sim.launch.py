"""The whole zebra_sim_ros graph for ROS 2 installations:

    ros2 launch zebra_sim_ros zebra_sim.launch.py frames:=10 world:=savanna seed:=0 drones:=3

The same processes as ``zebra-sim up`` (``drones`` cameras, three by default; labeller, detector, scorer, recorder,
placer), with the same names, namespaces, parameter files (share/zebra_sim_ros/config) and overrides; a test
compares the two. ``zebra-sim up`` adds what launch does not: it waits until every node is ready before the placer's
first step, stops the graph after the last step and scores the run. Here the placer waits for the recorder through
``wait_for_nodes`` (the recorder by name: another subscriber such as RViz does not count) and exits after ``frames``
steps; stop the rest with Ctrl-C. The scorer (``score:=false`` leaves it out) publishes the detector's figures on
``/diagnostics``, status ``scorer: scorer`` (``ros2 topic echo /diagnostics``, or rqt's runtime monitor); nothing
holds the first step for it, so a scorer that subscribes late scores the steps from then on. ``locate:=true`` adds
the locator (each drone's detections placed on the map, ``<drone>/detections/located``, and each step's animals
counted once across the drones, ``census/animals``), as ``up --locate``.

Topic names are relative: wrap this launch file in a group with ``PushRosNamespace`` to move the whole graph (and
remap ``/tf``, ``/tf_static`` and ``/clock`` into it, as ``zebra-sim up --namespace`` does). The placer is the
clock (``/clock``, the simulated time of each step); every other node runs with ``use_sim_time``.

``rviz:=true`` also starts RViz (a desktop install's rviz2) on the package's view drawn for ``drones`` cameras,
written beside the bag (``zebra_sim.rviz``) as ``zebra-sim up`` writes it; its topics are the graph's without a
namespace (a graph moved into one needs up's view, ``up --namespace``, or RViz's own remaps); the census display is
off without ``locate:=true`` (or with the locator file's ``census: false``), and shows the topic that file's
``census_output`` names.

``config:=DIR`` reads the nodes' parameter files from ``DIR`` instead of the package's (a copy of
share/zebra_sim_ros/config edited, as ``zebra-sim up --config DIR``): every node's file, the recorder's exclusions,
the cameras' settings the placer aims with, the RViz view and the locator's topics come from it, and so does the
Fast DDS profile (its ``fastdds.xml``, where it holds one and no profile file is chosen already). A folder without
``placer.yaml`` is refused, naming ``config``.
"""

import os
from pathlib import Path

from ament_index_python.packages import get_package_share_directory
from launch.actions import DeclareLaunchArgument, LogInfo, OpaqueFunction, SetEnvironmentVariable
from launch.conditions import IfCondition, evaluate_condition_expression
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue

from launch import LaunchDescription

# up's own rules (light: numpy and OpenCV, no rclpy, no torch): the camera cap, what the bag may hold of the images
# and the recorder's exclude_regex for it, the environment every node gets (OpenMP threads that sleep when idle),
# and the RViz view drawn for the drones, its census display on what the locator's file names
from zebra_sim_ros.detection.config import LocatorConfig
from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.graph.rviz import RVIZ_FILE, rviz_view, write_rviz
from zebra_sim_ros.graph.spec import (
    NODE_ENVIRONMENT,
    PACKAGE,
    aim_warning,
    bag_image_overrides,
    check_bag_images,
    check_drones,
    cloud_topics,
    config_dir,
    dds_profile,
    node_config,
    placer_aim,
    recorder_excludes,
    rviz_census,
)
from zebra_sim_ros.rendering.config import CameraConfig


def generate_launch_description():
    share = os.path.join(get_package_share_directory(PACKAGE), "config")
    args = [
        DeclareLaunchArgument("frames", default_value="10", description="steps to run"),
        DeclareLaunchArgument("drones", default_value="3", description="cameras, drone_0 .. drone_<N-1> (1..16; as "
                              "zebra-sim up --drones)"),
        DeclareLaunchArgument("world", default_value="savanna", description="world preset or USD terrain"),
        DeclareLaunchArgument("seed", default_value="0", description="placer seed"),
        DeclareLaunchArgument("strategy", default_value="far", description="camera strategy (as zebra-sim up "
                              "--strategy: far, closeby, low, nadir, mixed, any)"),
        DeclareLaunchArgument("width", default_value="1280", description="image width, px"),
        DeclareLaunchArgument("height", default_value="720", description="image height, px"),
        DeclareLaunchArgument("weights", default_value="", description="detector checkpoint ('' = shipped)"),
        DeclareLaunchArgument("device", default_value="auto", description="detector device"),
        DeclareLaunchArgument("detect_scale", default_value="0.0", description="detector inference size over "
                              "the cameras' long side (0: the checkpoint's rule; as zebra-sim up --detect-scale)"),
        DeclareLaunchArgument("detect_amp", default_value="off", description="detector features in mixed precision "
                              "(off, auto, bf16, fp16; as zebra-sim up --detect-amp)"),
        DeclareLaunchArgument("verifier", default_value="", description="detector crop verifier ('' = off, "
                              "shipped, or a path; as zebra-sim up --verifier)"),
        DeclareLaunchArgument("score", default_value="true", description="start the scorer node (the detector's "
                              "figures live on /diagnostics; as zebra-sim up without --no-score)"),
        DeclareLaunchArgument("locate", default_value="false", description="start the locator node (each drone's "
                              "detections placed on the map, <drone>/detections/located, and the census, "
                              "census/animals; as zebra-sim up --locate)"),
        DeclareLaunchArgument("bag", default_value="out/up/zebra_sim.mcap", description="bag to record"),
        DeclareLaunchArgument("rviz", default_value="false", description="also start RViz (rviz2: a ROS 2 desktop "
                              "install) on the package's view drawn for these drones, as zebra-sim up writes it"),
        DeclareLaunchArgument("bag_images", default_value="raw", description="the cameras' images in the bag: raw, "
                              "or jpeg or png (image_raw/compressed instead; as zebra-sim up --bag-images)"),
        DeclareLaunchArgument("config", default_value="", description="folder of the nodes' parameter files ('' = "
                              "the package's, share/zebra_sim_ros/config; as zebra-sim up --config)"),
    ]

    def arg(name, value_type=str):
        return ParameterValue(LaunchConfiguration(name), value_type=value_type)

    def nodes(context):
        """The graph's processes: the number of cameras is the ``drones`` argument's value, read here, and their
        parameter files are the ``config`` argument's folder's."""
        given = LaunchConfiguration("config").perform(context).strip()
        try:
            config = str(config_dir(str(Path(given).expanduser()))) if given else share
        except ParameterError as exc:
            raise ParameterError("config", given, exc.allowed) from None

        def file(name):
            return os.path.join(config, name)

        # our Fast DDS profile (100 ms heartbeat: large images that lost a fragment arrive in 0.1 s, not 3 s) from
        # this folder, as zebra-sim up sets it, unless a profile file is already chosen
        profile = [SetEnvironmentVariable(k, v) for k, v in dds_profile(Path(config), os.environ).items()]
        count = LaunchConfiguration("drones").perform(context)
        if not count.isdigit():
            raise ParameterError("drones", count, "a number of cameras")
        drones = [f"drone_{i}" for i in range(check_drones(int(count), "drones"))]
        bag_images = check_bag_images(LaunchConfiguration("bag_images").perform(context), "bag_images")
        # the recorder's own sections of its file: in the namespace a PushRosNamespace around this file gives it
        ns = "/" + str(context.launch_configurations.get("ros_namespace", "")).strip("/")
        compressed, excludes = bag_image_overrides(
            bag_images, recorder_excludes(config, bag_images, f"{ns.rstrip('/')}/recorder"))
        locator = {"drones": drones, "image_reliability": "reliable", "pose_transient_local": True,
                   "use_sim_time": True}
        # each camera's overrides, and its settings as it starts (its file and them): the placer aims with the first
        # one's field of view and lens; RViz shows the points of those that publish them
        size = {}
        for k in ("width", "height"):
            value = LaunchConfiguration(k).perform(context)
            if not value.strip().isdigit():
                raise ParameterError(k, value, "a number of pixels")
            size[k] = int(value)
        overrides = [{"drone_index": i, **size, "ack": False, **compressed, "use_sim_time": True}
                     for i in range(len(drones))]
        cameras = [(f"/{d}", node_config(Path(config), "camera.yaml", f"{ns.rstrip('/')}/{d}_camera", o, CameraConfig))
                   for d, o in zip(drones, overrides, strict=True)]  # as the view names them (no namespace)
        aimed = placer_aim(cameras[0][1])
        said = [LogInfo(msg=f"warning: {warning}")] if (warning := aim_warning(cameras)) else []
        viewer = []
        if evaluate_condition_expression(context, [LaunchConfiguration("rviz")]):  # true, 1, false, 0, as score
            # the package's view, one detection image per drone, written beside the bag as up writes it
            # the census display on what this graph's locator publishes (its file's census_output), off without it
            located = (node_config(Path(config), "locator.yaml", f"{ns.rstrip('/')}/locator", locator, LocatorConfig)
                       if evaluate_condition_expression(context, [LaunchConfiguration("locate")]) else None)
            view = rviz_view(config, drones, "", *rviz_census(located),
                             clouds=cloud_topics(cameras))
            if view is None:
                raise ValueError(f"rviz:=true: no {RVIZ_FILE} in {config}")
            path = write_rviz(view, Path(LaunchConfiguration("bag").perform(context)).parent / RVIZ_FILE)
            viewer = [Node(package="rviz2", executable="rviz2", name="rviz", output="screen",
                           arguments=["-d", str(path.resolve())], parameters=[{"use_sim_time": True}])]
        return profile + said + [
            Node(package=PACKAGE, executable="camera", name=f"{d}_camera", namespace="", output="screen",
                 parameters=[file("camera.yaml"), o])
            for d, o in zip(drones, overrides, strict=True)
        ] + [
            Node(package=PACKAGE, executable="labeller", name="labeller", namespace="", output="screen",
                 parameters=[file("labeller.yaml"), {"drones": drones, "ack_name": "labeller",
                                                     "image_reliability": "reliable", "use_sim_time": True}]),
            Node(package=PACKAGE, executable="detector", name="detector", namespace="", output="screen",
                 parameters=[file("detector.yaml"), {"image_topics": [f"{d}/image_raw" for d in drones],
                                                     "ack_name": "detector", "weights": arg("weights"),
                                                     "device": arg("device"), "scale": arg("detect_scale", float),
                                                     "amp": arg("detect_amp"), "verifier": arg("verifier"),
                                                     "image_reliability": "reliable", "use_sim_time": True}]),
            Node(package=PACKAGE, executable="locator", name="locator", namespace="", output="screen",
                 parameters=[file("locator.yaml"), locator],
                 condition=IfCondition(LaunchConfiguration("locate"))),
            Node(package=PACKAGE, executable="scorer", name="scorer", namespace="", output="screen",
                 parameters=[file("scorer.yaml"), {"drones": drones, "use_sim_time": True}],
                 condition=IfCondition(LaunchConfiguration("score"))),
            Node(package=PACKAGE, executable="recorder", name="recorder", namespace="", output="screen",
                 parameters=[file("recorder.yaml"), {"output": arg("bag"), **excludes, "use_sim_time": True}]),
            Node(package=PACKAGE, executable="placer", name="placer", namespace="", output="screen",
                 parameters=[file("placer.yaml"), {
                     "world": arg("world"), "seed": arg("seed", int), "strategy": arg("strategy"),
                     "num_cameras": int(count), "mode": "lockstep", "max_steps": arg("frames", int),
                     "lockstep_ack_from": ["labeller", "detector"], "lockstep_timeout_s": 120.0,
                     "camera_width": size["width"], "camera_height": size["height"], **aimed,
                     "wait_for_subscribers": 1, "wait_for_nodes": ["recorder"]}]),
        ] + viewer

    env = [SetEnvironmentVariable(k, v) for k, v in NODE_ENVIRONMENT.items() if k not in os.environ]
    return LaunchDescription(args + env + [OpaqueFunction(function=nodes)])
