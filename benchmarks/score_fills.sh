#!/usr/bin/env bash
# The scoring step of the ship-rule benchmarks (nograph_ship.sh, students.sh): fills scored on a split of
# Bandai-Namco-2 with the same code, each into <out dir>/<split>_<name>_<protocol>/ (a run already there is skipped):
# the LAFAN protocol and keys only at every 5 / 15 / 30 / 45 frames, random and extremes, with the fill's defaults;
# interpolation ("-") by the LAFAN protocol only (the keyframes protocol scores interpolation itself).
#   bash benchmarks/score_fills.sh <out dir> <standard|content> "<name> <checkpoint, [ensemble] or ->" ...
# PYTHON (python), THREADS (2) and EXTRA (more eval.py overrides for every run, e.g. EXTRA=keyframe_clips=4) as the
# callers'.
set -euo pipefail
OUT=${1:?out dir}
SPLIT=${2:?standard or content}
shift 2
PY=${PYTHON:-python}
mkdir -p "$OUT"
for r in "$@"; do
  read -r name ckpt <<< "$r"
  model=(); [ "$ckpt" = - ] && model=(model=interpolation) || model=("ckpt_path=$ckpt")
  for protocol in lafan keyframes; do
    [ "$ckpt" = - ] && [ $protocol = keyframes ] && continue
    dir="$OUT/${SPLIT}_${name}_$protocol"
    [ -f "$dir/benchmark.json" ] && continue
    extra=(); [ $protocol = keyframes ] && extra=('keyframe_intervals=[5,15,30,45,random,extremes]')
    "$PY" eval.py "${model[@]}" data=bandai_namco data.split="$SPLIT" protocol=$protocol "${extra[@]}" \
      "threads=${THREADS:-2}" ${EXTRA:-} hydra.run.dir="$dir" > "$dir.log" 2>&1
  done
done
