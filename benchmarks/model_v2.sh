#!/usr/bin/env bash
# Model v2's figures (RESULTS.md section 2.2) from its training runs:
#   python train.py experiment=bn2_v2 model.checkpoint_layers=false [data.split=content] hydra.run.dir=<run>
# The run itself tests checkpoints/calibrated.ckpt (the best validation checkpoint + the do-no-harm blend fitted on the
# validation windows) with the LAFAN protocol and the keyframes protocol (K = 5/15/30/45, random, extremes; feet
# locked on the predicted contacts): <run>/benchmark.json.  This script adds, for each (split, run) given, with eval.py:
#   <split>_blended_lafan        the calibrated checkpoint, LAFAN protocol (must equal the run's own test figures)
#   <split>_blended_unlocked     the calibrated checkpoint, keyframes protocol with foot_lock=false
#   <split>_plain_lafan          the best checkpoint without the blend, LAFAN protocol
#   <split>_plain_keyframes      the best checkpoint without the blend, keyframes protocol (feet locked)
# One job at a time (each keyframes scoring about 3 min alone on the 2-core CPU); finished scorings are skipped.
# Table: python benchmarks/model_v2_table.py <out dir>
#   bash benchmarks/model_v2.sh <out dir> standard=<run dir> [content=<run dir>] [threads]
set -euo pipefail
OUT=${1:?out dir}; shift
mkdir -p "$OUT"
THREADS=2
SCHEDULES='keyframe_intervals=[5,15,30,45,random,extremes]'
runs=()
for a in "$@"; do case $a in *=*) runs+=("$a") ;; *) THREADS=$a ;; esac; done
score() {  # name, eval.py arguments...
  local name=$1; shift
  [ -f "$OUT/$name/benchmark.json" ] && return 0
  python eval.py "$@" threads="$THREADS" hydra.run.dir="$OUT/$name" > "$OUT/$name.log" 2>&1
}
for pass in 1 2; do  # pass 1: what the targets need; pass 2: the figures without the blend
  for r in "${runs[@]}"; do
    split=${r%%=*}; run=${r#*=}
    data=(data=bandai_namco data.split="$split")
    cal=$run/checkpoints/calibrated.ckpt
    best=$(ls "$run"/checkpoints/epoch_*.ckpt | head -1)
    [ -f "$run/benchmark.json" ] && cp "$run/benchmark.json" "$OUT/${split}_run_benchmark.json"
    if [ $pass = 1 ]; then
      score "${split}_blended_lafan" ckpt_path="$cal" "${data[@]}"
      score "${split}_blended_unlocked" ckpt_path="$cal" "${data[@]}" protocol=keyframes "$SCHEDULES" foot_lock=false
    else
      score "${split}_plain_lafan" ckpt_path="$best" "${data[@]}"
      score "${split}_plain_keyframes" ckpt_path="$best" "${data[@]}" protocol=keyframes "$SCHEDULES"
    fi
  done
done

${PYTHON:-python} benchmarks/model_v2_table.py "$OUT"         # the tables (RESULTS.md)
