#!/usr/bin/env bash
# Build the message packages under interfaces/ into the venv (prefix .venv: libraries in .venv/lib, Python in its
# site-packages, .msg texts in .venv/share/<pkg>/msg), with CMake and the rosidl generators from PyPI. Idempotent:
# a package is rebuilt only when its sources (or this script) change. tf2_msgs and rosbag2_interfaces (the services
# the replay and the recorder serve, as ros2 bag's) are built only where no other can be imported (a ROS 2 install
# that has geometry2 or rosbag2 keeps its own). Only the C and Python code is generated
# (-DZEBRA_SIM_PYTHON_ONLY=ON, interfaces/python_includes.cmake): rclpy loads the C typesupports, and the C++ ones
# were a third of the build's time (benchmarks/bench_interfaces_build.py). Needs cmake and a C/C++ compiler
# (scripts/setup.sh installs them). Usage: bash scripts/build_interfaces.sh [--force]
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
ROOT="$PWD"
VENV="$ROOT/.venv"
PY="$VENV/bin/python"
BUILD="$ROOT/build/interfaces"
log() { echo "[interfaces] $*"; }
force=0
[[ "${1:-}" == "--force" ]] && force=1

# The typesupport packages of the PyPI wheels do not register themselves in the ament index, which
# rosidl_generate_interfaces reads to learn which typesupports to generate: register them in a private prefix.
MARKERS="$BUILD/markers/share/ament_index/resource_index"
mkdir -p "$MARKERS/rosidl_typesupport_c" "$MARKERS/rosidl_typesupport_cpp" "$MARKERS/packages"
for t in rosidl_typesupport_fastrtps_c rosidl_typesupport_introspection_c; do
    touch "$MARKERS/rosidl_typesupport_c/$t"
done
for t in rosidl_typesupport_fastrtps_cpp rosidl_typesupport_introspection_cpp; do
    touch "$MARKERS/rosidl_typesupport_cpp/$t"
done
touch "$MARKERS/packages/zebra_sim_ros_typesupport_markers"
export AMENT_PREFIX_PATH="$BUILD/markers:$VENV"
export CMAKE_PREFIX_PATH="$VENV"
export PATH="$VENV/bin:$PATH"

shopt -s nullglob
for pkg in tf2_msgs rosbag2_interfaces zebra_sim_msgs; do
    src="$ROOT/interfaces/$pkg"
    stamp="$VENV/share/$pkg/.zebra_sim_build_stamp"
    want="$(cat "$ROOT/scripts/build_interfaces.sh" "$ROOT/interfaces/python_includes.cmake" "$src/CMakeLists.txt" \
        "$src/package.xml" "$src"/msg/*.msg "$src"/srv/*.srv | sha256sum | cut -d' ' -f1)"
    kind=msg
    [[ -d "$src/msg" ]] || kind=srv
    if ((force == 0)) && [[ "$(cat "$stamp" 2>/dev/null || true)" == "$want" ]]; then
        log "$pkg up to date"
        continue
    fi
    if [[ "$pkg" != zebra_sim_msgs && ! -f "$stamp" ]] && "$PY" -c "import $pkg.$kind" 2>/dev/null; then
        log "$pkg comes from this ROS 2 install: not built"
        continue
    fi
    log "building $pkg"
    # what the last build installed goes first (its install manifest), so no file of an older build (C++ headers and
    # typesupports built before -DZEBRA_SIM_PYTHON_ONLY, or a removed message's code) stays in the venv
    if [[ -f "$BUILD/$pkg/install_manifest.txt" ]]; then
        xargs -d '\n' rm -f < "$BUILD/$pkg/install_manifest.txt"
    fi
    rm -rf "$BUILD/$pkg"
    if ! { cmake -S "$src" -B "$BUILD/$pkg" -DCMAKE_INSTALL_PREFIX="$VENV" -DPython3_EXECUTABLE="$PY" \
              -DBUILD_TESTING=OFF -DCMAKE_BUILD_TYPE=Release -DZEBRA_SIM_PYTHON_ONLY=ON \
           && cmake --build "$BUILD/$pkg" -j "$(nproc)" \
           && cmake --install "$BUILD/$pkg"; } >"$BUILD/$pkg.log" 2>&1; then
        tail -30 "$BUILD/$pkg.log" >&2
        echo "[interfaces] error: building $pkg failed (full log: $BUILD/$pkg.log)" >&2
        exit 1
    fi
    "$PY" -c "import importlib; importlib.import_module('$pkg.$kind')" \
        || { echo "[interfaces] error: $pkg was built but does not import" >&2; exit 1; }
    echo "$want" >"$stamp"
done
log "done"
