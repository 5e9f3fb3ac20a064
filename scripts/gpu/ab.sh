#!/usr/bin/env bash
# An A/B on a lent GPU machine inside one call of at most 10 minutes: two `train` runs side by side on `gpu_data/`
# (made by scripts/gpu/pack.py, carried with the tree), the same data, init, seed, epochs and recipe as train.sh's
# (320 px crops of 2176 px samples, K passes over the frames per epoch), arm a with A_OPTS and arm b with B_OPTS
# (e.g. A_OPTS=--p2: the stride-4 level against its control). Each arm gets half the loader processes. The epoch
# count is fixed (EPOCHS), not fitted to the budget, so that both arms see the same crops under the same schedule; if
# BUDGET ends them early, the snapshots of the epochs both finished still pair up. After every epoch an fp16 copy of
# each arm's last.pt (EMA weights) is kept; $OUT receives logs.tar.gz (each arm's train.log and results.csv) and,
# per arm, the snapshots of the last two epochs both arms finished: a/ep_N.pt, b/ep_N.pt.
#
# The P2 A/B of 2026-11-28 (BENCHMARKS.md, "A stride-4 level on a lent GPU"):
#   A_OPTS=--p2 AUG='--aug-zoom 0.5 --aug-background 0.3 --aug-zoom-crop 1 --aug-zoom-max 16' bash scripts/gpu/ab.sh
# A smoke test on a CPU: DEVICE=cpu K=1 MAXIMG=8 EPOCHS=2 BATCH=4 WORKERS=1 IMGSZ=640 bash scripts/gpu/ab.sh
# DATA names another pack folder than gpu_data (the arms' run folders and the mix file go there too).
set -u
cd "$(dirname "$0")/../.."
export PYTHONPATH=$PWD PYTHONUNBUFFERED=1 OPENCV_FOR_THREADS_NUM=1
T0=$(date +%s)
BUDGET=${BUDGET:-520}; EPOCHS=${EPOCHS:-5}; K=${K:-12}; IMGSZ=${IMGSZ:-2176}; CROP=${CROP:-320}; BATCH=${BATCH:-32}
WORKERS=${WORKERS:-7}; DEVICE=${DEVICE:-cuda}; LR=${LR:-0.004}; SEED=${SEED:-33}; MAXIMG=${MAXIMG:-0}
INIT=${INIT:-zebra_sim_ros/detection/weights/zebra_yolo_n.pt}; INIT_A=${INIT_A:-$INIT}; INIT_B=${INIT_B:-$INIT}
AUG=${AUG:---aug-zoom 0.5}; A_OPTS=${A_OPTS:-}; B_OPTS=${B_OPTS:-}
OUTD=${OUT:-/tmp/gpu_ab}; DATA=${DATA:-gpu_data}
for v in BUDGET EPOCHS K IMGSZ CROP BATCH WORKERS SEED; do  # whole numbers, at least 1
  [[ ${!v} =~ ^[1-9][0-9]*$ ]] || { echo "ab.sh: $v=${!v}: want a whole number >= 1" >&2; exit 2; }
done
[[ $MAXIMG =~ ^[0-9]+$ ]] || { echo "ab.sh: MAXIMG=$MAXIMG: want a whole number >= 0 (0: all)" >&2; exit 2; }
((BUDGET <= 580)) || { echo "ab.sh: BUDGET=$BUDGET: want at most 580 s (one call runs 600 s at most)" >&2; exit 2; }
[ "$A_OPTS" != "$B_OPTS" ] || { echo "ab.sh: A_OPTS and B_OPTS are the same ('$A_OPTS'): nothing to compare" >&2; exit 2; }
for v in INIT_A INIT_B; do [ -f "${!v}" ] || { echo "ab.sh: $v=${!v}: no such checkpoint" >&2; exit 2; }; done
[ -d "$DATA/train/images/train" ] || { echo "ab.sh: DATA=$DATA: no $DATA/train/images/train: run scripts/gpu/pack.py" >&2
  exit 2; }
mkdir -p "$OUTD"
elapsed() { echo $(( $(date +%s) - T0 )); }
python3 - "$K" "$DATA" <<'EOF'
import sys
k = int(sys.argv[1])
open(sys.argv[2] + '/ab_mix.yaml', 'w').write('path: .\ntrain: [' + ', '.join(['train/images/train'] * k)
                                        + ']\nval: val/images/val\nnc: 1\nnames:\n  0: zebra\n')
