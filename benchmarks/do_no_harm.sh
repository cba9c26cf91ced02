#!/usr/bin/env bash
# The "do no harm" measurement (RESULTS.md section 5.1): what the do-no-harm blend (src/inbetweening/predictor/
# calibration.py) does to a trained model, with and without it, on both Bandai-Namco-2 splits.
# For each (checkpoint, split): calibrate.py fits the blend on that split's validation windows (never its test clips),
# then eval.py scores the checkpoint and the calibrated one with the LAFAN protocol and the keyframes-only protocol
# (K = 5/15/30/45, random, extremes); interpolation is scored on the same LAFAN windows for the ratios.  Default:
# the shipped v1 models (models/bn2_reference on the standard split, models/bn2_content on the content split).  One job at a time; about 1 h in all on the 2-core CPU.
# Table: python benchmarks/do_no_harm_table.py <out dir> [--copy results/do_no_harm]
#   bash benchmarks/do_no_harm.sh <out dir> [<std checkpoint> <content checkpoint>]
set -euo pipefail
OUT=${1:?out dir}
STD=${2:-models/bn2_reference/model.ckpt}
CONTENT=${3:-models/bn2_content/model.ckpt}
SCHEDULES='keyframe_intervals=[5,15,30,45,random,extremes]'
mkdir -p "$OUT"
for split in standard content; do
  src=$STD; [ $split = content ] && src=$CONTENT
  data=(data=bandai_namco data.split=$split)
  python calibrate.py ckpt_path="$src" "${data[@]}" out="$OUT/$split.calibrated.ckpt" threads=2 \
    hydra.run.dir="$OUT/${split}_calibrate" > "$OUT/${split}_calibrate.log" 2>&1
  python eval.py model=interpolation "${data[@]}" hydra.run.dir="$OUT/${split}_interpolation_lafan" \
    > "$OUT/${split}_interpolation_lafan.log" 2>&1
  for variant in plain blended; do
    ckpt=$src; [ $variant = blended ] && ckpt=$OUT/$split.calibrated.ckpt
    python eval.py ckpt_path="$ckpt" "${data[@]}" hydra.run.dir="$OUT/${split}_${variant}_lafan" \
      > "$OUT/${split}_${variant}_lafan.log" 2>&1
    python eval.py ckpt_path="$ckpt" "${data[@]}" protocol=keyframes "$SCHEDULES" \
      hydra.run.dir="$OUT/${split}_${variant}_keyframes" > "$OUT/${split}_${variant}_keyframes.log" 2>&1
  done
done

${PYTHON:-python} benchmarks/do_no_harm_table.py "$OUT"       # the tables (RESULTS.md)
