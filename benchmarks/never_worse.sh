#!/usr/bin/env bash
# The self-check of the do-no-harm blend (RESULTS.md section 12): the keyframes-only protocol, per clip, on both
# Bandai-Namco-2 splits with the shipped v1 models, with the self-check (the default) and without (the calibrated
# weight per gap length alone, as before), K = 5/15/30/45, random, extremes.  One job at a time, about 10 min per run
# on the 2-core CPU.  Table: python benchmarks/never_worse_table.py <out dir>
#   bash benchmarks/never_worse.sh <out dir> [self_check values, default "true false"]
set -euo pipefail
OUT=${1:?out dir}
CHECKS=${2:-true false}
SCHEDULES='keyframe_intervals=[5,15,30,45,random,extremes]'
mkdir -p "$OUT"
for check in $CHECKS; do
  for split in content standard; do
    ckpt=models/bn2_reference/model.ckpt; [ $split = content ] && ckpt=models/bn2_content/model.ckpt
    run="$OUT/${split}_check_${check}"
    [ -f "$run/benchmark.json" ] && continue
    python eval.py ckpt_path=$ckpt data=bandai_namco data.split=$split protocol=keyframes "$SCHEDULES" \
      self_check=$check threads=1 hydra.run.dir="$run" > "$run.log" 2>&1
  done
done
