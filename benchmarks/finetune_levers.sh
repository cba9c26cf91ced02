#!/usr/bin/env bash
# Levers of the ten-minute fine-tune (issue 51 item 3, RESULTS.md 4), chosen on the user's own held-out takes: each
# lever is finetune_unseen.sh's fine-tune (models/bn2_content, 440 steps, takes 001-003 of every style of `run` and
# `wave-both-hands`) with its overrides; the takes held out for validation (data.val_fraction of the training takes)
# pick the winner by its best val/l2p_mean; only the winner is scored on the 483 test takes, once: LAFAN and keys every
# 15 and 30 for its best checkpoint (the network as it is, as finetune_unseen.sh scores), keys for calibrated.ckpt
# (the blend fitted on the validation takes); and what it forgot: BN-2's standard split, the winner against
# models/bn2_content.  Alone on the 2-core CPU: about 10 min per lever, 25 min for the scores.
#   bash benchmarks/finetune_levers.sh <out dir> <folder of the run / wave-both-hands takes> NAME='OVERRIDE ...' ...
#   e.g. ... base= lr4e-4='optim.optimizer.lr=4e-4' mirror='data.mirror=true'
# THREADS (2): each training's threads (two levers at once: THREADS=1, each with PICK=0); PICK=0 trains only (a lever
# already trained is skipped, so a last call with every lever picks and tests the winner).
set -euo pipefail
OUT=${1:?out dir}
DATA=${2:?folder of takes}
shift 2
[ $# -gt 0 ] || { echo "give at least one lever: NAME='OVERRIDE ...'" >&2; exit 2; }
mkdir -p "$OUT"
DATA_ARGS=(data=bvh "data.path=$DATA" 'data.test_pattern=["*_00[4-9].bvh","*_0[1-9][0-9].bvh"]')
TEN_MIN=(trainer.max_steps=440 trainer.val_check_interval=100 "threads=${THREADS:-2}" run_test=false)
for lever in "$@"; do
  name=${lever%%=*}
  read -r -a over <<< "${lever#*=}"
  [ -f "$OUT/$name/done" ] && continue
  /usr/bin/time -v ${PYTHON:-python} train.py experiment=finetune init_from=models/bn2_content/model.ckpt \
    "${DATA_ARGS[@]}" "${TEN_MIN[@]}" "${over[@]}" hydra.run.dir="$OUT/$name" > "$OUT/$name.log" 2>&1
  touch "$OUT/$name/done"
done
[ "${PICK:-1}" = 0 ] && exit 0
# the winner by validation: the lowest best val/l2p_mean of each run's kept checkpoint
${PYTHON:-python} - "$OUT" "$@" > "$OUT/validation.md" <<'PY'
import glob, sys, torch
out, levers = sys.argv[1], [a.split("=", 1)[0] for a in sys.argv[2:]]
rows = []
for name in levers:
    (ckpt,) = glob.glob(f"{out}/{name}/checkpoints/epoch_*.ckpt")
    state = torch.load(ckpt, map_location="cpu", weights_only=False)["callbacks"]
    score = next(float(v["best_model_score"]) for k, v in state.items() if k.startswith("ModelCheckpoint"))
    rows.append((score, name, ckpt))
print("| lever | best val/l2p_mean | checkpoint |\n|---|---:|---|")
for score, name, ckpt in rows:
    print(f"| {name} | {score:.4f} | {ckpt} |")
print(f"\nwinner: {min(rows)[1]} {min(rows)[2]}")
PY
cat "$OUT/validation.md"
ckpt=$(awk '/^winner:/ {print $3}' "$OUT/validation.md")
name=$(awk '/^winner:/ {print $2}' "$OUT/validation.md")
${PYTHON:-python} eval.py "ckpt_path=$ckpt" "${DATA_ARGS[@]}" hydra.run.dir="$OUT/${name}_eval" > "$OUT/${name}_eval.log" 2>&1
${PYTHON:-python} eval.py "ckpt_path=$ckpt" "${DATA_ARGS[@]}" protocol=keyframes 'keyframe_intervals=[15,30]' \
  hydra.run.dir="$OUT/${name}_keyframes" > "$OUT/${name}_keyframes.log" 2>&1
# the checkpoint the run hands a user: the same weights with the do-no-harm blend fitted on the validation takes
${PYTHON:-python} eval.py "ckpt_path=$OUT/$name/checkpoints/calibrated.ckpt" "${DATA_ARGS[@]}" protocol=keyframes \
  'keyframe_intervals=[15,30]' hydra.run.dir="$OUT/${name}_calibrated_keyframes" > "$OUT/${name}_calibrated_keyframes.log" 2>&1
# what it forgot: BN-2's standard split (LAFAN protocol), the winner against the model it started from
[ -f "$OUT/start_standard/benchmark.json" ] || ${PYTHON:-python} eval.py ckpt_path=models/bn2_content/model.ckpt \
  data=bandai_namco hydra.run.dir="$OUT/start_standard" > "$OUT/start_standard.log" 2>&1
${PYTHON:-python} eval.py "ckpt_path=$ckpt" data=bandai_namco hydra.run.dir="$OUT/${name}_standard" > "$OUT/${name}_standard.log" 2>&1
