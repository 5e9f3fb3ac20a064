#!/usr/bin/env bash
# Fine-tune on a lent GPU machine, inside one call of at most 10 minutes: `gpu_data/` (made by scripts/gpu/pack.py,
# carried with the tree) trained as 320 px crops of 2176 px samples for as many epochs as fit in BUDGET seconds. The
# run starts with E0 epochs; the second epoch is timed and the run resumes with the epoch count that fits. After
# every epoch an fp16 copy of last.pt (EMA weights, no optimizer) is kept; $OUT receives train.log, results.csv, the
# latest snapshot (last_snap.pt), best.pt (the last epoch, validated on gpu_data/val) and snapshots (snap/: one from
# the middle of the run and the two before the last), as many as the machine sends back (8 files of 16 MiB at most,
# 64 MiB together): a file over 15 MiB (an s snapshot: 22 MB) travels as 15 MiB parts NAME.part00, NAME.part01, ...
# (join them with `cat NAME.part* > NAME`). Each epoch is K passes over the frames (one crop per frame per pass), so
# that the data loader's workers, which restart each epoch, are not started every few seconds.
#
# Stage 12 (README, "Shipped weights"): run a `BUDGET=480 bash scripts/gpu/train.sh` (stage 11 init, lr0 0.004,
# seed 16), run b `BUDGET=280 E0=4 LR=0.002 SEED=17 INIT=gpu_data/init.pt bash scripts/gpu/train.sh` (init: run a's
# last snapshot). AUG holds the augmentation options passed to train, e.g. stage 14's
# AUG='--aug-zoom 0.5 --aug-background 0.3 --aug-zoom-crop 1 --aug-zoom-max 16'. P2=1 trains with a stride-4 level
# (`train --p2`); from a three-level INIT (the shipped weights) the other levels start from it and the new one fresh.
# MODEL=s trains the small model: from the nano's weights (the default INIT) widened to it (`train --init` keeps their
# function: README, "The small model from the nano"), from scratch (INIT=none) or from an s checkpoint (a snapshot an
# earlier call sent back, to go on from it in the next call).
set -u
cd "$(dirname "$0")/../.."
# shellcheck source=scripts/gpu/lib.sh
source scripts/gpu/lib.sh  # the environment, the clock (elapsed) and the helpers both scripts use
BUDGET=${BUDGET:-470}; K=${K:-24}; E0=${E0:-12}; IMGSZ=${IMGSZ:-2176}; CROP=${CROP:-320}; BATCH=${BATCH:-32}
WORKERS=${WORKERS:-15}; DEVICE=${DEVICE:-cuda}; OUTD=${OUT:-/tmp/gpu_out}; LR=${LR:-0.004}; SEED=${SEED:-16}
INIT=${INIT:-zebra_sim_ros/detection/weights/zebra_yolo_n.pt}
AUG=${AUG:---aug-zoom 0.5}  # the train options of augmentation, as words (stage 12's by default)
P2=${P2:-0}; MODEL=${MODEL:-n}; DATA=${DATA:-gpu_data}  # DATA: another pack folder (its run_out/ and mix file go there)
case $MODEL in n|s) ;; *) echo "train.sh: MODEL=$MODEL: want n or s" >&2; exit 2 ;; esac
case $P2 in 0) ARCH= ;; 1) ARCH=--p2 ;; *) echo "train.sh: P2=$P2: want 0 or 1" >&2; exit 2 ;; esac
whole_numbers train.sh BUDGET K E0 IMGSZ CROP BATCH WORKERS SEED
((BUDGET <= 590)) || { echo "train.sh: BUDGET=$BUDGET: want at most 590 s (one call runs 600 s at most)" >&2; exit 2; }
if [ "$INIT" = none ]; then START=; else
  [ -f "$INIT" ] || { echo "train.sh: INIT=$INIT: no such checkpoint (none: from scratch)" >&2; exit 2; }
  START="--init $INIT"
fi
[ -d "$DATA/train/images/train" ] || { echo "train.sh: DATA=$DATA: no $DATA/train/images/train: run scripts/gpu/pack.py" >&2
  exit 2; }
