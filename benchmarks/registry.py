"""Every benchmark that RESULTS.md and BENCHMARKS.md cite, by name: its script, what it measures, about how long it
takes on the 2-core CPU (alone: most of them time things, so run one at a time), what it writes and which document
section holds its figures.  ``python -m benchmarks list`` prints them, ``python -m benchmarks run NAME [ARG ...]``
runs one (the arguments go to the script; ``run NAME --help`` prints the script's own usage)."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


@dataclass(frozen=True)
class Benchmark:
    name: str
    script: str                  # a file of benchmarks/ (.py run with this Python, .sh with bash)
    measures: str
    time: str                    # on the 2-core CPU, alone
    writes: str                  # the files it writes (or "prints")
    cited: str                   # the section of RESULTS.md / BENCHMARKS.md that holds its figures
    usage: str = ""              # the arguments it needs, when it needs any
    needs: str = ""              # what must be there besides the repository (data, Blender, a GPU, earlier runs)
    steps: tuple[str, ...] = field(default=())  # further scripts of benchmarks/ it runs itself (its tables)

    @property
    def path(self) -> Path:
        return HERE / self.script


BN2 = "../shared/datasets/bandai-namco-2.zip"
CC = "../shared/datasets/cmu-iclone-subset.zip"
BPY = "Blender's Python (.venv-bpy: pip install bpy==5.0.1)"

BENCHMARKS: tuple[Benchmark, ...] = (
    # --- speed and memory (BENCHMARKS.md) ---
    Benchmark("bvh_read", "bvh_read.py", "reading every BVH clip of Bandai-Namco-2 against a reference parser",
              "about 2 min", "prints", "BENCHMARKS.md, BVH reading", "[zip or folder] [--repeat 3]", BN2),
    Benchmark("dataset_load", "dataset_load.py", "cold dataset preparation against the cached load", "about 3 min",
              "BENCHMARKS.md section", "BENCHMARKS.md, Dataset preparation and cached load", needs=BN2),
    Benchmark("train_throughput", "train_throughput.py", "training windows/s, FLOPs and matmul share of every model",
              "about 10 min", "BENCHMARKS.md section", "BENCHMARKS.md, Training throughput"),
    Benchmark("train_step_profile", "train_step_profile.py", "where a training step of the shipped recipe goes",
              "about 5 min", "BENCHMARKS.md section (--write)", "BENCHMARKS.md, Training step: where the time goes"),
    Benchmark("recipe_budget", "recipe_budget.py", "optimiser steps that fit a wall-clock budget, per recipe",
              "about 5 min", "prints", "RESULTS.md 10.5, recipe levers (the step budgets)"),
    Benchmark("inference_latency", "inference_latency.py", "one transition through the API; the batch API",
              "about 3 min", "BENCHMARKS.md section", "BENCHMARKS.md, Inference latency"),
    Benchmark("fill_profile", "fill_profile.py", "the shipped fill's 30-frame transition split into its stages",
              "about 1 min", "BENCHMARKS.md section (--write)", "BENCHMARKS.md, Where the fill's time goes"),
    Benchmark("network_sizes", "network_sizes.py", "one window's CPU time and GFLOP per graph-transformer size",
              "about 1 min", "BENCHMARKS.md section (--write)", "BENCHMARKS.md, Network size and window time"),
    Benchmark("predict_startup", "predict_startup.py", "`python -m inbetweening.predict` start-up included: ONNX vs checkpoints",
              "about 1 min", "BENCHMARKS.md section", "BENCHMARKS.md, predict start-up", needs=BN2),
    Benchmark("memory", "memory.py", "peak resident memory of train, eval and the shipped model's eval",
              "about 15 min", "BENCHMARKS.md section", "BENCHMARKS.md, Memory", needs=BN2),
    Benchmark("character_fill_time", "character_fill_time.py", "300 frames of a Character Creator take, 10 keys",
              "about 1 min", "prints", "BENCHMARKS.md, Fill time with retargeting", needs=CC),
    Benchmark("blender_fill", "blender_fill.py", "the extension in real Blender: fill time and error against Bezier",
              "about 5 min", "results/blender_fill.json, BENCHMARKS.md section", "BENCHMARKS.md, Blender extension",
              needs=f"{BN2}; {BPY}"),
    Benchmark("blender_loop", "blender_loop.py", "re-filling one gap after an edit in real Blender, Auto Re-fill",
              "about 3 min", "BENCHMARKS.md section", "BENCHMARKS.md, Blender extension: re-fill after an edit",
              needs=f"{BN2}; {BPY}"),
    Benchmark("blender_rigify", "blender_rigify.py", "a Rigify rig in real Blender: error against Bezier, fill time",
              "about 10 min", "results/blender_rigify.json", "RESULTS.md 6, Blender against Bezier", needs=f"{BN2}; {BPY}"),
    # --- figures and pictures ---
    Benchmark("blender_figures", "blender_figures.py", "docs/blender.md's timeline figure from real Blender",
              "about 2 min", "docs/blender/timeline.png", "docs/blender.md", needs=f"{BN2}; {BPY}"),
    Benchmark("blender_loop_figure", "blender_loop_figure.py", "docs/blender.md's animator's-loop figure",
              "about 2 min", "docs/blender/loop.png", "docs/blender.md", needs=f"{BN2}; {BPY}"),
    Benchmark("unseen_strip", "unseen_strip.py", "a held-out content filled from keys: model, interpolation, truth",
              "about 1 min", "results/unseen.png, results/unseen.gif", "RESULTS.md 3, motions it never saw",
              "<content-split checkpoint>", BN2),
    Benchmark("foot_lock_strip", "foot_lock_strip.py", "a walk filled with and without the feet locked",
              "about 1 min", "results/foot_lock.png", "RESULTS.md 5.3, the feet", "<checkpoint>", BN2),
    # --- accuracy of the fill (RESULTS.md) ---
    Benchmark("reference_parity", "reference_parity.py", "this project's LAFAN1 benchmark against the official code",
              "about 1 min", "prints", "BENCHMARKS.md, Reference parity", "--reference <official code>",
              "the official LAFAN1 benchmark code"),
    Benchmark("characters", "characters.py", "the same motion on other rigs (renamed, re-proportioned, other units)",
              "about 20 min", "results/characters/characters.json", "RESULTS.md 7, any humanoid character", needs=BN2),
    Benchmark("real_rigs", "real_rigs.py", "real rigs nobody here wrote (Character Creator, ReActIdle, assimp CMU)",
              "about 10 min", "results/characters/real_rigs.json", "RESULTS.md 7, any humanoid character",
              needs=f"{CC}; reactidle.zip; apt assimp-testmodels"),
    Benchmark("known_motions_on_real_rig", "known_motions_on_real_rig.py", "BN-2 test clips on the CC rig",
              "about 15 min", "results/characters/known_on_cc.json", "RESULTS.md 7, any humanoid character",
              needs=f"{BN2}; {CC}"),
    Benchmark("frame_rates", "frame_rates.py", "BN-2 test clips resampled to 24/60/120 fps, keys at the same times",
              "about 10 min", "results/characters/frame_rates.json", "RESULTS.md 7, any humanoid character", needs=BN2),
    Benchmark("foot_lock_check", "foot_lock_check.py", "the keyframes protocol with the feet locked or not",
              "about 10 min", "prints", "RESULTS.md 5.3, the feet", "<ckpt[,ckpt...]> <split> [--clips 60]", BN2),
    Benchmark("test_time_adaptation", "test_time_adaptation.py", "adapting to the clip's own keys: gain and cost",
              "about 15 min", "prints", "RESULTS.md 3, motions it never saw", needs=BN2),
    Benchmark("retarget_rig", "retarget_rig.py", "writes the generated target character of the retargeting task",
              "seconds", "the BVH named", "RESULTS.md 9, learned retargeting", "<out.bvh>"),
    Benchmark("model_pose", "model_pose.py", "the model skeleton's natural pose read off its data (runtime.tpose)",
              "about 1 min", "prints the table of runtime/tpose.py", "RESULTS.md 7; docs/characters.md", needs=BN2),
    # --- trainings and their tables (RESULTS.md) ---
    Benchmark("bn2_best", "bn2_best.sh", "the 2-hour reference model on both splits, its export, eval parity",
              "about 3 h", "<out>/, models/bn2_reference/", "RESULTS.md 2.2, the shipped fill's members", "<out dir>", BN2),
    Benchmark("model_v2", "model_v2.sh", "model v2's figures from its training runs", "about 30 min",
              "<out>/ and its tables", "RESULTS.md 2.2, the shipped fill's members",
              "<out dir> standard=<run dir> [content=<run dir>] [threads]", BN2, ("model_v2_table.py",)),
    Benchmark("do_no_harm", "do_no_harm.sh", "the do-no-harm blend on and off, both splits", "about 1 h",
              "<out>/ and its tables", "RESULTS.md 5.1, the blend per gap length", "<out dir> [<std ckpt> <content ckpt>]",
              BN2, ("do_no_harm_table.py",)),
    Benchmark("never_worse", "never_worse.sh", "per clip, the shipped fill against interpolation, both splits",
              "about 1 h", "<out>/ and its tables", "RESULTS.md 2.1 and 5.2, per clip", "<out dir>", BN2,
              ("never_worse_table.py",)),
    Benchmark("loco_train", "loco_train.sh", "leave-one-content-out models at a short budget", "about 1 h",
              "<out>/<content>/", "RESULTS.md 3, motions it never saw", "<out dir> [steps]", BN2),
    Benchmark("loco_eval", "loco_eval.sh", "each leave-one-content-out model on the content it never saw",
              "about 30 min", "<out>/ and its tables", "RESULTS.md 3, motions it never saw",
              "<train dir> <out dir> [clips]", "loco_train's runs", ("never_worse_table.py",)),
    Benchmark("folds", "folds.sh", "a lever's overrides on the five held-out-content folds (the protocol)",
              "about 45 min per configuration", "<out>/<name>/ and the table", "RESULTS.md 3, motions it never saw",
              "<out dir> <name> [override ...]", BN2),
    Benchmark("content_speeds", "content_speeds.py", "the hip's speed per content: which held-out motions leave the "
              "training contents' range", "about 10 s", "prints", "RESULTS.md 3.3, the folds protocol", "[zip or folder]",
              BN2),
    Benchmark("body_parts", "body_parts.py", "a fill's error per content and body part (legs, arms, trunk) against "
              "interpolation's", "about 1 min per 100 clips", "prints", "RESULTS.md 3.3, the folds protocol",
              "<checkpoint> [--split standard] [--keys 15] [--clips N] [--defaults | --network-alone]", BN2),
    Benchmark("check_windows", "check_windows.py", "the self-check's error ratio against the fill's own on validation "
              "clips at two schedules, and the long-window thresholds that follow", "about 2 min per checkpoint",
              "prints [--json]", "RESULTS.md 3.5, long gaps", "--ckpt fold-1=<ckpt> ... [--keys 15 30] [--clips 30]",
              f"{BN2}; the folds' checkpoints (benchmarks/folds.sh)"),
    Benchmark("finetune_unseen", "finetune_unseen.sh", "10 minutes of fine-tuning on motions never seen",
              "about 1 h", "<out>/", "RESULTS.md 4, fine-tuning on your motions", "<out dir> [<folder of takes>]", BN2),
    Benchmark("finetune_levers", "finetune_levers.sh", "levers of the 10-minute fine-tune, the winner picked on "
              "the user's held-out takes and tested once", "about 10 min per lever and 15 min", "<out>/",
              "RESULTS.md 4, fine-tuning on your motions", "<out dir> <folder of takes> NAME='OVERRIDE ...' ...", BN2),
    Benchmark("finetune_keep", "finetune_keep.sh", "init_keep's trade: a fine-tune mixed with its start at each "
              "share, scored on the test takes and BN-2's standard split", "about 8 min per share", "<out>/",
              "RESULTS.md 4, fine-tuning on your motions", "<fine-tune run> <folder of takes> <out dir> KEEP ...",
              f"{BN2}; a finetune_levers run with init_stats=checkpoint"),
    Benchmark("nograph_ship", "nograph_ship.sh", "the graph-free candidate fill against the shipped one on a split "
              "(LAFAN and keys only), for the ship rule", "about 20 min per split", "<out>/ and the table",
              "RESULTS.md 3.3, the folds protocol", "<out dir> <training run dir> <standard|content>",
              f"{BN2}; a run of experiment=bn2_best model.graph=none on the split",
              ("nograph_ship_table.py", "score_fills.sh")),
    Benchmark("partial_keys", "partial_keys.sh", "the keyframes protocol's partial-key schedules per checkpoint",
              "about 15 min per checkpoint", "<out>/", "RESULTS.md 8, partial keys", "<out dir> <name>=<checkpoint> ...", BN2),
    Benchmark("researcher_grid", "researcher_grid.sh", "mask / depth / heads / norm, 2 seeds, 200 steps",
              "about 3 h", "<out>/grid.md", "RESULTS.md 10.3, the researcher's grid", "[sweep dir]", BN2),
    Benchmark("m_vs_none", "m_vs_none.sh", "the relation matrix M against plain attention, 3 seeds", "about 1 h",
              "<out>/m_vs_none.md", "RESULTS.md 10.4, M against plain attention", "<out dir>", BN2),
    Benchmark("recipe_ablation", "recipe_ablation.sh", "the recipe levers at a 10-minute budget", "about 4 h",
              "<out>/recipe_ablation.md", "RESULTS.md 10.5, recipe levers", "<out dir> [job name ...]", BN2),
    Benchmark("v3_gpu", "v3_gpu.sh", "trainings on a lent GPU machine (model v3, the students side by side)",
              "about 40 min on an H100", "<out>/", "RESULTS.md 2.2, 2.3 and 10.6",
              "part1 | take | part2 <max_steps> [override ...] | parallel <max_steps> '<name> <override ...>' ...",
              f"{BN2}; a GPU; python benchmarks/gpu_pack.py", ("gpu_pack.py",)),
    Benchmark("students", "students.sh", "a student distilled from the ensemble, scored as the ensemble is (LAFAN and "
              "keys only), for issue 54's ship rule", "about 15 min per student", "<out>/ and the table",
              "RESULTS.md 2.3, one network distilled from the ensemble",
              "<out dir> <standard|content> <name> <calibrated checkpoint>", f"{BN2}; a student (v3_gpu parallel)",
              ("students_table.py", "score_fills.sh")),
)

BY_NAME = {b.name: b for b in BENCHMARKS}
