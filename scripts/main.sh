#!/usr/bin/env bash
# Set up (idempotent), then run the main job with the venv's console script.
set -euo pipefail

cd "$(dirname "${BASH_SOURCE[0]}")/.."
bash scripts/setup.sh

mkdir -p out
.venv/bin/zebra-sim asset build
.venv/bin/zebra-sim asset preview out/zebra_preview.png
echo "[main] preview written to $PWD/out/zebra_preview.png"
