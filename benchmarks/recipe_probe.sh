#!/usr/bin/env bash
# Recipe probe on the lent GPU machine (issue 12/13), as run: the recipe candidates for the 2-hour reference model,
# each trained for the optimiser steps that the 2-hour CPU budget gives it (experiment=bn2_best: 10,800 steps of
# frame_transformer; graph_transformer 4,400), all side by side on one GPU, one CPU thread each.  The GPU changes
# the wall time, not the experiment: same steps, batches, seeds and schedule as on the CPU (numerics differ a little).
#   bash benchmarks/recipe_probe.sh <out dir>            then   python -m inbetweening.collect <out dir>
set -euo pipefail
OUT=${1:?out dir}
mkdir -p "$OUT"
# experiment=bn2_best was then the frame transformer's recipe; these overrides pin what ran
B="experiment=bn2_best model=frame_transformer trainer.max_steps=10800 trainer.val_check_interval=1200 trainer=gpu threads=1 callbacks.skeleton_figure=null"
C="data.split=content"
GT="model=graph_transformer model.checkpoint_layers=false trainer.max_steps=4400 trainer.val_check_interval=1100"
jobs=(
  "s_base"
  "s_full         +recipe=last"
  "c_base         $C"
  "c_mirror       $C data.mirror=true"
  "c_centre_last  $C centre=last"
  "c_dense        $C data.train_offset=3"
  "c_full         $C +recipe=last"
  "c_reg          $C model.dropout=0.3 optim.optimizer.weight_decay=0.05"
  "c_gt           $C $GT"
)
# prepare the two splits' caches once, then start every run at once
python3 train.py $B trainer.max_steps=1 run_test=false logger=none hydra.run.dir="$OUT/.prep_s" > "$OUT/prep_s.log" 2>&1 &
python3 train.py $B $C trainer.max_steps=1 run_test=false logger=none hydra.run.dir="$OUT/.prep_c" > "$OUT/prep_c.log" 2>&1 &
wait
for j in "${jobs[@]}"; do
  set -- $j; name=$1; shift
  python3 train.py $B "$@" hydra.run.dir="$OUT/$name" > "$OUT/$name.log" 2>&1 &
done
wait
