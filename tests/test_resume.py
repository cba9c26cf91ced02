"""Checkpoints never lose more than a few steps, and resuming is exact: SIGKILL mid-epoch, resume, and the
benchmark equals the uninterrupted run's; Ctrl-C / SIGTERM write a checkpoint and print how to resume."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch

from inbetweening.predictor.checkpoint import predictor_state

ROOT = Path(__file__).resolve().parents[1]
RUN = ["model.d_model=16", "model.depth=1", "model.heads=2", "model.dropout=0.1", "data.synthetic.num_clips=10",
       "data.synthetic.min_frames=120", "data.synthetic.max_frames=160", "data.batch_size=4",
       "data.max_eval_windows=8", "data.transition_per=sample", "trainer.max_epochs=4", "trainer.log_every_n_steps=1",
       "callbacks.progress_bar=null", "callbacks.skeleton_figure=null", "callbacks.last_checkpoint.every_n_train_steps=3",
       "logger=none", "+trainer.enable_progress_bar=false", "trainer.enable_model_summary=false"]


def _env(cache):
    return dict(os.environ, OMP_NUM_THREADS="1", INBETWEENING_CACHE=str(cache), PYTHONUNBUFFERED="1")


def _cmd(run_dir, cache, *extra):
    return [sys.executable, "train.py", *RUN, f"hydra.run.dir={run_dir}", f"paths.cache_dir={cache}", *extra]


def _step(ckpt: Path) -> int:
    try:
        return int(torch.load(ckpt, map_location="cpu", weights_only=True)["global_step"])
    except Exception:  # noqa: BLE001 - not there yet
        return -1


def _start_and_wait(run_dir, cache, min_step):
    # SIGINT back to its default in the child: a background job of a non-interactive shell (nohup ... &) starts with
    # SIGINT ignored, and a process that inherits SIG_IGN rightly keeps ignoring Ctrl-C
    proc = subprocess.Popen(_cmd(run_dir, cache), cwd=ROOT, env=_env(cache), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    last = run_dir / "checkpoints" / "last.ckpt"
    deadline = time.time() + 600
    while _step(last) < min_step:
        assert proc.poll() is None, f"run ended before step {min_step}: {proc.stderr.read()[-2000:]}"
        assert time.time() < deadline
        time.sleep(0.02)
    return proc, last


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The uninterrupted run (and the shared dataset cache)."""
    tmp = tmp_path_factory.mktemp("resume")
    cache = tmp / "cache"
    r = subprocess.run(_cmd(tmp / "full", cache), cwd=ROOT, env=_env(cache), capture_output=True, text=True,
                       timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    steps = _step(tmp / "full" / "checkpoints" / "last.ckpt")
    assert steps > 20  # several epochs of several batches
    return tmp, cache, json.loads((tmp / "full" / "benchmark.json").read_text())


@pytest.mark.slow
def test_sigkill_mid_epoch_then_resume_gives_the_same_benchmark(reference):
    tmp, cache, want = reference
    proc, last = _start_and_wait(tmp / "killed", cache, min_step=10)
    proc.kill()  # SIGKILL: no handler runs
    proc.wait()
    assert not (tmp / "killed" / "benchmark.json").exists()
    ckpt = torch.load(last, map_location="cpu", weights_only=True)
    steps_per_epoch = _step(tmp / "full" / "checkpoints" / "last.ckpt") // 4
    assert ckpt["global_step"] % steps_per_epoch != 0, "the checkpoint should be mid-epoch"
    # resume into the same run folder, as the printed resume command does
    r = subprocess.run(_cmd(tmp / "killed", cache, f"ckpt_path={last}"), cwd=ROOT, env=_env(cache),
                       capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    final = predictor_state(torch.load(last, map_location="cpu", weights_only=True)["state_dict"])
    full = predictor_state(torch.load(tmp / "full" / "checkpoints" / "last.ckpt", map_location="cpu",
                                      weights_only=True)["state_dict"])
    assert full and all(torch.equal(final[k], full[k]) for k in full), "weights differ"
    got = json.loads((tmp / "killed" / "benchmark.json").read_text())
    assert got == want  # bit-identical metrics


@pytest.mark.slow
@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_interrupt_writes_a_checkpoint_and_prints_the_resume_command(reference, sig, code):
    tmp, cache, _ = reference
    run = tmp / f"sig{int(sig)}"
    proc, last = _start_and_wait(run, cache, min_step=4)
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == code, err[-2000:]
    assert "resume with: python train.py" in out and f"ckpt_path={last}" in out
    assert _step(last) >= 4
    assert not list(run.glob("checkpoints/.*.tmp"))  # no temporary file left behind
