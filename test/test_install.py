"""Build the package with colcon, as a ROS user would, and check what `ros2 run` relies on.

`ros2 run zebra_sim_ros <exe>` asks the ament index for the package prefix and runs
`<prefix>/lib/zebra_sim_ros/<exe>`; nodes find their YAML under the share directory. ros2cli is
not installable here, so this test does that lookup itself with ament_index_python, in a
subprocess whose environment is what sourcing `install/setup.bash` would give it.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGE = "zebra_sim_ros"
EXECUTABLES = ["placer", "camera", "labeller", "detector", "recorder", "replay", "scorer", "locator", "zebra-sim"]
# What the package's source tree contributes to a colcon build; anything else (the .venv,
# out/, datasets) must not leak into the copy.
SOURCE_ITEMS = ["package.xml", "setup.py", "setup.cfg", "resource", "config", "launch", PACKAGE]
BUILD_TIMEOUT_S = 120
RUN_TIMEOUT_S = 30


class Installed:
    """A colcon install of the package: its prefix and the environment that finds it."""

    def __init__(self, workspace: Path, prefix: Path, env: dict[str, str]) -> None:
        self.workspace = workspace  # cwd for subprocesses: `python -c` would import from a source tree
        self.prefix = prefix
        self.env = env


def _colcon_env(root: Path) -> dict[str, str]:
    env = dict(os.environ)
    # Keep colcon away from the user's ~/.colcon defaults and the repo's log/ directory.
    env["COLCON_HOME"] = str(root / "colcon_home")
    env["COLCON_LOG_PATH"] = str(root / "log")
    return env


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> Installed:
    root = tmp_path_factory.mktemp("colcon_ws")
    src = root / "src" / PACKAGE
    src.mkdir(parents=True)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    for name in SOURCE_ITEMS:
        path = REPO / name
        if path.is_dir():
            shutil.copytree(path, src / name, ignore=ignore)
        elif path.is_file():
            shutil.copy2(path, src / name)

    cmd = [
        sys.executable,
        "-m",
        "colcon",
        "build",
        "--base-paths",
        "src",
        "--build-base",
        "build",
        "--install-base",
        "install",
    ]
    proc = subprocess.run(
        cmd, cwd=root, env=_colcon_env(root), capture_output=True, text=True, timeout=BUILD_TIMEOUT_S
    )
    assert proc.returncode == 0, f"colcon build failed:\n{proc.stdout}\n{proc.stderr}"

    prefix = root / "install" / PACKAGE
    site_packages = sorted(prefix.glob("lib/python3.*/site-packages"))
    assert len(site_packages) == 1, f"expected one site-packages under {prefix}, got {site_packages}"

    # What `source install/setup.bash` would add, in front of anything already set.
    env = dict(os.environ)
    env["AMENT_PREFIX_PATH"] = os.pathsep.join(filter(None, [str(prefix), env.get("AMENT_PREFIX_PATH")]))
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(site_packages[0]), env.get("PYTHONPATH")]))
    return Installed(root, prefix, env)


_LOOKUP = """
import json
from ament_index_python.packages import get_package_prefix, get_package_share_directory
import zebra_sim_ros.nodes
print(json.dumps({
    "prefix": get_package_prefix("zebra_sim_ros"),
    "share": get_package_share_directory("zebra_sim_ros"),
    "nodes_file": zebra_sim_ros.nodes.__file__,
}))
"""


@pytest.fixture(scope="module")
def lookup(installed: Installed) -> dict[str, str]:
    proc = subprocess.run(
        [sys.executable, "-c", _LOOKUP],
        cwd=installed.workspace,
        env=installed.env,
        capture_output=True,
        text=True,
        timeout=RUN_TIMEOUT_S,
    )
    assert proc.returncode == 0, proc.stderr
    result: dict[str, str] = json.loads(proc.stdout)
    return result


def test_ament_index_finds_the_colcon_install(installed: Installed, lookup: dict[str, str]) -> None:
    assert Path(lookup["prefix"]).resolve() == installed.prefix.resolve()
    # The Python package is imported from the install, not from the source tree or the .venv.
    assert Path(lookup["nodes_file"]).resolve().is_relative_to(installed.prefix.resolve())


def test_executables_are_where_ros2_run_looks(lookup: dict[str, str]) -> None:
    lib = Path(lookup["prefix"]) / "lib" / PACKAGE
    missing = [exe for exe in EXECUTABLES if not (lib / exe).is_file()]
    assert not missing, f"not in {lib}: {missing}; found {sorted(p.name for p in lib.glob('*'))}"
    not_executable = [exe for exe in EXECUTABLES if not os.access(lib / exe, os.X_OK)]
    assert not not_executable, f"not executable in {lib}: {not_executable}"


def test_share_directory_holds_package_xml(lookup: dict[str, str]) -> None:
    share = Path(lookup["share"])
    assert (share / "package.xml").is_file()
    assert f"<name>{PACKAGE}</name>" in (share / "package.xml").read_text()
    marker = Path(lookup["prefix"]) / "share" / "ament_index" / "resource_index" / "packages" / PACKAGE
    assert marker.is_file()


def test_package_xml_declares_every_ros_package_the_code_imports() -> None:
    """rosdep installs what package.xml names: every ROS interface package our code imports must be there (the
    placer's std_srvs once was not)."""
    import re

    imported = set()
    for path in (REPO / PACKAGE).rglob("*.py"):
        imported |= set(re.findall(r"^\s*(?:from|import) (\w+_(?:msgs|srvs))\b", path.read_text(), re.M))
    declared = set(re.findall(r"<exec_depend>(\w+)</exec_depend>", (REPO / "package.xml").read_text()))
    assert {"std_srvs", "diagnostic_msgs", "sensor_msgs"} <= imported
    assert imported <= declared, sorted(imported - declared)


@pytest.mark.parametrize("exe", ["zebra-sim", "placer"])
def test_installed_script_runs_help(installed: Installed, lookup: dict[str, str], exe: str) -> None:
    script = Path(lookup["prefix"]) / "lib" / PACKAGE / exe
    proc = subprocess.run(
        [str(script), "--help"],
        cwd=installed.workspace,
        env=installed.env,
        capture_output=True,
        text=True,
        timeout=RUN_TIMEOUT_S,
    )
    assert proc.returncode == 0, f"{script} --help exited {proc.returncode}:\n{proc.stdout}\n{proc.stderr}"
    assert proc.stdout.strip(), f"{script} --help printed nothing"


def test_the_core_never_imports_rclpy() -> None:
    """Only the node adapters may import rclpy or message packages: the rest must run without ROS."""
    import re

    pattern = re.compile(r"^\s*(from|import)\s+(rclpy|\w+_msgs|builtin_interfaces|rcl_interfaces)\b", re.M)
    offenders = [str(p.relative_to(REPO)) for p in (REPO / PACKAGE).rglob("*.py")
                 if "nodes" not in p.relative_to(REPO / PACKAGE).parts and pattern.search(p.read_text())]
    assert not offenders, offenders


def test_the_command_line_starts_without_torch() -> None:
    """``zebra-sim``'s parser (every command's options, the training augmentations and the verifier's settings
    among them) is built without importing torch: a command that needs no model (``--help``, ``generate``, ``up``,
    ``bag``) starts in about a second instead of four (torch's import, on our 2 cores); the commands that run a model
    import it when they run."""
    code = ("import sys; from zebra_sim_ros.cli import build_parser; build_parser(); "
            "print(sorted(m for m in ('torch', 'zebra_sim_ros.detection.data', 'zebra_sim_ros.detection.verify') "
            "if m in sys.modules))")
    run = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.strip() == "[]", run.stdout
