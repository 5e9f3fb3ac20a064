#!/usr/bin/env bash
# Set up (idempotent), then run the main job on the built-in default world (savanna): build the zebra asset and
# its preview sheet, then place zebras and render the three drone views of one step (RGB, depth, masks).
set -euo pipefail

cd "$(dirname "${BASH_SOURCE[0]}")/.."
bash scripts/setup.sh

mkdir -p out
.venv/bin/zebra-sim asset build
.venv/bin/zebra-sim asset preview out/zebra_preview.png
.venv/bin/zebra-sim render --seed 0 --world savanna --out out/render
echo "[main] zebra preview: $PWD/out/zebra_preview.png"
echo "[main] three drone views of step 0 (RGB, depth, instance masks, scene.json): $PWD/out/render/preview.png"
