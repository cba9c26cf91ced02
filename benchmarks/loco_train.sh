#!/usr/bin/env bash
# Leave-one-content-out at a short budget (RESULTS.md section 3.2): for each of Bandai-Namco-2's ten contents, the
# shipped recipe (experiment=bn2_best) trained on the nine others (data.split=holdout-<content>) for STEPS optimiser
# steps, one thread, then its do-no-harm blend calibrated on the nine contents' validation windows (checkpoints/
# calibrated.ckpt).  The held-out content is scored afterwards by benchmarks/loco_eval.sh.  About 6 min per content
# on the 2-core CPU at 150 steps.  EXPERIMENT=bn2_v2 trains model v2's recipe instead (the second member of the
# leave-one-content-out ensembles, RESULTS.md section 3.2).
#   [EXPERIMENT=bn2_v2] bash benchmarks/loco_train.sh <out dir> [steps]
set -euo pipefail
OUT=${1:?out dir}
STEPS=${2:-150}
EXPERIMENT=${EXPERIMENT:-bn2_best}
mkdir -p "$OUT"
CONTENTS=$(python -c "from inbetweening.data.specs import BN_CONTENTS; print(' '.join(BN_CONTENTS))")
for c in $CONTENTS; do
  [ -f "$OUT/$c/checkpoints/calibrated.ckpt" ] && continue
  python train.py experiment=$EXPERIMENT data.split=holdout-$c model.checkpoint_layers=false threads=1 \
    trainer.max_steps=$STEPS trainer.val_check_interval=$STEPS run_test=false callbacks.skeleton_figure=null \
    hydra.run.dir="$OUT/$c" > "$OUT/$c.log" 2>&1
done
