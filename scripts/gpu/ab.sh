#!/usr/bin/env bash
# An A/B on a lent GPU machine inside one call of at most 10 minutes: two `train` runs side by side on a pack made by
# scripts/gpu/pack.py (DATA, default gpu_data/, carried with the tree), the same data, seed, epochs and recipe as
# train.sh's (320 px crops of 2176 px samples, K passes over the frames per epoch), arm a with A_OPTS and arm b with
# B_OPTS (e.g. A_OPTS=--p2: the stride-4 level against its control). Each arm gets half the loader processes and
# THREADS torch threads (default half the cores; with all of them each, two arms on 2 cores trained 3-4x slower, their
# threads spinning against each other), and starts from INIT_A / INIT_B (default INIT, the shipped weights; none: from
# scratch). The epoch count is fixed (EPOCHS), not fitted to the budget, so that both arms see the same crops under
# the same schedule; if BUDGET ends them early, the snapshots of the epochs both finished still pair up. As each arm's
# last.pt (EMA weights) lands, a hard link keeps it (the trainer replaces it by a rename, so a link is always a whole
# checkpoint); at the end scripts/gpu/snapshots.py names them by the epoch they hold and exports the last two epochs
# both arms reached as fp16 snapshots, snap/ep_N.pt in each run folder (a next call's INIT_A / INIT_B). $OUT receives
# machine.txt (the machine and the settings), logs.tar.gz (each arm's train.log and results.csv) and the pairs:
# a/ep_N.pt, b/ep_N.pt. The exit status is 0 only if both arms trained all EPOCHS.
# Relative paths (DATA, INIT_A, INIT_B, OUT) are taken from the repository's root.
#
# The P2 A/B of 2026-11-28 (BENCHMARKS.md, "A stride-4 (P2) level on a lent GPU, 101k crops against a control"):
#   A='--aug-zoom 0.5 --aug-background 0.3 --aug-zoom-crop 1 --aug-zoom-max 16'
#   A_OPTS=--p2 AUG="$A" BUDGET=520 bash scripts/gpu/ab.sh                       # call 1
#   INIT_A=gpu_data/ab_a/snap/ep_5.pt INIT_B=gpu_data/ab_b/snap/ep_5.pt A_OPTS=--p2 AUG="$A" LR=0.002 SEED=34 \
#       BUDGET=400 bash scripts/gpu/ab.sh                                         # call 2, on the same machine
# A smoke test on a CPU: DEVICE=cpu A_OPTS=--p2 K=1 MAXIMG=8 EPOCHS=2 BATCH=4 WORKERS=1 IMGSZ=640 bash scripts/gpu/ab.sh
set -u
cd "$(dirname "$0")/../.."
# shellcheck source=scripts/gpu/lib.sh
source scripts/gpu/lib.sh  # the environment, the clock (elapsed) and the helpers both scripts use
BUDGET=${BUDGET:-520}; EPOCHS=${EPOCHS:-5}; K=${K:-12}; IMGSZ=${IMGSZ:-2176}; CROP=${CROP:-320}; BATCH=${BATCH:-32}
WORKERS=${WORKERS:-7}; DEVICE=${DEVICE:-cuda}; LR=${LR:-0.004}; SEED=${SEED:-33}; MAXIMG=${MAXIMG:-0}
CORES=$(env -u OMP_NUM_THREADS -u OMP_THREAD_LIMIT nproc)  # nproc would answer OMP_NUM_THREADS if set
THREADS=${THREADS:-$(( CORES / 2 > 0 ? CORES / 2 : 1 ))}  # each arm's torch threads: half the cores
INIT=${INIT:-zebra_sim_ros/detection/weights/zebra_yolo_n.pt}; INIT_A=${INIT_A:-$INIT}; INIT_B=${INIT_B:-$INIT}
AUG=${AUG:---aug-zoom 0.5}; A_OPTS=${A_OPTS:-}; B_OPTS=${B_OPTS:-}
OUTD=${OUT:-/tmp/gpu_ab}; DATA=${DATA:-gpu_data}
whole_numbers ab.sh BUDGET EPOCHS K IMGSZ CROP BATCH WORKERS SEED THREADS
[[ $MAXIMG =~ ^[0-9]+$ ]] || { echo "ab.sh: MAXIMG=$MAXIMG: want a whole number >= 0 (0: all)" >&2; exit 2; }
# one call runs 600 s at most; after the budget come the kill's grace (10 s), the last exports and the copies
((BUDGET <= 540)) || { echo "ab.sh: BUDGET=$BUDGET: want at most 540 s (one call runs 600 s at most)" >&2; exit 2; }
[ "$A_OPTS" != "$B_OPTS" ] || { echo "ab.sh: A_OPTS and B_OPTS are the same ('$A_OPTS'): nothing to compare" >&2; exit 2; }
for v in INIT_A INIT_B; do
  [ "${!v}" = none ] || [ -f "${!v}" ] || { echo "ab.sh: $v=${!v}: no such checkpoint (none: from scratch)" >&2; exit 2; }
done
[ -d "$DATA/train/images/train" ] || { echo "ab.sh: DATA=$DATA: no $DATA/train/images/train: run scripts/gpu/pack.py" >&2
  exit 2; }
