#!/usr/bin/env bash
# Model v3 from scratch on a lent GPU machine, as run: the v2 recipe with the loss averaged per window,
#   python train.py experiment=bn2_v2 model.checkpoint_layers=false loss.reduce=windows trainer=gpu run_test=false
# (4,800 steps, seed 42, validation every max_steps / 4; the test benchmark runs afterwards on the CPU machine, e.g.
# `python eval.py ckpt_path=<calibrated or best>.ckpt data=bandai_namco`).  The GPU changes the wall time, not the
# experiment: same steps, batches, seed and schedule as on the CPU (numerics differ a little).
#
# The machine has no network and takes at most 64 MiB per call with the working tree, so what it lacks travels in the
# git-ignored .gpu/ (made by `python benchmarks/gpu_pack.py`):
#   .gpu/whl/*.whl          hydra-core 1.3.8, omegaconf 2.3.1, antlr4-python3-runtime 4.9.3, roma 1.8.0 (pure Python;
#                           `pip wheel --no-deps -w .gpu/whl hydra-core==1.3.8 ...`)
#   .gpu/c1, c2, ...        pieces of two xz archives of Bandai-Namco-2's BVH files (all 2,902: the loader refuses a
#                           dataset without test windows; every other one by name in each) and bn2_manifest.tsv (name,
#                           bytes, sha1 of every file), one piece per call (pieces.txt says how to put them together)
# Calls on the same warm machine, back to back (/tmp persists between them; it goes back 30 s after a call); every
# mode first keeps the pieces it was carried in /tmp/pieces and, once it has them all, unpacks the archives to /tmp/bn:
#   bash benchmarks/v3_gpu.sh part1               carry [.gpu/whl, .gpu/c1]: wheels to /tmp/site, GPU check, a speed
#                                                 probe of the recipe on the synthetic data (PROBE_STEPS=0: none)
#   bash benchmarks/v3_gpu.sh take                carry [.gpu/c2] (and so on): the piece kept, nothing else
#   bash benchmarks/v3_gpu.sh part2 <max_steps> [hydra overrides...]
#                                                 carry [.gpu/whl, .gpu/c<last>]: every file checked against the
#                                                 manifest, /tmp/bn2.zip rebuilt, the training run in /tmp/v3run;
#                                                 last.ckpt, the best checkpoint and the log are copied to $OUT every
#                                                 20 s (what was reached comes back if the call is stopped)
# Variables (for a dry run on a CPU machine): PY (python3), TRAINER (gpu), OUT (required), SITE (/tmp/site; SKIP_WHEELS=1
# skips the install), BN (/tmp/bn), ZIP (/tmp/bn2.zip), RUN (/tmp/v3run; its log $RUN.log), INBETWEENING_CACHE
# (/tmp/cache), PROBE_STEPS (150), RESUME=1 (part2 on the same warm machine: continue $RUN from its last.ckpt instead of
# starting afresh, reusing $ZIP; then only .gpu/whl need be carried), RECIPE_ARGS (another recipe than v3's, as hydra
# overrides in one string: RECIPE_ARGS="experiment=bn2_best model.checkpoint_layers=false seed=7" trains the v1
# recipe with another seed, RESULTS.md sections 2.1 and 2.2).
# As run (device time is short): `part2 4800 calibrate=false`, the do-no-harm blend fitted afterwards on the CPU machine
# (`python calibrate.py ckpt_path=<best.ckpt> data=bandai_namco`, about 3 min; on the device it would run on its CPU).
set -euo pipefail
PY=${PY:-python3}
TRAINER=${TRAINER:-gpu}
SITE=${SITE:-/tmp/site}
BN=${BN:-/tmp/bn}
RUN=${RUN:-/tmp/v3run}
ZIP=${ZIP:-/tmp/bn2.zip}
PIECES=${PIECES:-/tmp/pieces}
PROBE_STEPS=${PROBE_STEPS:-150}
OUT=${OUT:?set OUT to the folder whose files come back}
G=.gpu
PFX=Bandai-Namco-Research-Motiondataset-2/data
export INBETWEENING_CACHE=${INBETWEENING_CACHE:-/tmp/cache}
export PYTHONPATH=$SITE:src${PYTHONPATH:+:$PYTHONPATH}
export PYTHONUNBUFFERED=1
RECIPE=(experiment=bn2_v2 model.checkpoint_layers=false loss.reduce=windows)
if [[ -n ${RECIPE_ARGS:-} ]]; then read -ra RECIPE <<< "$RECIPE_ARGS"; fi  # another recipe, e.g. the v1 ensemble twin
RECIPE+=(trainer=$TRAINER run_test=false)
# display only: Lightning's default (Rich) bar prints nothing until the end when stdout is no terminal; tqdm's prints
# a line (steps done, steps/s) every 50 steps into the log
PBAR=('++callbacks.progress_bar={_target_:lightning.pytorch.callbacks.TQDMProgressBar,refresh_rate:50}')
mkdir -p "$OUT"
now() { date +%s.%N; }
secs() { "$PY" -c "import sys; print(f'{float(sys.argv[2]) - float(sys.argv[1]):.1f}')" "$1" "$2"; }

