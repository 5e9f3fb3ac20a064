# Shared by scripts/gpu/train.sh and ab.sh (sourced from the repository's root, not run): the trainer's environment,
# the clock, their settings' checks, the epoch mix file, the results counter and
# the snapshots named by the epoch they hold.
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

# snap_named CHECKPOINT FOLDER: an fp16 export of CHECKPOINT (a hard link to a last.pt: always a whole file) as
# FOLDER/ep_N.pt, N the epoch it holds (1-based; not the results rows seen, which a short epoch can outrun); prints N
snap_named() {
  python3 - "$1" "$2" <<'PY'
import sys
from pathlib import Path
from zebra_sim_ros.detection.checkpoint import read_checkpoint
from zebra_sim_ros.detection.export import export_checkpoint
src, folder = Path(sys.argv[1]), Path(sys.argv[2])
n = int(read_checkpoint(src)["epoch"]) + 1
tmp = export_checkpoint(src, folder / f".ep_{n}.pt.tmp")
tmp.replace(folder / f"ep_{n}.pt")
print(n)
PY
}

# rows_of RUN: the epochs a run folder's results.csv holds (0 without one)
rows_of() { [ -f "$1/results.csv" ] && echo $(( $(wc -l < "$1/results.csv") - 1 )) || echo 0; }
