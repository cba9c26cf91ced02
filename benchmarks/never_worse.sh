#!/usr/bin/env bash
# Never worse than interpolation, planted feet (RESULTS.md section 5): the keyframes-only protocol, per clip, on both
# Bandai-Namco-2 splits, K = 5/15/30/45, random, extremes, for the shipped models with the fill's defaults (the
# self-check of the do-no-harm blend, feet locked) and, for the v1 models, as before (self_check=false
# foot_lock=false: the calibrated weight per gap length alone, no locking), the shipped ensemble (predict's default,
# section 2.1: the v1 + v1 twin fine-tuned for partial keys + v2), the v1 + v1 twin + v2 ensembles and the v1 + v2
# pairs (section 2.1; their whole-set figures: RESULTS.md, appendix).  One job at a time, 5-20 min per run
# on the 2-core CPU.  Table: python benchmarks/never_worse_table.py <out dir>
#   bash benchmarks/never_worse.sh <out dir>
set -euo pipefail
OUT=${1:?out dir}
SCHEDULES='keyframe_intervals=[5,15,30,45,random,extremes]'
mkdir -p "$OUT"
runs=(
  "standard_partial3   [models/bn2_partial/model.ckpt,models/bn2_partial_twin/model.ckpt,models/bn2_v2/model.ckpt]  standard"
  "standard_ensemble3  [models/bn2_reference/model.ckpt,models/bn2_twin/model.ckpt,models/bn2_v2/model.ckpt]  standard"
  "content_ensemble3   [models/bn2_content/model.ckpt,models/bn2_twin_content/model.ckpt,models/bn2_v2_content/model.ckpt]  content"
  "standard_ensemble   [models/bn2_reference/model.ckpt,models/bn2_v2/model.ckpt]          standard"
  "content_ensemble    [models/bn2_content/model.ckpt,models/bn2_v2_content/model.ckpt]    content"
  "content_v1      models/bn2_content/model.ckpt     content"
  "standard_v1     models/bn2_reference/model.ckpt   standard"
  "standard_v2     models/bn2_v2/model.ckpt          standard"
  "content_v2      models/bn2_v2_content/model.ckpt  content"
  "content_v1_before   models/bn2_content/model.ckpt     content   self_check=false foot_lock=false"
  "standard_v1_before  models/bn2_reference/model.ckpt   standard  self_check=false foot_lock=false"
)
for r in "${runs[@]}"; do
  set -- $r; name=$1; ckpt=$2; split=$3; shift 3
  [ -f "$OUT/$name/benchmark.json" ] && continue
  python eval.py "ckpt_path=$ckpt" data=bandai_namco data.split=$split protocol=keyframes "$SCHEDULES" threads=1 \
    "$@" hydra.run.dir="$OUT/$name" > "$OUT/$name.log" 2>&1
done

${PYTHON:-python} benchmarks/never_worse_table.py "$OUT"      # the tables (RESULTS.md)
