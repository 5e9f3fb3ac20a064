#!/usr/bin/env bash
# Set up (idempotent), then run the main job on the built-in default world (savanna): the whole ROS 2 graph
# (placer, three cameras, labeller, detector with the shipped weights, scorer, recorder) for 10 lockstep steps with
# `zebra-sim up`, which prints frames per drone, detection scores against the live ground truth, throughput and
# stage times, and writes the bag, summary.json and a preview (RGB with ground-truth and detected boxes).
set -euo pipefail

cd "$(dirname "${BASH_SOURCE[0]}")/.."
bash scripts/setup.sh

mkdir -p out
.venv/bin/zebra-sim asset build
.venv/bin/zebra-sim asset preview out/zebra_preview.png
# A private DDS domain on this host only, so the run neither sees nor disturbs other ROS 2 graphs.
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
.venv/bin/zebra-sim up --frames "${FRAMES:-10}" --world savanna --seed 0 --out out/up \
    --domain-id "${ROS_DOMAIN_ID:-42}"
echo "[main] bag:     $PWD/out/up/zebra_sim.mcap   (zebra-sim bag info / eval, ros2 bag, Foxglove)"
echo "[main] preview: $PWD/out/up/preview.jpg   (per drone: green = ground truth, red = detected)"
echo "[main] summary: $PWD/out/up/summary.json   logs: $PWD/out/up/logs/"
echo "[main] zebra preview: $PWD/out/zebra_preview.png"
