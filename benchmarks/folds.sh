#!/usr/bin/env bash
# The generalisation protocol (issue 51, RESULTS.md "Motions it never saw"): one configuration (a lever's overrides)
# trained and scored on the five folds of Bandai-Namco-2's contents (experiment=folds: 300 steps each, calibrated,
# keys only on 30 clips of the fold's two held-out contents), as one Hydra multirun, two 1-thread jobs at a time
# (the joblib launcher).  About 45 min per configuration on the 2-core CPU.  Then the table, per fold and pooled:
#   python -m inbetweening.collect <out dir> --folds
#   bash benchmarks/folds.sh <out dir> <name> [override ...]       e.g.  ... mirror data.mirror=true
set -euo pipefail
OUT=${1:?out dir}
NAME=${2:?configuration name}
shift 2
extra=()
[[ " $* " == *" model="* ]] || extra=(model.checkpoint_layers=false)   # the graph transformer's faster backward
[ -f "$OUT/$NAME/multirun.yaml" ] && [ "$(find "$OUT/$NAME" -name benchmark.json | wc -l)" -ge 5 ] && exit 0
${PYTHON:-python} train.py -m experiment=folds data.split=fold-1,fold-2,fold-3,fold-4,fold-5 hydra/launcher=joblib \
  hydra.launcher.n_jobs=2 threads=1 logger=none "${extra[@]}" "$@" hydra.sweep.dir="$OUT/$NAME" \
  > "$OUT/$NAME.log" 2>&1

${PYTHON:-python} -m inbetweening.collect "$OUT" --folds   # per fold and pooled
