"""Distributed for real: 2-process CPU DDP (gloo) trains, validates and tests; its metrics equal one process's."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DATA = ["data.synthetic.num_clips=20", "data.synthetic.min_frames=120", "data.synthetic.max_frames=160",
        "data.batch_size=8", "data.eval_batch_size=3", "data.max_eval_windows=7"]  # odd: padding would show
TINY = ["model.d_model=16", "model.depth=1", "model.heads=2", *DATA, "trainer.max_epochs=2",
        "callbacks.progress_bar=null", "callbacks.skeleton_figure=null", "logger=none"]
DDP = ["trainer=ddp", "trainer.accelerator=cpu", "trainer.devices=2"]


def _run(script, args, tmp_path, cache):
    env = dict(os.environ, OMP_NUM_THREADS="1", INBETWEENING_CACHE=str(cache))
    r = subprocess.run([sys.executable, script, *args, f"paths.cache_dir={cache}"], cwd=ROOT, env=env,
                       capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    return r


@pytest.mark.slow
def test_ddp_two_processes_train_and_score_like_one(tmp_path):
    cache = tmp_path / "cache"
    run = tmp_path / "ddp_train"
    r = _run("train.py", [*TINY, *DDP, f"hydra.run.dir={run}"], tmp_path, cache)
    assert r.stdout.count("Test benchmark (") == 1  # rank 0 alone prints and writes
    res = json.loads((run / "benchmark.json").read_text())
    assert res["n_windows"] == 7
    ckpt = run / "checkpoints" / "last.ckpt"
    assert ckpt.exists()
    # the same checkpoint scored by 2 processes and by 1: identical metrics (each window scored exactly once)
    one, two = tmp_path / "eval1", tmp_path / "eval2"
    _run("eval.py", [f"ckpt_path={ckpt}", *DATA, f"hydra.run.dir={one}"], tmp_path, cache)
    _run("eval.py", [f"ckpt_path={ckpt}", *DATA, *DDP, f"hydra.run.dir={two}"], tmp_path, cache)
    m1 = json.loads((one / "benchmark.json").read_text())["metrics"]
    m2 = json.loads((two / "benchmark.json").read_text())["metrics"]
    assert m1.keys() == m2.keys()
    for k in m1:
        assert m2[k] == pytest.approx(m1[k], rel=1e-6, abs=1e-9), k
