#!/usr/bin/env bash
# The researcher's grid on Bandai-Namco-2, as it was run (results/researcher_grid/, RESULTS.md section 10.3): the
# graph transformer over mask / depth / heads / norm, one factor at a time around the default (lerp mask, depth 6,
# 4 heads, layer norm), 2 seeds each, at an equal budget of 200 optimiser steps (the budget of the one-seed table,
# RESULTS.md appendix A.2), then `python -m inbetweening.collect --seeds` (mean ± std over the seeds; per-seed rows
# too).
#   bash benchmarks/researcher_grid.sh [sweep dir]          (default logs/researcher_grid; needs BANDAI_NAMCO_PATH
#                                                           or the dataset at ../shared/datasets/bandai-namco-2.zip)
#
# Jobs: 5 configurations x 2 seeds = 10, one at a time (Hydra's basic launcher), each with one torch thread.
# Recipe: experiment=bn2_ablation (batch 32, 50-frame windows, transitions 5-30, AdamW lr 1e-3 with 100 warm-up
# steps then cosine to step 200, dropout 0, no validation), activation checkpointing off (1 thread: memory is no
# issue, recomputation is), no logger, calibrate=false (the network as it is), tested once at the end on the whole
# standard test split (data.max_eval_windows=null: 542 windows, LAFAN protocol at 5/15/30/45 frames, with
# interpolation on the same windows).
# Budget in steps, not time, so the figures do not depend on the machine's load.
#
# Measured (2026-11-25, this project's 2-core CPU shared with other jobs' test suites, one job at a time, 1 thread):
# 10 jobs x 268-535 s (mean 396 s: set-up, 200 steps at 1.17-2.38 s/step, the 542-window test), 66 min in all
# (results/researcher_grid/timing.json).  The spread in time is the machine's load; the figures do not depend on it.
# Why not the full factorial (mask x depth 6,12 x heads 4,8 x norm x 2 seeds = 32 jobs): 30-step probes on the quiet
# machine trained depth 6 / 4 heads / layer norm at 1.27 s/step and depth 12 / 8 heads / batch norm at 3.7 s/step;
# 32 jobs at 150 steps would take over 3 hours, against the 80 minutes this run had.  One factor at a time, at the
# 200 steps of the one-seed table (RESULTS.md appendix A.2), fits.
set -euo pipefail
OUT=${1:-logs/researcher_grid}
export OMP_NUM_THREADS=1
python train.py -m experiment=bn2_ablation \
    +variant=base,mask_zero,depth_12,heads_8,norm_batch seed=1,2 \
    trainer.max_steps=200 threads=1 model.checkpoint_layers=false logger=none calibrate=false run_test=true \
    data.max_eval_windows=null hydra.sweep.dir="$OUT"
python -m inbetweening.collect "$OUT" --out "$OUT/grid_runs"              # one row per run (each seed)
python -m inbetweening.collect "$OUT" --seeds --out "$OUT/grid"          # mean ± std over the 2 seeds
