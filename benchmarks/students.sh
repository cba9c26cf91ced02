#!/usr/bin/env bash
# Issue 54 item 1: students distilled from the shipped ensemble on a lent GPU (RESULTS.md 2.3), scored on the CPU with
# the same code as the ensemble: the LAFAN protocol and keys only with the fill's defaults, on the split the student's
# teacher was trained on (standard: the shipped ensemble; content: the shipped recipe's ensemble of the content split).
# The students were trained with `benchmarks/v3_gpu.sh parallel 3600 ...` (its header has the command) and calibrated
# here (`python calibrate.py ckpt_path=<run>/checkpoints/<best>.ckpt data=bandai_namco [data.split=content]`).
#   bash benchmarks/students.sh <out dir> <standard|content> <name> <calibrated ckpt>   (one student; about 15 min)
# Table and the ship rule: python benchmarks/students_table.py <out dir>.  EXTRA: more eval.py overrides for every run.
set -euo pipefail
OUT=${1:?out dir}
SPLIT=${2:?standard or content}
NAME=${3:?a name for the student}
CKPT=${4:?its calibrated checkpoint}
PY=${PYTHON:-python}
mkdir -p "$OUT"
for r in "$NAME $CKPT" "interpolation -"; do
  set -- $r; name=$1; ckpt=$2
  model=(); [ "$ckpt" = - ] && model=(model=interpolation) || model=("ckpt_path=$ckpt")
  for protocol in lafan keyframes; do
    [ "$ckpt" = - ] && [ $protocol = keyframes ] && continue  # the keyframes protocol scores interpolation itself
    dir="$OUT/${SPLIT}_${name}_$protocol"
    [ -f "$dir/benchmark.json" ] && continue
    extra=(); [ $protocol = keyframes ] && extra=('keyframe_intervals=[5,15,30,45,random,extremes]')
    "$PY" eval.py "${model[@]}" data=bandai_namco data.split=$SPLIT protocol=$protocol "${extra[@]}" \
      "threads=${THREADS:-2}" ${EXTRA:-} hydra.run.dir="$dir" > "$dir.log" 2>&1
  done
done
