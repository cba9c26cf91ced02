#!/usr/bin/env bash
# Does the relation matrix M help the patent's graph transformer?  (RESULTS.md section 10.4)
# The shipped recipe (`+recipe=base`: 10 context frames, windows every 20 frames, centre=known, lr 1e-3, batch 32,
# 65-frame windows, transitions 5-45) with `model.graph=multiply` (M) against `model.graph=none` (plain attention
# over all joints), 3 seeds each, the same 308 optimiser steps: what the graph transformer reaches in 10 minutes with
# one thread and a second job beside it (1.95 s/step, measured in the bn2_best run, RESULTS.md section 2.2).
# Two 1-thread jobs side by side (xargs -P 2); scored on the BN-2 standard test split (LAFAN protocol) and keyframes
# every 15 / 30 frames; then `python -m inbetweening.collect --seeds` (mean ± std over the 3 seeds).
#   bash benchmarks/m_vs_none.sh <out dir>
set -euo pipefail
OUT=${1:?out dir}
STEPS=${STEPS:-308}
mkdir -p "$OUT"
v=$((STEPS / 4))
for s in 1 2 3; do
  for g in multiply none; do
    echo "python train.py ablation=recipe +recipe=base model=graph_transformer model.checkpoint_layers=false model.graph=$g seed=$s trainer.max_steps=$((v * 4)) trainer.val_check_interval=$v hydra.mode=RUN hydra.run.dir=$OUT/gt_${g}_s$s > $OUT/gt_${g}_s$s.log 2>&1"
  done
done | xargs -P 2 -I{} bash -c "{}"
python -m inbetweening.collect "$OUT" --seeds --out "$OUT/m_vs_none"
