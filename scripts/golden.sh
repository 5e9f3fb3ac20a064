#!/usr/bin/env bash
# Golden outputs for refactors that must not change behaviour: sha256 of a `render --seed 5` (instance masks,
# depth, scene.json), of a 6-frame `generate` (labels, ignore boxes, COCO) and of a 3-step `up` bag's messages
# (per topic: the serialised payloads, sorted so that arrival order does not count, read back with rosbags). Run it before and after a
# change and diff the two listings. Usage: bash scripts/golden.sh OUT_DIR > hashes.txt
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
out="${1:?usage: scripts/golden.sh OUT_DIR}"
rm -rf "$out" && mkdir -p "$out"
zs=.venv/bin/zebra-sim
$zs render --seed 5 --out "$out/render" >/dev/null
$zs generate --frames 6 --seed 7 --workers 1 --out "$out/generate" >/dev/null 2>&1
ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST $zs up --frames 3 --size 320x180 --seed 3 --out "$out/up" \
    --domain-id "${GOLDEN_DOMAIN_ID:-61}" >/dev/null 2>&1
(cd "$out/render" && sha256sum -- *_instances.png *_depth.npy *_depth_mm.png scene.json camera_info.json)
(cd "$out/generate" && find labels ignore coco annotations -type f | sort | xargs sha256sum)
.venv/bin/python - "$out/up/zebra_sim.mcap" <<'PY'
import hashlib
import sys
from pathlib import Path

from rosbags.highlevel import AnyReader

payloads: dict[str, list[bytes]] = {}
with AnyReader([Path(sys.argv[1])]) as reader:
    for conn, _t, raw in reader.messages():
        payloads.setdefault(conn.topic, []).append(bytes(raw))
for topic, raws in sorted(payloads.items()):
    digest = hashlib.sha256(b"".join(sorted(raws))).hexdigest()
    print(f"{digest}  up:{topic} ({len(raws)} messages)")
PY
