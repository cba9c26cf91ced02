#!/usr/bin/env bash
# Leave-one-content-out, scored (RESULTS.md section 12): each model of benchmarks/loco_train.sh on the content it never
# saw, the keyframes-only protocol per clip (K = 5/15/30/45, random, extremes; CLIPS clips of the content, evenly
# spaced), with the fill's defaults (the self-check, feet locked) and as before (self_check=false foot_lock=false).
# About 1.5 min per run on the 2-core CPU at 60 clips.  Table: python benchmarks/never_worse_table.py <out dir>
#   bash benchmarks/loco_eval.sh <train dir> <out dir> [clips]
set -euo pipefail
TRAIN=${1:?train dir}
OUT=${2:?out dir}
CLIPS=${3:-60}
SCHEDULES='keyframe_intervals=[5,15,30,45,random,extremes]'
mkdir -p "$OUT"
CONTENTS=$(python -c "from inbetweening.data.specs import BN_CONTENTS; print(' '.join(BN_CONTENTS))")
for c in $CONTENTS; do
  ckpt="$TRAIN/$c/checkpoints/calibrated.ckpt"
  [ -f "$ckpt" ] || { echo "missing $ckpt"; continue; }
  for variant in default before; do
    run="$OUT/${c}_$variant"
    [ -f "$run/benchmark.json" ] && continue
    extra=(); [ $variant = before ] && extra=(self_check=false foot_lock=false)
    python eval.py ckpt_path="$ckpt" data=bandai_namco data.split=holdout-$c protocol=keyframes "$SCHEDULES" \
      keyframe_clips=$CLIPS threads=1 "${extra[@]}" hydra.run.dir="$run" > "$run.log" 2>&1
  done
done