mkdir -p "$OUTD"
A=$DATA/ab_a; B=$DATA/ab_b
# the starting checkpoints beside the run folders, which are emptied next (an INIT may lie in one: a snapshot of the
# last call); the sources as given are what machine.txt records
SRC_A=$INIT_A; SRC_B=$INIT_B
for arm in a b; do
  v=INIT_${arm^^}; init=${!v}; [ "$init" != none ] || continue
  rm -f "$DATA/ab_init_$arm.pt"
  cp "$init" "$DATA/ab_init_$arm.pt.tmp" && mv "$DATA/ab_init_$arm.pt.tmp" "$DATA/ab_init_$arm.pt" \
    || { echo "ab.sh: $v=$init: could not be copied to $DATA" >&2; exit 1; }
  printf -v "$v" '%s' "$DATA/ab_init_$arm.pt"
done
for r in "$A" "$B"; do rm -rf "$r"; mkdir -p "$r/snap"; done
write_mix "$K" "$DATA/ab_mix.yaml"
arm() {  # $1 run folder, $2 the arm's options (as words), $3 its init (none: from scratch); its exit code to $1/rc
  local start=() left=$((BUDGET - $(elapsed)))
  [ "$3" = none ] || start=(--init "$3")
  if [ -f "$1/snap.stop" ] || ((left < 10)); then
    echo "ab.sh: $1: stopped or $left s of BUDGET left: not started" >"$1/train.log"; echo 124 >"$1/rc"; return
  fi
  # shellcheck disable=SC2086  # AUG and the arm's options are words
  OMP_NUM_THREADS=$THREADS timeout --signal=TERM --kill-after=10 "$left" python3 -m zebra_sim_ros.cli train \
    --data "$DATA/ab_mix.yaml" --model n --imgsz "$IMGSZ" --crop "$CROP" --epochs "$EPOCHS" --batch "$BATCH" \
    --device "$DEVICE" --workers "$WORKERS" --lr0 "$LR" --warmup-epochs 0.5 --close-mosaic 1 --val-every 1000 \
    --save-period 0 --max-train-images "$MAXIMG" --seed "$SEED" "${start[@]}" $AUG $2 --out "$1" >"$1/train.log" 2>&1
  echo $? >"$1/rc"
}
stop_all() {  # the trainers (through their timeout, which passes it on to its process group) and the watches on last.pt
  touch "$A/snap.stop" "$B/snap.stop" 2>/dev/null
  for p in ${PA:-} ${PB:-}; do pkill -TERM -P "$p" timeout 2>/dev/null; done
}
trap 'stop_all; exit 130' INT
trap 'stop_all; exit 143' TERM
trap 'touch "$A/snap.stop" "$B/snap.stop" 2>/dev/null' EXIT
{ nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv 2>/dev/null; echo "$CORES"
  python3 -c "import torch;print('torch',torch.__version__,'cuda',torch.cuda.is_available())"
  echo "A_OPTS='$A_OPTS' B_OPTS='$B_OPTS' AUG='$AUG' EPOCHS=$EPOCHS K=$K LR=$LR SEED=$SEED INIT_A=$SRC_A INIT_B=$SRC_B"
  echo "THREADS=$THREADS (torch threads per arm)"
} >"$OUTD/machine.txt" 2>&1
arm "$A" "$A_OPTS" "$INIT_A" & PA=$!
arm "$B" "$B_OPTS" "$INIT_B" & PB=$!
each_new_last "$A" 0.2 & SA=$!  # a hard link to each last.pt as it lands: snapshots.py names them by epoch
each_new_last "$B" 0.2 & SB=$!
# an arm that fails before its last epoch stops the other: the pair could not be compared past it
wait -n "$PA" "$PB"
for r in "$A" "$B"; do
  if [ -f "$r/rc" ] && [ "$(cat "$r/rc")" != 0 ] && [ "$(rows_of "$r")" -lt "$EPOCHS" ]; then
    echo "[ab] $r failed (exit $(cat "$r/rc")) after $(rows_of "$r") epochs at $(elapsed) s: stopping the other arm"
    for p in $PA $PB; do pkill -TERM -P "$p" timeout 2>/dev/null; done
  fi
done
wait "$PA" "$PB"
touch "$A/snap.stop" "$B/snap.stop"; wait "$SA" "$SB"
for r in "$A" "$B"; do [ -f "$r/last.pt" ] && ln -f "$r/last.pt" "$r/snap/raw_last.pt"; done  # in case it was missed
python3 scripts/gpu/snapshots.py pair "$A" "$B" --out "$OUTD" --want "$EPOCHS"; snaps=$?
logs=(); for f in ab_a/train.log ab_a/results.csv ab_b/train.log ab_b/results.csv; do
  [ -f "$DATA/$f" ] && logs+=("$f"); done
tar -C "$DATA" -czf "$OUTD/logs.tar.gz" "${logs[@]}"
echo "[ab] done at $(elapsed) s; sent: $(cd "$OUTD" && find . -type f | sort | tr '\n' ' ')"
for r in "$A" "$B"; do
  echo "== $r (exit $(cat "$r/rc" 2>/dev/null || echo '?'))"
  tr '\r' '\n' <"$r/train.log" | grep -v "^\[train\] epoch [0-9]*/[0-9]* [0-9]*/" | tail -8
done
rc_a=$(cat "$A/rc" 2>/dev/null || echo 1); rc_b=$(cat "$B/rc" 2>/dev/null || echo 1)
[ "$rc_a" = 0 ] && [ "$rc_b" = 0 ] && [ "$snaps" = 0 ]
