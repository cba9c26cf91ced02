#!/usr/bin/env bash
# init_keep's trade (issue 51 item 3, RESULTS.md 4): a fine-tune run of finetune_levers.sh (trained with
# init_stats=checkpoint) mixed with the model it started from at each share KEEP (the framework's kept_start, what
# init_keep=KEEP does after the fit), each mix scored as finetune_levers.sh scores its winner: keys every 15 and 30 on
# the test takes of the folder, and BN-2's standard split (what it forgot).  About 8 min per share, alone.
#   bash benchmarks/finetune_keep.sh <fine-tune run dir> <folder of takes> <out dir> KEEP ...
#   e.g. ... /work/runs/ft/stats_ckpt <folder> /work/runs/keep 0.3 0.5
set -euo pipefail
RUN=${1:?fine-tune run dir}
DATA=${2:?folder of takes}
OUT=${3:?out dir}
shift 3
mkdir -p "$OUT"
DATA_ARGS=(data=bvh "data.path=$DATA" 'data.test_pattern=["*_00[4-9].bvh","*_0[1-9][0-9].bvh"]')
best=$(ls "$RUN"/checkpoints/epoch_*.ckpt)
for keep in "$@"; do
  ckpt="$OUT/keep$keep.ckpt"
  ${PYTHON:-python} - "$best" "$RUN/.hydra/config.yaml" "$keep" "$ckpt" <<'PY'
import sys, torch, yaml
from inbetweening.predictor.checkpoint import kept_start, read_checkpoint
best, config, keep, out = sys.argv[1], sys.argv[2], float(sys.argv[3]), sys.argv[4]
cfg = yaml.safe_load(open(config))
assert cfg.get("init_stats") == "checkpoint", "the run must keep init_from's statistics (init_stats=checkpoint)"
torch.save(kept_start(read_checkpoint(best), read_checkpoint(cfg["init_from"]), keep), out)
PY
  ${PYTHON:-python} eval.py "ckpt_path=$ckpt" "${DATA_ARGS[@]}" protocol=keyframes 'keyframe_intervals=[15,30]' \
    "threads=${THREADS:-2}" hydra.run.dir="$OUT/keep${keep}_keyframes" > "$OUT/keep${keep}_keyframes.log" 2>&1
  ${PYTHON:-python} eval.py "ckpt_path=$ckpt" data=bandai_namco "threads=${THREADS:-2}" \
    hydra.run.dir="$OUT/keep${keep}_standard" > "$OUT/keep${keep}_standard.log" 2>&1
done
