#!/usr/bin/env bash
# Set up (idempotent), then lint, type-check and test. Extra arguments go to pytest.
# ZEBRA_SIM_CPU=avx2 runs the tests as on a CPU without AVX-512 (scripts/cpu_avx2.env): our machines differ.
# OMP_NUM_THREADS is deliberately left as the caller has it (not set here); tests that start
# ROS processes choose their own ROS_DOMAIN_ID.
set -euo pipefail

cd "$(dirname "${BASH_SOURCE[0]}")/.."
case ${ZEBRA_SIM_CPU:-} in
    "") ;;
    # shellcheck source=scripts/cpu_avx2.env
    avx2) source scripts/cpu_avx2.env
          echo "[test] AVX-512 code paths off (ZEBRA_SIM_CPU=avx2: scripts/cpu_avx2.env)" ;;
    *) echo "[test] ZEBRA_SIM_CPU=$ZEBRA_SIM_CPU: want avx2 or nothing" >&2; exit 2 ;;
esac

bash scripts/setup.sh --no-messages

# The venv first on PATH, so tests that spawn tools (colcon, console scripts) get the venv's.
export PATH="$PWD/.venv/bin:$PATH"

echo "[test] ruff check ."
.venv/bin/ruff check .
# mypy (single-threaded, 40-45 s cold) beside the message packages' build (CMake's configure steps are serial too);
# it reads none of their files.
echo "[test] mypy, beside the message packages' build"
mypy_log="$(mktemp)"
.venv/bin/mypy >"$mypy_log" 2>&1 &
mypy_pid=$!
# a failed build or an interrupt (background jobs of a script ignore SIGINT) leaves no mypy running
trap 'kill "$mypy_pid" 2>/dev/null || true; rm -f "$mypy_log"' EXIT
bash scripts/build_interfaces.sh || { kill "$mypy_pid" 2>/dev/null || true; exit 1; }
mypy_rc=0
wait "$mypy_pid" || mypy_rc=$?
cat "$mypy_log"
((mypy_rc == 0)) || exit "$mypy_rc"
echo "[test] pytest $*"
rc=0
.venv/bin/python -m pytest "$@" || rc=$?
if ((rc == 5)); then
    echo "[test] error: pytest collected no tests; treating that as a failure" >&2
    exit 1
fi
exit "$rc"