RUN=$DATA/run_out; rm -rf "$RUN"; mkdir -p "$RUN/snap" "$OUTD/snap"
LOG=$OUTD/train.log
{ nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv 2>/dev/null; nproc
  python3 -c "import torch,cv2,numpy,yaml;print('torch',torch.__version__,'cuda',torch.cuda.is_available(),'cv2',cv2.__version__,'numpy',numpy.__version__)"
} >"$LOG" 2>&1
write_mix "$K" "$DATA/mix.yaml"
train() {  # $1 epochs, $2 seconds allowed, $3 --init WEIGHTS, --resume or nothing (from scratch)
  timeout --signal=TERM --kill-after=10 "$2" python3 -m zebra_sim_ros.cli train --data "$DATA/mix.yaml" --model "$MODEL" \
    --imgsz "$IMGSZ" --crop "$CROP" --epochs "$1" --batch "$BATCH" --device "$DEVICE" --workers "$WORKERS" \
    --amp "$AMP" --lr0 "$LR" --warmup-epochs 0.5 --close-mosaic 1 --val-every 1000 --seed "$SEED" \
    $AUG $ARCH --out "$RUN" $3 >>"$LOG" 2>&1
}
deliver() {  # $1 -> $OUTD/$2, in 15 MiB parts ($2.part00, ...) where it is larger; the old copy or parts go first;
  # the status says whether it was sent
  rm -f "$OUTD/$2" "$OUTD/$2".part*
  if [ "$(stat -c %s "$1")" -le 15728640 ]; then cp "$1" "$OUTD/$2"; return; fi
  local t rc; t=$(mktemp -d "$RUN/parts.XXXXXX") || return
  split -b 15M -d -a 2 "$1" "$t/$(basename "$2").part" && mv "$t"/* "$(dirname "$OUTD/$2")/"; rc=$?
  rm -rf "$t"; return $rc
}
rows() { rows_of "$RUN"; }
snap_one() {  # $1 a link to a last.pt: exported as snap/ep_N.pt (N the epoch it holds) and delivered as
  # last_snap.pt; snap/exported keeps its inode (the last one sent); a failed one is kept as snap/failed_*.pt
  local n
  if n=$(python3 scripts/gpu/snapshots.py one "$1" "$RUN"/snap) && deliver "$RUN"/snap/ep_$n.pt last_snap.pt; then
    ln -f "$1" "$RUN"/snap/exported && rm -f "$1"
    echo "[run] snapshot epoch $n at $(elapsed) s" >>"$LOG"
  else
    mv -f "$1" "$RUN/snap/failed_${1##*/raw_}"
    echo "[run] the snapshot of $1 failed at $(elapsed) s (the link kept as failed_${1##*/raw_})" >>"$LOG"
  fi
}
each_new_last "$RUN" 0.2 & SNAP=$!  # a hard link to every last.pt the trainer writes, as it lands
export_links "$RUN" "$SNAP" "$LOG" & EXPORT=$!  # each link through snap_one, behind the watch
AMP=auto
wait_rows() {  # until the trainer has written epoch $1's results and last.pt, or has stopped
  while kill -0 $TR 2>/dev/null; do
    [ "$(rows)" -ge "$1" ] && [ -f "$RUN"/last.pt ] && [ "$RUN"/last.pt -nt "$RUN"/results.csv ] && return 0
    sleep 1
  done
  [ "$(rows)" -ge "$1" ]
}
stop_train() {  # TERM to this run's trainer only (the timeout under the background job passes it on), then wait
  pkill -TERM -P "$TR" timeout || kill -TERM "$TR"; wait "$TR"
}
train "$E0" $((BUDGET - $(elapsed))) "$START" & TR=$!
if ! wait_rows 1; then  # the first start failed: once more in float32
  echo "[run] the first start failed at $(elapsed) s; again with --amp off" >>"$LOG"
  AMP=off; rm -rf "$RUN"/last.pt "$RUN"/results.csv
  train "$E0" $((BUDGET - $(elapsed))) "$START" & TR=$!
fi
if wait_rows 1; then
  T1=$(date +%s)
  if wait_rows 2; then
    D=$(( $(date +%s) - T1 ))
    E=$(python3 -c "print(max(3, min(80, 2 + int(0.92 * ($BUDGET - $(elapsed) - 30) / max($D, 1)))))")
    echo "[run] epoch 2 took ${D} s; $(elapsed) s gone; $E epochs fit" >>"$LOG"
    if [ "$E" != "$E0" ]; then
      stop_train
      train "$E" $((BUDGET - $(elapsed))) --resume
    else
      wait $TR
    fi
  fi
fi
echo "[run] training ended at $(elapsed) s, rows $(rows)" >>"$LOG"
sleep 1; touch "$RUN"/snap.stop; wait $SNAP; wait $EXPORT  # the watch stops, then the exports left are done
# the last epoch, where the watch had not sent it: last_snap.pt is the last epoch trained
if [ -f "$RUN"/last.pt ] && ! [ "$RUN"/last.pt -ef "$RUN"/snap/exported ]; then
  ln -f "$RUN"/last.pt "$RUN"/snap/raw_last.pt && snap_one "$RUN"/snap/raw_last.pt
fi
ls "$RUN"/snap >>"$LOG"
cp "$RUN"/results.csv "$OUTD/" 2>/dev/null
# then snapshots, one from the middle of the run and the two before the last, and best.pt, while 8 files and 60 MiB
# hold them (the log, results.csv and last_snap.pt's parts counted first)
mapfile -t SEND < <(python3 scripts/gpu/snapshots.py pick "$RUN" "$OUTD")
for f in "${SEND[@]}"; do
  case $f in */best.pt) deliver "$f" best.pt ;; *) deliver "$f" "snap/$(basename "$f")" ;; esac
done
echo "[run] sent back: $(cd "$OUTD" && find . -type f | sort | tr '\n' ' ')" >>"$LOG"
echo "[run] done at $(elapsed) s" >>"$LOG"
tail -40 "$LOG"