EOF
rows() { [ -f "$1/results.csv" ] && echo $(( $(wc -l < "$1/results.csv") - 1 )) || echo 0; }
arm() {  # $1 run folder, $2 the arm's options (as words), $3 its init
  rm -rf "$1"; mkdir -p "$1/snap"
  # shellcheck disable=SC2086  # AUG and the arm's options are words
  timeout --signal=TERM --kill-after=10 $((BUDGET - $(elapsed))) python3 -m zebra_sim_ros.cli train \
    --data "$DATA/ab_mix.yaml" --model n --imgsz "$IMGSZ" --crop "$CROP" --epochs "$EPOCHS" --batch "$BATCH" \
    --device "$DEVICE" --workers "$WORKERS" --lr0 "$LR" --warmup-epochs 0.5 --close-mosaic 1 --val-every 1000 \
    --save-period 0 --max-train-images "$MAXIMG" --seed "$SEED" --init "$3" $AUG $2 --out "$1" >"$1/train.log" 2>&1
  echo "[ab] $1 ended (exit $?) at $(elapsed) s, $(rows "$1") epochs" >>"$1/train.log"
}
snapper() {  # $1 run folder: an fp16 copy of last.pt after every epoch, until $1/snap.stop appears
  local done=0 n
  while sleep 1 && [ ! -f "$1/snap.stop" ]; do
    n=$(rows "$1")
    if [ "$n" -gt "$done" ] && [ -f "$1/last.pt" ] && [ "$1/last.pt" -nt "$1/results.csv" ]; then
      sleep 1; python3 -m zebra_sim_ros.cli export --weights "$1/last.pt" --format pt --out "$1/snap/ep_$n.pt" \
        >/dev/null && echo "[ab] snapshot epoch $n at $(elapsed) s" >>"$1/train.log"
      done=$n
    fi
  done
}
{ nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv 2>/dev/null; nproc
  python3 -c "import torch;print('torch',torch.__version__,'cuda',torch.cuda.is_available())"
  echo "A_OPTS='$A_OPTS' B_OPTS='$B_OPTS' AUG='$AUG' EPOCHS=$EPOCHS K=$K LR=$LR SEED=$SEED INIT_A=$INIT_A INIT_B=$INIT_B"
} >"$OUTD/machine.txt" 2>&1
A=$DATA/ab_a; B=$DATA/ab_b
arm $A "$A_OPTS" "$INIT_A" & PA=$!
arm $B "$B_OPTS" "$INIT_B" & PB=$!
snapper $A & SA=$!
snapper $B & SB=$!
wait $PA $PB
sleep 3; touch $A/snap.stop $B/snap.stop; wait $SA $SB
for r in $A $B; do  # the last epoch's snapshot, if the snapper stopped before it
  n=$(rows $r); if [ "$n" -gt 0 ] && [ -f $r/last.pt ] && [ ! -f $r/snap/ep_$n.pt ]; then
    python3 -m zebra_sim_ros.cli export --weights $r/last.pt --format pt --out $r/snap/ep_$n.pt >/dev/null; fi
done
n=$(( $(rows $A) < $(rows $B) ? $(rows $A) : $(rows $B) ))
mkdir -p "$OUTD/a" "$OUTD/b"
for e in $((n - 1)) $n; do
  [ "$e" -ge 1 ] || continue
  for arm in a b; do [ -f "$DATA/ab_$arm/snap/ep_$e.pt" ] && cp "$DATA/ab_$arm/snap/ep_$e.pt" "$OUTD/$arm/"; done
done
tar -czf "$OUTD/logs.tar.gz" $A/train.log $A/results.csv $B/train.log $B/results.csv 2>/dev/null
echo "[ab] done at $(elapsed) s; both arms finished $n epochs; sent: $(cd "$OUTD" && find . -type f | sort | tr '\n' ' ')"
for r in $A $B; do echo "== $r"; tr '\r' '\n' <$r/train.log | grep -v "^\[train\] epoch [0-9]*/[0-9]* [0-9]*/" | tail -8; done
