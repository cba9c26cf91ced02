#!/usr/bin/env bash
# The recipe ablation of RESULTS.md section 10.5, as it was run: two 1-thread jobs side by side (xargs -P 2), each a
# `python train.py ablation=recipe +recipe=<lever> model=<model>` run for the optimiser steps that this lever and model
# reach in 10 minutes on this CPU with a second job beside it (benchmarks/recipe_budget.py), validated 4 times, then
# `python -m inbetweening.collect --seeds`.
#   bash benchmarks/recipe_ablation.sh <out dir> [job name ...]     (names given: run only those jobs)
# (`python train.py ablation=recipe` runs the standard-split grid of the default model through Hydra's joblib launcher.)
set -euo pipefail
OUT=${1:?out dir}
mkdir -p "$OUT"
FT="model=frame_transformer"
UN="model=unet1d"
GT="model=graph_transformer model.checkpoint_layers=false"   # 1 thread: memory is no issue, recomputation is
# steps in 10 min (s/step, 1 thread, two jobs side by side, benchmarks/recipe_budget.py, 2026-11-23):
# frame_transformer base/task 0.550 -> 1091, dense/mirror/last 0.569 -> 1055; graph_transformer last 1.372 -> 437,
# last with model.graph=none 1.328 -> 451
jobs=(
  "ft_base_s1       base   1 1091 $FT"
  "ft_last_s1       last   1 1055 $FT"
  "ft_base_content  base   1 1091 $FT data.split=content"
  "ft_last_content  last   1 1055 $FT data.split=content"
  "ft_task_s1       task   1 1091 $FT"
  "ft_dense_s1      dense  1 1055 $FT"
  "ft_mirror_s1     mirror 1 1055 $FT"
  "gt_M_s1          last   1 437  $GT"
  "gt_none_s1       last   1 451  $GT model.graph=none"
  # round 2 (issue 12): single levers on top of base, then the second seeds. rot6d / velocity / keyframe get base's
  # step budget: the extra input channels and the extra L1 term cost under 1 % of a step (the runs' own s/step,
  # RESULTS.md 10.5)
  "ft_rot6d_s1      rot6d    1 1091 $FT"
  "ft_velocity_s1   velocity 1 1091 $FT"
  "ft_keyframe_s1   keyframe 1 1091 $FT"
  "ft_base_s2       base   2 1091 $FT"
  "ft_last_s2       last   2 1055 $FT"
  "ft_task_s2       task   2 1091 $FT"
  "ft_dense_s2      dense  2 1055 $FT"
  "ft_mirror_s2     mirror 2 1055 $FT"
  "ft_rot6d_s2      rot6d    2 1091 $FT"
  "ft_velocity_s2   velocity 2 1091 $FT"
  "ft_keyframe_s2   keyframe 2 1091 $FT"
  "ft_base_content_s2 base 2 1091 $FT data.split=content"
  "ft_last_content_s2 last 2 1055 $FT data.split=content"
  # round 3 (issue 12): velocity on the content split, and velocity combined with each other lever. Budgets from
  # `python benchmarks/recipe_budget.py model=frame_transformer --threads 1 --steps 30 --recipes velocity vel_foot
  # vel_fk vel_last vel_mirror` (quiet machine, 2026-11-23), as ratios to vel_last (0.595 s/step; centre=last costs
  # nothing, so vel_last = velocity = base's 1091): vel_foot 0.606 -> 1071, vel_fk 0.632 -> 1027, vel_mirror 0.640
  # -> 1014 (the first row, velocity 0.665, was the cold start and is not used)
  "ft_velocity_content_s1 velocity 1 1091 $FT data.split=content"
  "ft_vel_last_s1   vel_last 1 1091 $FT"
  "ft_vel_last_content_s1 vel_last 1 1091 $FT data.split=content"
  "ft_vel_mirror_s1 vel_mirror 1 1014 $FT"
  "ft_vel_foot_s1   vel_foot 1 1071 $FT"
  "ft_vel_fk_s1     vel_fk   1 1027 $FT"
  "ft_vel_keyframe_s1 vel_keyframe 1 1091 $FT"
  "ft_velocity_content_s2 velocity 2 1091 $FT data.split=content"
  # the model lever at the same wall clock: unet1d (temporal convolutions) with velocity inputs. Its budget is the ratio
  # of its s/step to the frame transformer's, measured back to back under the same load (recipe_budget.py --threads 1,
  # velocity: unet1d 0.254 and 0.271, frame_transformer 0.965 between them) -> 1091 x 0.965 / 0.263 = 4003
  "un_velocity_s1   velocity 1 4000 $UN"
  "un_velocity_content_s1 velocity 1 4000 $UN data.split=content"
  # time warp on the content split (the unseen `run` is faster than every training content); its s/step equals
  # vel_mirror's, measured back to back (recipe_budget.py --recipes vel_mirror vel_speed vel_mirror vel_speed: 1.927 /
  # 1.917 / 2.214 / 1.885 under load), so vel_mirror's 1014 steps
  "ft_vel_speed_content_s1 vel_speed 1 1014 $FT data.split=content"
  # unet1d, the best model of round 3, with the time warp on the content split: vel_speed / velocity s/step 1.03 for
  # unet1d (recipe_budget.py model=unet1d --recipes velocity vel_speed velocity vel_speed: 0.627 / 0.609 / 0.631 /
  # 0.687 under load) -> 4000 / 1.03 = 3880
  "un_vel_speed_content_s1 vel_speed 1 3880 $UN data.split=content"
  # second seeds of the best configuration at this budget
  "un_velocity_s2   velocity 2 4000 $UN"
  "un_velocity_content_s2 velocity 2 4000 $UN data.split=content"
)
want=" ${*:2} "
for j in "${jobs[@]}"; do
  set -- $j; name=$1; r=$2; s=$3; steps=$4; shift 4
  if [ "$want" != "  " ] && [[ "$want" != *" $name "* ]]; then continue; fi
  v=$((steps / 4))
  echo "python train.py ablation=recipe +recipe=$r seed=$s trainer.max_steps=$((v * 4)) trainer.val_check_interval=$v $* hydra.mode=RUN hydra.run.dir=$OUT/$name > $OUT/$name.log 2>&1"
done | xargs -P 2 -I{} bash -c "{}"
python -m inbetweening.collect "$OUT" --seeds --out "$OUT/recipe_ablation"
