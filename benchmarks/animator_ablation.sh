#!/usr/bin/env bash
# The ablation of model v2's levers 2-4 at an equal short budget, 2 seeds (RESULTS.md section 6.1): the 2-hour recipe
# (experiment=bn2_best) on the content split, at a proxy size (depth 3, batch 16, 500 optimiser steps: a fixed number
# of steps, so runs sharing the CPU stay comparable), adding one lever at a time:
#   base      the recipe as it is (10 context frames, one target, transitions 5-45)
#   task      + the animator's task: context 1-10 frames, transitions 2-45 drawn per sample, with probability 0.5
#               1-4 extra keys inside the transition (dense and sparse spacing)
#   gate      + model.gate=true (a learned per-joint, per-frame weight on the correction to the interpolation)
#   contacts  + representation=global_pos_local_quat_contact (predicted foot contacts; the keyframes protocol locks
#               the feet on them)
# Each run scores the LAFAN protocol (256 test windows) and the keyframes protocol (K = 5 and 30 and the random
# keypose schedule, 100 test clips evenly spaced) of the unseen contents; the contacts runs' keyframes protocol is
# scored again with foot_lock=false (<run>_unlocked).  The table: python benchmarks/animator_table.py <out dir>
#   bash benchmarks/animator_ablation.sh <out dir> [threads]
set -euo pipefail
OUT=${1:?out dir}
THREADS=${2:-1}
mkdir -p "$OUT"
COMMON=(experiment=bn2_best data.split=content model.depth=3 data.batch_size=16 trainer.max_steps=500
        trainer.val_check_interval=250 data.max_eval_windows=256 "test_keyframes=[5,30,random]" keyframe_clips=100
        threads=$THREADS logger=none callbacks.skeleton_figure=null)
TASK=(data.context_min=1 data.transition_min=2 data.transition_per=sample data.keyframes_max=4 data.keyframe_prob=0.5)
GATE=(model.gate=true)
CONTACTS=(representation=global_pos_local_quat_contact)
for seed in 1 2; do
  for variant in base task gate contacts; do
    case $variant in
      base) extra=() ;;
      task) extra=("${TASK[@]}") ;;
      gate) extra=("${TASK[@]}" "${GATE[@]}") ;;
      contacts) extra=("${TASK[@]}" "${GATE[@]}" "${CONTACTS[@]}") ;;
    esac
    run="$OUT/${variant}_s$seed"
    [ -f "$run/benchmark.json" ] && continue
    python train.py "${COMMON[@]}" "${extra[@]}" seed=$seed hydra.run.dir="$run" > "$run.log" 2>&1
  done
done
for seed in 1 2; do  # the contacts runs' feet unlocked: the same checkpoint, clips and schedules
  run="$OUT/contacts_s$seed"
  [ -f "$run/benchmark.json" ] && [ ! -f "${run}_unlocked/benchmark.json" ] || continue
  python eval.py ckpt_path="$(ls "$run"/checkpoints/epoch_*.ckpt | head -1)" data=bandai_namco data.split=content \
    protocol=keyframes "keyframe_intervals=[5,30,random]" keyframe_clips=100 foot_lock=false seed=$seed \
    hydra.run.dir="${run}_unlocked" > "${run}_unlocked.log" 2>&1
done
