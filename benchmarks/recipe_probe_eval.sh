#!/usr/bin/env bash
# Score every run of benchmarks/recipe_probe.sh from its last step checkpoint (also when the probe was stopped
# before max_steps): the benchmark windows and keyframes every 15/30 frames of its own split's test clips.
#   bash benchmarks/recipe_probe_eval.sh <probe dir> <out dir>
set -uo pipefail
P=${1:?probe dir}; E=${2:?out dir}
mkdir -p "$E"
for d in "$P"/*/checkpoints/last.ckpt; do
  run=$(basename "$(dirname "$(dirname "$d")")")
  split=standard; [[ $run == c_* ]] && split=content
  python3 -c "import torch,sys; print(torch.load(sys.argv[1], map_location='cpu', weights_only=False)['global_step'])" \
    "$d" > "$E/$run.steps"
  common="data=bandai_namco data.split=$split ckpt_path=$d trainer=gpu"
  python3 eval.py $common hydra.run.dir="$E/$run" > "$E/$run.log" 2>&1 &
  python3 eval.py $common protocol=keyframes "keyframe_intervals=[15,30]" hydra.run.dir="$E/${run}_kf" \
    > "$E/${run}_kf.log" 2>&1 &
done
wait
