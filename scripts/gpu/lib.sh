# Shared by scripts/gpu/train.sh and ab.sh (sourced from the repository's root, not run): the trainer's environment,
# the clock, their settings' checks, the epoch mix file, the results counter, the watch on last.pt and its exports.
export PYTHONPATH=$PWD PYTHONUNBUFFERED=1 OPENCV_FOR_THREADS_NUM=1
T0=$(date +%s)

# elapsed: seconds since the script started
elapsed() { echo $(( $(date +%s) - T0 )); }

# whole_numbers SCRIPT VAR...: each named variable a whole number >= 1, or exit 2 naming it
whole_numbers() {
  local script=$1 v; shift
  for v in "$@"; do
    [[ ${!v} =~ ^[1-9][0-9]*$ ]] || { echo "$script: $v=${!v}: want a whole number >= 1" >&2; exit 2; }
  done
}

# write_mix K FILE: a dataset.yaml beside the pack's train/ and val/ that lists the training frames K times, so that
# an epoch is K passes (the loader's workers restart each epoch: not every few seconds)
write_mix() {
  python3 - "$1" "$2" <<'PY'
import sys
k = int(sys.argv[1])
open(sys.argv[2], 'w').write('path: .\ntrain: [' + ', '.join(['train/images/train'] * k)
                             + ']\nval: val/images/val\nnc: 1\nnames:\n  0: zebra\n')
PY
}

# each_new_last RUN POLL: each time RUN/last.pt is replaced (a new inode: the trainer writes it by a rename), a hard
# link to it (a whole file, whatever lands next) as RUN/snap/raw_<inode>.pt; every POLL seconds until RUN/snap.stop
# appears or the script that sourced this is gone
each_new_last() {
  local run=$1 poll=$2 seen='' ino
  while sleep "$poll" && [ ! -f "$run/snap.stop" ] && kill -0 $$ 2>/dev/null; do
    ino=$(stat -c %i "$run/last.pt" 2>/dev/null) || continue
    [ "$ino" != "$seen" ] || continue
    ln -f "$run/last.pt" "$run/snap/.new.pt" 2>/dev/null || continue
    seen=$(stat -c %i "$run/snap/.new.pt")  # the inode linked, should another last.pt have landed since the stat
    mv -f "$run/snap/.new.pt" "$run/snap/raw_$seen.pt"
  done
}

# rows_of RUN: the epochs a run folder's results.csv holds (0 without one)
rows_of() { [ -f "$1/results.csv" ] && echo $(( $(wc -l < "$1/results.csv") - 1 )) || echo 0; }

# export_links RUN WATCH LOG: the links the watch (process WATCH, running each_new_last) leaves as RUN/snap/raw_*.pt,
# oldest first (a link keeps its last.pt's time), each through the caller's `snap_one LINK`, which must take the link
# away (export it, or keep it under another name). An export never holds up the watch, so no epoch is skipped while
# one runs. Once the watch has stopped, the links left but the newest three are dropped (counted in LOG: the
# snapshots sent back are among the last three, and a backlog must not outlast the call), the rest exported, and
# the function returns.
export_links() {
  local run=$1 watch=$2 log=$3 f stopped='' old
  while :; do
    if [ -z "$stopped" ] && ! kill -0 "$watch" 2>/dev/null; then  # no link comes after this look
      stopped=1
      mapfile -t old < <(ls -t "$run"/snap/raw_*.pt 2>/dev/null | tail -n +4)
      rm -f "${old[@]}"
      echo "[run] ${#old[@]} older links not exported" >>"$log"
    fi
    f=$(ls -tr "$run"/snap/raw_*.pt 2>/dev/null | head -n 1)
    if [ -n "$f" ]; then snap_one "$f"; continue; fi
    [ -z "$stopped" ] || return 0
    sleep 1
  done
}
