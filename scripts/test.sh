#!/usr/bin/env bash
# Set up (idempotent), then lint, type-check and test. Extra arguments go to pytest.
# OMP_NUM_THREADS is deliberately left as the caller has it (not set here); tests that start
# ROS processes choose their own ROS_DOMAIN_ID.
set -euo pipefail

cd "$(dirname "${BASH_SOURCE[0]}")/.."
bash scripts/setup.sh

# The venv first on PATH, so tests that spawn tools (colcon, console scripts) get the venv's.
export PATH="$PWD/.venv/bin:$PATH"

echo "[test] ruff check ."
.venv/bin/ruff check .
echo "[test] mypy"
.venv/bin/mypy
echo "[test] pytest $*"
rc=0
.venv/bin/python -m pytest "$@" || rc=$?
if ((rc == 5)); then
    echo "[test] error: pytest collected no tests; treating that as a failure" >&2
    exit 1
fi
exit "$rc"
