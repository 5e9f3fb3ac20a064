"""Packaging for zebra_sim_ros (ament_python).

torch and the ROS 2 wheels (ros-jazzy-*) are deliberately absent from install_requires:
scripts/setup.sh installs them, torch pinned to the local CPU build 2.13.0, because an
unpinned torch pulls several GB of CUDA packages and the ROS wheels are not on plain PyPI
for every platform.
"""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = "zebra_sim_ros"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test", "test.*", "benchmarks", "benchmarks.*"]),
    package_data={PACKAGE: ["py.typed", "detection/weights/*.pt"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + PACKAGE]),
        ("share/" + PACKAGE, ["package.xml"]),
        # Empty globs are fine: setuptools installs an empty list as nothing.
        ("share/" + PACKAGE + "/config", sorted(glob("config/*.yaml") + glob("config/*.xml") + glob("config/*.rviz"))),
        ("share/" + PACKAGE + "/launch", sorted(glob("launch/*.py"))),
    ],
    install_requires=[
        "numpy",
        "usd-core",
        "trimesh",
        "opencv-python-headless",
        "mcap",
        "moderngl",
        "glcontext",
        "PyYAML",
    ],
    extras_require={
        "test": ["pytest", "ruff", "mypy", "rosbags", "colcon-common-extensions"],
    },
    zip_safe=True,
    maintainer="zebra_sim_ros developers",
    maintainer_email="dev@zebra-sim-ros.invalid",
    description=(
        "Synthetic drone imagery of zebras with exact ground truth, and a YOLO detector "
        "trained on it, as a ROS 2 node graph"
    ),
    license="Apache-2.0",
    python_requires=">=3.11",
    entry_points={
        "console_scripts": [
            "placer = zebra_sim_ros.nodes.placer:main",
            "camera = zebra_sim_ros.nodes.camera:main",
            "labeller = zebra_sim_ros.nodes.labeller:main",
            "detector = zebra_sim_ros.nodes.detector:main",
            "recorder = zebra_sim_ros.nodes.recorder:main",
            "replay = zebra_sim_ros.nodes.replay:main",
            "scorer = zebra_sim_ros.nodes.scorer:main",
            "locator = zebra_sim_ros.nodes.locator:main",
            "zebra-sim = zebra_sim_ros.cli:main",
        ],
    },
)