wheels() {
  if [[ ${SKIP_WHEELS:-0} == 1 ]]; then return; fi
  if [[ -d $SITE/hydra && -d $SITE/omegaconf && -d $SITE/roma && -d $SITE/antlr4 ]]; then
    echo "wheels: already in $SITE"; return
  fi
  "$PY" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target "$SITE" "$G"/whl/*.whl
  echo "wheels: installed into $SITE"
}

take() {  # keep the pieces this call carries; once all are kept, put the archives together, check and unpack them
  local t0; t0=$(now)
  mkdir -p "$PIECES" "$BN"
  cp -f "$G"/c*/* "$PIECES"/ 2>/dev/null || true
  "$PY" - "$PIECES" "$BN" <<'EOF'
import hashlib, os, sys, tarfile
pieces, bn = sys.argv[1:]
if not os.path.exists(os.path.join(pieces, "pieces.txt")):
    sys.exit(f"no pieces in {pieces}: carry .gpu/c1 (python benchmarks/gpu_pack.py makes them)")
lines = open(os.path.join(pieces, "pieces.txt")).read().split("\n")
n, archives = int(lines[0]), [line.split("\t") for line in lines[1:] if line]
have = [k for k in range(1, n + 1) if os.path.exists(os.path.join(pieces, f"bn2.{k}"))]
if os.path.exists(os.path.join(pieces, "unpacked")):
    print(f"pieces: all {n} already unpacked into {bn}")
elif len(have) < n:
    print(f"pieces: {len(have)} of {n} kept ({have}); carry the others in the next calls")
else:
    blob = b"".join(open(os.path.join(pieces, f"bn2.{k}"), "rb").read() for k in range(1, n + 1))
    at = 0
    for name, size, sha in archives:
        part = blob[at:at + int(size)]
        at += int(size)
        if hashlib.sha1(part).hexdigest() != sha:
            sys.exit(f"{name}: put together from the pieces, its sha1 is not the packed one (a piece from another pack?)")
        path = os.path.join(pieces, name)
        open(path, "wb").write(part)
        with tarfile.open(path, "r:xz") as t:  # python's tarfile + lzma: nothing else is certain to be there
            t.extractall(bn, **({"filter": "data"} if hasattr(tarfile, "data_filter") else {}))
        os.remove(path)
    open(os.path.join(pieces, "unpacked"), "w").close()
    print(f"pieces: {n} put together, {len(archives)} archives checked and unpacked into {bn}")
EOF
  echo "take: $(secs "$t0" "$(now)") s"
}

