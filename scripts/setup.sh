#!/usr/bin/env bash
# Idempotent set-up: Debian EGL/Mesa libraries for headless rendering, the .venv, and the
# Python dependencies (torch pinned to the local CPU build). Safe to run repeatedly; the
# second run is a few seconds. Works from any directory.
# Usage: bash scripts/setup.sh [--no-messages]   (--no-messages: all but step (d), which scripts/test.sh then runs
# itself, beside mypy)
set -euo pipefail

messages=1
case ${1:-} in
    "") ;;
    --no-messages) messages=0 ;;
    *) echo "[setup] error: unknown option '$1' (want --no-messages or nothing)" >&2; exit 2 ;;
esac

cd "$(dirname "${BASH_SOURCE[0]}")/.."
ROOT="$PWD"
VENV="$ROOT/.venv"
STAMP="$VENV/.zebra_sim_setup_stamp"

log() { echo "[setup] $*"; }
die() { echo "[setup] error: $*" >&2; exit 1; }

# (a) System libraries for moderngl on headless EGL (Mesa llvmpipe without a GPU), and CMake and a C++ compiler
# for the message packages under interfaces/. opencv is the headless wheel, which needs no libGL or glib.
APT_PACKAGES=(libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri cmake g++)
if ! command -v dpkg-query >/dev/null 2>&1; then
    log "no dpkg here: make sure EGL and Mesa (${APT_PACKAGES[*]}) are installed"
else
    missing=()
    for pkg in "${APT_PACKAGES[@]}"; do
        status="$(dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null || true)"
        [[ "$status" == "install ok installed" ]] || missing+=("$pkg")
    done
    if ((${#missing[@]} == 0)); then
        log "system libraries present (${APT_PACKAGES[*]})"
    else
        log "installing system libraries: ${missing[*]}"
        SUDO=()
        if [[ "$(id -u)" -ne 0 ]]; then
            command -v sudo >/dev/null 2>&1 || die "need root or sudo to install: ${missing[*]}"
            SUDO=(sudo)
        fi
        "${SUDO[@]}" apt-get update -qq
        "${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive \
            apt-get install -y -qq --no-install-recommends "${missing[@]}"
    fi
fi

# (b) The virtual environment, on Python >= 3.11.
if [[ ! -x "$VENV/bin/python" ]]; then
    PY=""
    if command -v python3.11 >/dev/null 2>&1; then
        PY=python3.11
    elif command -v python3 >/dev/null 2>&1 \
        && python3 -c 'import sys; raise SystemExit(sys.version_info < (3, 11))'; then
        PY=python3
    else
        die "need Python >= 3.11 (python3.11 or python3); found: $(python3 --version 2>&1 || echo none)"
    fi
    log "creating .venv with $PY ($("$PY" --version 2>&1))"
    "$PY" -m venv "$VENV" || die "'$PY -m venv' failed (on Debian: apt-get install python3-venv)"
else
    log ".venv present ($("$VENV/bin/python" --version 2>&1))"
fi

# (c) Python packages, skipped when the inputs have not changed since the last success.
want="$(cat requirements.txt requirements-interfaces.txt setup.py setup.cfg | sha256sum | cut -d' ' -f1)"
have="$(cat "$STAMP" 2>/dev/null || true)"
if [[ "$want" == "$have" && -x "$VENV/bin/zebra-sim" ]]; then
    log "python packages up to date (stamp matches)"
else
    # --no-compile: pip compiles what it installs one file at a time (torch alone: 38 s against 11 s without); the
    # whole venv is compiled once below on every core instead.
    PIP=("$VENV/bin/python" -m pip install -q --no-compile)
    # torch first and pinned: 2.13.0 resolves to the local CPU build; unpinned, pip would
    # fetch several GB of CUDA packages.
    log "pip: torch==2.13.0 (CPU build)"
    "${PIP[@]}" "torch==2.13.0"
    log "pip: requirements.txt"
    "${PIP[@]}" -r requirements.txt
    # --no-deps: their metadata asks for newer ROS runtime libraries (rcutils, rmw, rosidl) than Jazzy's, which
    # would replace the ones rclpy was built against; the build needs only these CMake and Python helpers.
    log "pip: requirements-interfaces.txt (to build the message packages; without their dependencies)"
    "${PIP[@]}" --no-deps -r requirements-interfaces.txt
    log "pip: zebra_sim_ros (editable; console scripts in .venv/bin)"
    "${PIP[@]}" --no-deps -e .
    # The bytecode pip was told not to write, on every core (-j0). Where PYTHONDONTWRITEBYTECODE=1 nothing else would
    # write it, and every process would compile torch's modules again. As pip does, files that do not compile (a
    # package's Python 2 examples, say) are left as they are.
    log "compiling the installed packages' bytecode"
    # compileall exits 1 when any file does not compile (pip skips those too); one that wrote nothing (no process
    # pool, say) is run again on one core
    clog="$VENV/compileall.log"
    torch_pyc='*/site-packages/torch/__pycache__/__init__.cpython-*.pyc'
    if ! "$VENV/bin/python" -m compileall -q -j0 "$VENV" >"$clog" 2>&1; then
        if [[ -z "$(find "$VENV" -path "$torch_pyc" -print -quit)" ]]; then
            log "compileall -j0 wrote no bytecode (not even torch's); again on one core"
            "$VENV/bin/python" -m compileall -q "$VENV" >"$clog" 2>&1 || true
        fi
        log "compileall: $(grep -c '^\*\*\*' "$clog" || true) installed files do not compile, as pip allows ($clog)"
    fi
    echo "$want" >"$STAMP"
fi
# (d) The message packages (tf2_msgs/TFMessage where ROS 2's own is missing, zebra_sim_msgs/Detection2DArray),
# built into the venv; skipped when their sources have not changed.
if ((messages)); then
    bash scripts/build_interfaces.sh
else
    log "message packages left to the caller (--no-messages)"
fi
# (e) The package's own bytecode. The installed packages were compiled above, but our package is installed editable,
# and where PYTHONDONTWRITEBYTECODE=1 (as on our machines) Python never writes a .pyc itself: every process (each node,
# each CLI call) would compile the modules it imports, about 0.4 s for a node's. compileall writes only stale files.
"$VENV/bin/python" -m compileall -q zebra_sim_ros >/dev/null || die "compileall zebra_sim_ros failed"
log "done"
