#!/usr/bin/env bash
# Leave-one-content-out, scored (RESULTS.md section 3.2): each model of benchmarks/loco_train.sh on the content it never
# saw, the keyframes-only protocol per clip (K = 5/15/30/45, random, extremes; CLIPS clips of the content, evenly
# spaced), with the fill's defaults (the self-check, feet locked) and as before (self_check=false foot_lock=false).
# About 1.5 min per run on the 2-core CPU at 60 clips.  Table: python benchmarks/never_worse_table.py <out dir>
# SECOND=<train dir of EXPERIMENT=bn2_v2 loco_train.sh> scores instead each content's two models as one ensemble
# (ckpt_path=[first,second], the fill's defaults; RESULTS.md section 3.2), as <content>_ensemble.
#   [SECOND=<train dir>] bash benchmarks/loco_eval.sh <train dir> <out dir> [clips]
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
  variants=(default before)
  if [ -n "${SECOND:-}" ]; then
    [ -f "$SECOND/$c/checkpoints/calibrated.ckpt" ] || { echo "missing $SECOND/$c/checkpoints/calibrated.ckpt"; continue; }
    ckpt="[$ckpt,$SECOND/$c/checkpoints/calibrated.ckpt]"; variants=(ensemble)
  fi
  for variant in "${variants[@]}"; do
    run="$OUT/${c}_$variant"
    [ -f "$run/benchmark.json" ] && continue
    extra=(); [ $variant = before ] && extra=(self_check=false foot_lock=false)
    python eval.py "ckpt_path=$ckpt" data=bandai_namco data.split=holdout-$c protocol=keyframes "$SCHEDULES" \
      keyframe_clips=$CLIPS threads=1 "${extra[@]}" hydra.run.dir="$run" > "$run.log" 2>&1
  done
done

${PYTHON:-python} benchmarks/never_worse_table.py "$OUT"      # the tables (RESULTS.md)