part1() {
  local t0; t0=$(now)
  wheels
  take
  "$PY" -c 'import torch; print("cuda:", torch.cuda.is_available(), torch.cuda.get_device_name() if torch.cuda.is_available() else "-", "torch", torch.__version__)'
  "$PY" -c 'import hydra, omegaconf, roma, lightning, inbetweening; print("imports ok: hydra", hydra.__version__, "from", hydra.__file__, "omegaconf", omegaconf.__version__, "roma", roma.__version__, "lightning", lightning.__version__)'
  echo "setup took $(secs "$t0" "$(now)") s"
  if ((PROBE_STEPS == 0)); then echo "part1 took $(secs "$t0" "$(now)") s in all (no speed probe)"; return 0; fi
  # speed probe: the same recipe on the synthetic data (generated, no files), one validation at the end
  local p0 p1; p0=$(now)
  set +e
  "$PY" train.py "${RECIPE[@]}" data=synthetic logger=none callbacks=none "${PBAR[@]}" calibrate=false \
    trainer.max_steps="$PROBE_STEPS" trainer.val_check_interval="$PROBE_STEPS" hydra.run.dir=/tmp/v3probe \
    > "$OUT/probe.log" 2>&1
  local rc=$?
  set -e
  p1=$(now)
  tr '\r' '\n' < "$OUT/probe.log" | grep -av 'it/s' | tail -n 25 || true
  local rate; rate=$(tr '\r' '\n' < "$OUT/probe.log" | grep -a '^Epoch' | grep -aoE '[0-9.]+it/s' | tail -1 || true)
  local wall; wall=$(secs "$p0" "$p1")
  echo "speed probe (rc $rc): $PROBE_STEPS steps in $wall s wall, start-up and the validation included;" \
       "progress bar's last rate ${rate:-?} (steady state)"
  "$PY" - "$wall" "$PROBE_STEPS" "${rate%it/s}" <<'EOF'
import sys
wall, n = float(sys.argv[1]), int(sys.argv[2])
print(f"  overall {n / wall:.2f} steps/s")
try:
    r = float(sys.argv[3])
    print(f"  steady {r:.2f} steps/s: training {n / r:.1f} s, start-up + validation {wall - n / r:.1f} s "
          f"({100 * (wall - n / r) / wall:.0f} % of the wall time); 4,800 steps would train in {4800 / r / 60:.1f} min")
except ValueError:
    pass
EOF
  echo "part1 took $(secs "$t0" "$(now)") s in all"
  return $rc
}

rebuild_zip() {  # every file of the manifest present with its size and sha1, then an uncompressed zip of them
  "$PY" - "$BN" "$PFX" "$ZIP" <<'EOF'
import hashlib, os, sys, zipfile
bn, pfx, dst = sys.argv[1:]
rows = [line.rstrip("\n").split("\t") for line in open(os.path.join(bn, "bn2_manifest.tsv"))]
bad = []
for name, size, sha in rows:
    p = os.path.join(bn, pfx, name)
    if not os.path.isfile(p) or os.path.getsize(p) != int(size):
        bad.append(name)
    elif hashlib.sha1(open(p, "rb").read()).hexdigest() != sha:
        bad.append(name)
if bad:
    sys.exit(f"{len(bad)} of {len(rows)} files missing or different (e.g. {bad[0]}): was part1 extracted on this "
             "machine? (a cold machine has lost /tmp/bn: run part1 and part2 again, back to back)")
with zipfile.ZipFile(dst + ".tmp", "w", zipfile.ZIP_STORED) as z:
    for name, _, _ in rows:  # a fixed date: the unpacked files may carry none (zip refuses dates before 1980)
        z.writestr(zipfile.ZipInfo(f"{pfx}/{name}", (1980, 1, 1, 0, 0, 0)), open(os.path.join(bn, pfx, name), "rb").read())
os.replace(dst + ".tmp", dst)
print(f"{dst}: {len(rows)} files checked against the manifest, {os.path.getsize(dst)} bytes")
EOF
}

# copy what the run has reached to $OUT (flat, at most 8 files): last.ckpt, best.ckpt (the monitored best,
# epoch_NNN.ckpt), calibrated.ckpt, train.log, config.yaml, the TensorBoard events, status.txt
put() { [[ -f $1 ]] || return 0; cp -f "$1" "$OUT/.tmp_$2" && mv -f "$OUT/.tmp_$2" "$OUT/$2"; }
collect() {
  local ck=$RUN/checkpoints best ev
  put "$ck/last.ckpt" last.ckpt
  best=$(ls -t "$ck"/epoch_*.ckpt 2>/dev/null | head -1 || true)
  if [[ -n $best ]]; then put "$best" best.ckpt; fi
  put "$ck/calibrated.ckpt" calibrated.ckpt
  put "$LOG" train.log
  put "$RUN/.hydra/config.yaml" config.yaml
  ev=$(find "$RUN" -name 'events.out.tfevents.*' -type f -printf '%T@ %p\n' 2>/dev/null | sort -n | tail -1 | cut -d' ' -f2- || true)
  if [[ -n $ev ]]; then put "$ev" events.tfevents; fi
  { echo "best: ${best:+$(basename "$best")}"; echo "at: $(date -u +%FT%TZ)"; echo "overrides:"
    cat "$RUN/.hydra/overrides.yaml" 2>/dev/null || true; } > "$OUT/status.txt"
}
progress() { tr '\r' '\n' < "$LOG" | grep -aE 'it/s|s/it' | tail -1 || true; }

