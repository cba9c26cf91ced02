#!/usr/bin/env bash
# Issue 54 item 1: students distilled from the shipped ensemble on a lent GPU (RESULTS.md 2.3), scored on the CPU with
# the same code as the ensemble: the LAFAN protocol and keys only with the fill's defaults, on the split the student's
# teacher was trained on (standard: the shipped ensemble; content: the shipped recipe's ensemble of the content split).
# The students were trained with `benchmarks/v3_gpu.sh parallel 3600 ...` (its header has the command) and calibrated
# here (`python calibrate.py ckpt_path=<run>/checkpoints/<best>.ckpt data=bandai_namco [data.split=content]`).
#   bash benchmarks/students.sh <out dir> <standard|content> <name> <calibrated ckpt>   (one student; about 15 min)
# Table and the ship rule: python benchmarks/students_table.py <out dir>.  EXTRA: more eval.py overrides for every run.
set -euo pipefail
OUT=${1:?out dir}
SPLIT=${2:?standard or content}
NAME=${3:?a name for the student}
CKPT=${4:?its calibrated checkpoint}
bash "$(dirname "$0")/score_fills.sh" "$OUT" "$SPLIT" "$NAME $CKPT" "interpolation -"   # benchmarks/score_fills.sh
