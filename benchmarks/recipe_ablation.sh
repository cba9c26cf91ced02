#!/usr/bin/env bash
# The recipe ablation of RESULTS.md, as it was run: two 1-thread jobs side by side (xargs -P 2), each a
# `python train.py ablation=recipe +recipe=<lever>` run with the step budget that <lever> reaches in 10 minutes on
# this CPU (benchmarks/recipe_budget.py, two jobs side by side), then `python -m inbetweening.collect`.
#   bash benchmarks/recipe_ablation.sh <out dir> <steps windows> <steps clips>
# (`python train.py ablation=recipe` runs the standard-split grid through Hydra's joblib launcher instead.)
set -euo pipefail
OUT=${1:?out dir}; SW=${2:?steps for base/task}; SC=${3:?steps for dense/mirror/last}
mkdir -p "$OUT"
steps() { case $1 in base|task) echo "$SW";; *) echo "$SC";; esac; }
jobs=(
  "last 1" "base 1" "last 1 data.split=content" "base 1 data.split=content"
  "task 1" "dense 1" "mirror 1" "last 1 model.graph=none"
  "last 2" "base 2" "last 2 model.graph=none" "last 3"
  "last 3 model.graph=none"
)
for j in "${jobs[@]}"; do
  set -- $j; r=$1; s=$2; shift 2
  name="${r}_s${s}$(printf '_%s' "$@" | tr '=.' '--')"; name=${name%_}
  echo "python train.py ablation=recipe +recipe=$r seed=$s trainer.max_steps=$(steps "$r") $* hydra.mode=RUN hydra.run.dir=$OUT/$name > $OUT/$name.log 2>&1"
done | xargs -P 2 -I{} bash -c "{}"
python -m inbetweening.collect "$OUT" --seeds --out "$OUT/recipe_ablation"