part2() {
  local steps=${1:?part2 <max_steps> [hydra overrides...]}; shift
  local val=$((steps / 4)); ((val >= 1)) || val=1
  local t0; t0=$(now)
  wheels
  if [[ ${RESUME:-0} == 1 && -f $ZIP ]]; then
    echo "resume: $ZIP is already there (no piece need be carried)"
  else
    take
    rebuild_zip
  fi
  export BANDAI_NAMCO_PATH=$ZIP
  echo "data ready in $(secs "$t0" "$(now)") s"
  LOG=$RUN.log
  local extra=()
  if [[ ${RESUME:-0} == 1 && -f $RUN/checkpoints/last.ckpt ]]; then
    extra=(ckpt_path="$RUN/checkpoints/last.ckpt"); echo "resuming from $RUN/checkpoints/last.ckpt"
  else
    rm -rf "$RUN"
  fi
  local s0; s0=$(now)
  "$PY" train.py "${RECIPE[@]}" "${PBAR[@]}" trainer.max_steps="$steps" trainer.val_check_interval="$val" \
    hydra.run.dir="$RUN" "${extra[@]}" "$@" > "$LOG" 2>&1 &
  local pid=$! started=0 tick=0
  echo "training (pid $pid): ${RECIPE[*]} ${PBAR[*]} trainer.max_steps=$steps trainer.val_check_interval=$val hydra.run.dir=$RUN ${extra[*]} $*"
  while kill -0 "$pid" 2>/dev/null; do
    sleep 5; tick=$((tick + 5))
    if ((started == 0)) && [[ -n $(progress) ]]; then
      started=1; echo "first training step after $(secs "$s0" "$(now)") s (data preparation, model, CUDA start-up)"
    fi
    if ((tick % 20 == 0)); then
      collect
      echo "[$(secs "$s0" "$(now)") s] $(progress | sed 's/^ *//' | cut -c1-160)" \
           "$(command -v nvidia-smi >/dev/null && nvidia-smi --query-gpu=utilization.gpu,memory.used --format=csv,noheader 2>/dev/null | head -1)"
    fi
  done
  local rc=0; wait "$pid" || rc=$?
  collect
  echo "training exited with $rc after $(secs "$s0" "$(now)") s"
  tr '\r' '\n' < "$LOG" | grep -av 'it/s' | grep -v '^\s*$' | tail -n 30 || true
  ls -la "$RUN/checkpoints" "$OUT" || true
  "$PY" - "$OUT" <<'EOF' || true
import os, sys
from inbetweening.predictor.checkpoint import read_checkpoint
for name in ("last.ckpt", "best.ckpt", "calibrated.ckpt"):
    p = os.path.join(sys.argv[1], name)
    if os.path.exists(p):
        c = read_checkpoint(p)
        print(f"{name}: global_step {c.get('global_step')}, epoch {c.get('epoch')}, {os.path.getsize(p)} bytes")
EOF
  return $rc
}

