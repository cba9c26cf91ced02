#!/usr/bin/env bash
# Check that the commands of README.md and docs/*.md still run as written, cheaply (about 4 CPU-minutes; 8 minutes
# of wall time on a loaded 2-core machine):
#   bash docs/check_commands.sh            # synthetic data and the shipped model only
#   BN2=1 bash docs/check_commands.sh      # also the Bandai-Namco-2 baseline evaluations (needs ../shared; the
#                                          # first run prepares the dataset cache); KEEP=1 keeps the outputs
# 1. Every `python train.py ...` / `python eval.py ...` line of the docs is composed with Hydra's `--cfg job` (the
#    config is printed, nothing runs). A sweep (-m a=x,y) is composed for its first value, and its launcher with
#    `--cfg hydra`; placeholders (<run>, ...) are replaced by a real checkpoint.
# 2. The cheap commands run for real with tiny settings: train, resume, a sweep and collect, eval (LAFAN1 protocol
#    and keyframes-only) of a checkpoint and of the baselines, predict (both forms, GIF render), export to ONNX.
set -euo pipefail
cd "$(dirname "$0")/.."
export OMP_NUM_THREADS=1 INBETWEENING_WORKERS=1
W=$(mktemp -d /tmp/check_commands.XXXXXX)
TINY="trainer.max_epochs=1 data.max_train_windows=32 data.max_eval_windows=16 model.depth=1 threads=1"
ok() { echo "ok   $*"; }
run() { local log="$W/log.$RANDOM"; if "$@" >"$log" 2>&1; then ok "$*"; else echo "FAIL $*"; tail -5 "$log"; exit 1; fi; }

# a tiny checkpoint for the commands that need one (<run>/checkpoints/last.ckpt, ckpt_path=...)
run python train.py $TINY hydra.run.dir="$W/run"
CKPT="$W/run/checkpoints/last.ckpt"

# 1. compose every Hydra command of the docs
python - "$CKPT" README.md docs/*.md >"$W/hydra_cmds" <<'EOF'
import re, shlex, sys
ckpt, files = sys.argv[1], sys.argv[2:]
for f in files:
    for block in re.findall(r"```bash\n(.*?)```", open(f).read(), re.S):
        for line in block.replace("\\\n", " ").splitlines():
            line = line.split("  #")[0].strip()
            if not re.match(r"python (train|eval)\.py\b", line):
                continue
            for placeholder in ("logs/train/runs/<run>/checkpoints/last.ckpt", "<run>/checkpoints/last.ckpt",
                                "<model.ckpt>", "ckpt_path=..."):
                line = line.replace(placeholder, "ckpt_path=" + ckpt if placeholder.startswith("ckpt_path") else ckpt)
            line = line.replace(" ... ", " ")
            words = shlex.split(line)[1:]
            sweep = "-m" in words
            words = [w for w in words if w != "-m"]
            words = [w.split("=", 1)[0] + "=" + w.split("=", 1)[1].split(",")[0] if sweep and "=" in w and "[" not in w
                     else w for w in words]
            print(shlex.join(words) + ("\tsweep" if sweep else ""))
EOF
while IFS=$'\t' read -r cmd sweep; do
    eval "run python $cmd --cfg job"
    [ -n "$sweep" ] && eval "run python $cmd --cfg hydra"
done <"$W/hydra_cmds"

# 2. the cheap ones for real
run python train.py ckpt_path="$CKPT" ${TINY/max_epochs=1/max_epochs=2} hydra.run.dir="$W/resume"
run python train.py -m mask=zero,lerp $TINY hydra.sweep.dir="$W/sweep"
run python -m inbetweening.collect "$W/sweep"
run python eval.py ckpt_path="$CKPT" data=synthetic hydra.run.dir="$W/e1"
run python eval.py data=synthetic model=zero_velocity hydra.run.dir="$W/e2"
run python eval.py ckpt_path="$CKPT" data=synthetic protocol=keyframes keyframe_intervals=[10,20] hydra.run.dir="$W/e3"
if [ "${BN2:-0}" = 1 ]; then
    run python eval.py data=bandai_namco model=interpolation hydra.run.dir="$W/e4"
    run python eval.py data=bandai_namco data.split=content model=zero_velocity hydra.run.dir="$W/e5"
    run python eval.py data=bandai_namco model=interpolation protocol=keyframes hydra.run.dir="$W/e6"
fi
# predict and export: a Bandai-Namco-2-skeleton clip is needed for the shipped model; the synthetic clips for ours
SYN=$(find "${INBETWEENING_CACHE:-$HOME/.cache/inbetweening}/synthetic" -name '*subject5.bvh' | head -1)
cp "$SYN" "$W/syn.bvh"
python - "$W/syn.bvh" "$W/key_poses.bvh" <<'EOF2'
import sys  # key_poses.bvh: frames 0, 30 and 60 of the clip, the input of the --gap form
lines = open(sys.argv[1]).read().splitlines()
i = next(k for k, line in enumerate(lines) if line.startswith("Frame Time"))
head = [("Frames: 3" if line.startswith("Frames:") else line) for line in lines[: i + 1]]
open(sys.argv[2], "w").write("\n".join(head + [lines[i + 1 + k] for k in (0, 30, 60)]) + "\n")
EOF2
run python -m inbetweening.predict --help
run python -m inbetweening.predict ckpt_path="$CKPT" input="$W/syn.bvh" keyframes=[0,30,75] output="$W/out.bvh"
run python -m inbetweening.predict ckpt_path="$CKPT" input="$W/key_poses.bvh" --gap 30 output="$W/out2.bvh" --render "$W/out.gif"
ZIP=../shared/datasets/bandai-namco-2.zip
if [ -f "$ZIP" ]; then
    unzip -p "$ZIP" Bandai-Namco-Research-Motiondataset-2/data/dataset-2_walk-turn-right_normal_008.bvh >"$W/clip.bvh"
    (cd "$W" && run python -m inbetweening.predict input=clip.bvh keyframes=[0,30,75] output=out.bvh)
    run python -c "from inbetweening import Inbetweener
Inbetweener.from_checkpoint('models/bn2_reference/model.ckpt').fill('$W/clip.bvh', keyframes=[0, 30, 75])"
fi
run python -m inbetweening.export --help
run python -m inbetweening.export ckpt_path=models/bn2_reference/model.ckpt format=onnx output="$W/model.onnx"
echo "all commands ran"
[ "${KEEP:-0}" = 1 ] && echo "outputs kept in $W" || rm -rf "$W"
