#!/usr/bin/env bash
# Partial keys (issue 37, RESULTS.md section 8): the keyframes-only protocol's partial<K> schedules (whole keys every
# K frames, a key of one body part halfway between) on the Bandai-Namco-2 standard test clips, for each checkpoint
# given (e.g. the model fine-tuned for partial keys, experiment=bn2_partial, and the one it started from), with the
# fill's defaults (self-check, feet locked).  One job at a time, about 5-15 min each on the 2-core CPU with one thread;
# each log ends with the table (model / per-joint interpolation / frozen keys).
#   bash benchmarks/partial_keys.sh <out dir> <name>=<checkpoint> [<name>=<checkpoint> ...]
set -euo pipefail
OUT=${1:?out dir}
shift
SCHEDULES='keyframe_intervals=[partial15,partial30,partial45]'
mkdir -p "$OUT"
for run in "$@"; do
  name=${run%%=*}; ckpt=${run#*=}
  [ -f "$OUT/$name/benchmark.json" ] && continue
  python eval.py ckpt_path="$ckpt" data=bandai_namco protocol=keyframes "$SCHEDULES" threads=1 \
    hydra.run.dir="$OUT/$name" > "$OUT/$name.log" 2>&1
  tail -n 8 "$OUT/$name.log"
done