# Several trainings side by side on the one GPU (each small network leaves it mostly idle, and each process has its own
# CPU cores): `parallel <max_steps | -> "<name> <hydra overrides...>" ...`, after part1 and take on the same warm
# machine (the last piece carried as for part2).  Each run trains in $RUN/<name> (log $RUN/<name>.log) with
# trainer=$TRAINER threads=$THREADS (2) $RUN_ARGS (default "run_test=false calibrate=false": trainings whose test runs
# on the CPU machine afterwards), and trainer.max_steps=<max_steps> with a validation every quarter of it (`-`: the
# recipe's own steps and validations).  Every 20 s what the runs reached comes back: with at most 7 runs one tar each
# ($OUT/<name>.tar: the run folder, checkpoints included, and its log), with more one $OUT/runs.tar of every run
# without its checkpoints (the 8 files of at most 16 MiB a call returns), so a call stopped at its limit still returns
# what each run reached.
#   Issue 54's students, as run (RESULTS.md 2.3):
#     S='experiment=distil model.checkpoint_layers=false representation=global_pos_local_quat_contact model.gate=true
#        data.keyframes_max=4 data.keyframe_prob=0.5 data.partial_prob=0.5'
#     THREADS=4 bash benchmarks/v3_gpu.sh parallel 3600 "s48 $S model.d_model=48 model.depth=3 model.heads=2" \
#       "s64 $S model.d_model=64 model.depth=4 model.heads=4" "c48 $S model.d_model=48 model.depth=3 model.heads=2
#        data.split=content teacher.checkpoints=[models/bn2_content/model.ckpt,...,models/bn2_v2_content/model.ckpt]"
#   Issue 51's folds protocol, one lever on the five folds (RESULTS.md 3.3; then, on the CPU machine, the tar unpacked
#   into <dir> and `python -m inbetweening.collect <dir> --folds`):
#     RUN_ARGS=" " THREADS=3 bash benchmarks/v3_gpu.sh parallel - "f1 experiment=folds data.split=fold-1 <lever>" ...
pack_runs() {  # what the runs reached, under $OUT (at most 8 files come back)
  local n
  if (($# <= 7)); then
    for n in "$@"; do
      [[ -d $RUN/$n ]] || continue
      tar -chf "$OUT/.tmp_$n.tar" -C "$RUN" "$n.log" "$n" 2>/dev/null || true
      mv -f "$OUT/.tmp_$n.tar" "$OUT/$n.tar"
    done
  else
    tar -chf "$OUT/.tmp_runs.tar" -C "$RUN" --exclude='*.ckpt' "${@/%/.log}" "$@" 2>/dev/null || true
    mv -f "$OUT/.tmp_runs.tar" "$OUT/runs.tar"
  fi
}
parallel() {
  local steps=${1:?parallel <max_steps | -> "<name> <overrides...>" ...}; shift
  local budget=()
  if [[ $steps != - ]]; then
    local val=$((steps / 4)); ((val >= 1)) || val=1
    budget=(trainer.max_steps="$steps" trainer.val_check_interval="$val")
  fi
  local fixed; read -ra fixed <<< "${RUN_ARGS-run_test=false calibrate=false}"
  local t0; t0=$(now)
  wheels
  if [[ ${RESUME:-0} == 1 && -f $ZIP ]]; then echo "resume: $ZIP is already there"; else take; rebuild_zip; fi
  export BANDAI_NAMCO_PATH=$ZIP
  echo "data ready in $(secs "$t0" "$(now)") s"
  mkdir -p "$RUN"
  local pids=() names=() spec name args
  for spec in "$@"; do
    name=${spec%% *}; read -ra args <<< "${spec#* }"
    rm -rf "${RUN:?}/$name"
    "$PY" train.py "${args[@]}" trainer="$TRAINER" "${fixed[@]}" threads="${THREADS:-2}" "${PBAR[@]}" "${budget[@]}" \
      hydra.run.dir="$RUN/$name" > "$RUN/$name.log" 2>&1 &
    pids+=($!); names+=("$name")
    echo "started $name (pid $!): ${args[*]} ${fixed[*]} ${budget[*]}"
  done
  local s0 tick=0 alive=1 i; s0=$(now)
  while ((alive)); do
    sleep 5; tick=$((tick + 5)); alive=0
    for i in "${!pids[@]}"; do kill -0 "${pids[$i]}" 2>/dev/null && alive=1; done
    if ((tick % 20 == 0)); then
      pack_runs "${names[@]}"
      for i in "${!names[@]}"; do
        LOG=$RUN/${names[$i]}.log; echo "[$(secs "$s0" "$(now)") s] ${names[$i]}: $(progress | sed 's/^ *//' | cut -c1-120)"
      done
      command -v nvidia-smi >/dev/null && nvidia-smi --query-gpu=utilization.gpu,memory.used --format=csv,noheader | head -1
    fi
  done
  local rc=0
  for i in "${!pids[@]}"; do
    wait "${pids[$i]}" || { rc=$?; echo "${names[$i]} exited with $rc"; }
    echo "== ${names[$i]}"; tr '\r' '\n' < "$RUN/${names[$i]}.log" | grep -av 'it/s' | grep -v '^\s*$' | tail -n 8 || true
  done
  pack_runs "${names[@]}"
  echo "all done after $(secs "$s0" "$(now)") s"; ls -la "$OUT"
  return $rc
}

mode=${1:?usage: v3_gpu.sh part1 | take | part2 <max_steps> [hydra overrides...] | parallel <max_steps | -> "<name> <overrides>"...}; shift
case $mode in
  part1) part1 ;;
  take) take ;;
  part2) part2 "$@" ;;
  parallel) parallel "$@" ;;
  *) echo "unknown mode $mode" >&2; exit 2 ;;
esac
