#!/usr/bin/env bash
# The 2-hour reference model (RESULTS.md sections 2.2 and 3.1): the shipped model (standard split), then the same
# recipe on the content split, each alone on the 2-core CPU (about 1 h 30 min each), then the shipped model's
# inference-only export and the check that eval.py reproduces the run's own benchmark.
#   bash benchmarks/bn2_best.sh <out dir>
set -euo pipefail
OUT=${1:?out dir}
mkdir -p "$OUT"
for split in standard content; do
  /usr/bin/time -v python train.py experiment=bn2_best model.checkpoint_layers=false data.split=$split hydra.run.dir="$OUT/$split" > "$OUT/$split.log" 2>&1
done
best=$(ls "$OUT"/standard/checkpoints/epoch_*.ckpt | head -1)
python -m inbetweening.export ckpt_path="$best" format=ckpt output=models/bn2_reference/model.ckpt
cp "$OUT/standard/.hydra/config.yaml" models/bn2_reference/config.yaml
python eval.py ckpt_path=models/bn2_reference/model.ckpt data=bandai_namco hydra.run.dir="$OUT/eval"
cmp <(python -c "import json,sys; print(json.load(open(sys.argv[1]))['metrics'])" "$OUT/eval/benchmark.json") \
    <(python -c "import json,sys; print(json.load(open(sys.argv[1]))['metrics'])" "$OUT/standard/benchmark.json")
