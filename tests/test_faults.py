"""Faults never lose work or lie: a diverging run stops at the bad step; results are strict JSON."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from conftest import TINY, compose_cfg
from inbetweening.training.callbacks import NonFiniteError
from inbetweening.training.job import write_benchmark
from inbetweening.training.train import train

ROOT = Path(__file__).resolve().parents[1]
DIVERGE = [o for o in TINY if "max_steps" not in o] + [
    "optim.optimizer.lr=1e12", "optim.optimizer.weight_decay=0", "trainer.gradient_clip_val=null", "trainer.max_steps=30",
    "callbacks=default", "callbacks.progress_bar=null", "callbacks.skeleton_figure=null", "logger=none",
]


def test_diverging_run_stops_at_the_step_with_finite_checkpoints(tmp_path, cache_dir):
    cfg = compose_cfg("train", DIVERGE, tmp_path / "run", cache_dir)
    with pytest.raises(NonFiniteError, match=r"^step \d+: (training loss is (nan|inf)|gradient of \S+ is not finite); "
                                             r"training stopped") as e:
        train(cfg)
    step = int(str(e.value).split()[1].rstrip(":"))
    assert step < 30
    assert not (tmp_path / "run" / "benchmark.json").exists()
    for ckpt in (tmp_path / "run" / "checkpoints").glob("*.ckpt"):  # whatever was saved holds finite weights
        sd = torch.load(ckpt, map_location="cpu", weights_only=True)["state_dict"]
        assert all(torch.isfinite(v).all() for v in sd.values() if v.is_floating_point()), ckpt


def test_benchmark_json_is_strict(tmp_path):
    path = tmp_path / "benchmark.json"
    write_benchmark(path, "d", "m", 3, {"l2p@5": 1.5})
    assert json.loads(path.read_text())["metrics"] == {"l2p@5": 1.5}
    with pytest.raises(NonFiniteError, match=r"benchmark: l2p@15 not finite \(nan\)"):
        write_benchmark(tmp_path / "b2.json", "d", "m", 3, {"l2p@5": 1.0, "l2p@15": float("nan")})
    assert not (tmp_path / "b2.json").exists()


@pytest.mark.slow
def test_diverging_cli_run_exits_3_with_one_line(tmp_path):
    args = [sys.executable, "train.py", *DIVERGE, f"hydra.run.dir={tmp_path}", f"paths.cache_dir={tmp_path / 'cache'}",
            "+trainer.enable_progress_bar=false"]
    r = subprocess.run(args, cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert r.returncode == 3, r.stderr[-2000:]
    errors = [line for line in r.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "training stopped" in errors[0]
    assert "Traceback" not in r.stderr


def test_heap_is_trimmed_while_training(tmp_path, monkeypatch):
    """glibc keeps freed activations in a heap that fragments; the trainer returns it every few steps."""
    import platform

    from inbetweening.training import callbacks as C
    from inbetweening.training.builders import make_trainer

    assert C.trim_heap() == (platform.libc_ver()[0] == "glibc")
    cfg = compose_cfg("train", ["logger=none", "callbacks=none"], tmp_path, tmp_path / "cache")
    trim = [c for c in make_trainer(cfg).callbacks if isinstance(c, C.TrimHeap)]
    assert len(trim) == 1
    calls = []
    monkeypatch.setattr(C, "trim_heap", lambda: calls.append(1) or True)
    for i in range(60):
        trim[0].on_train_batch_end(None, None, None, None, i)
    assert len(calls) == 60 // trim[0].every == 2


def test_heap_is_trimmed_when_a_step_leaves_it_grown(monkeypatch):
    """Between the periodic trims, a step that leaves the process ``slack_mb`` above its size after the last trim
    triggers one (the fragmentation that made the default run's peak grow epoch after epoch)."""
    from inbetweening.training import callbacks as C

    sizes = iter([400.0, 700.0, 950.0, 420.0, 600.0])
    calls = []
    monkeypatch.setattr(C, "trim_heap", lambda: calls.append(1) or True)
    monkeypatch.setattr(C, "resident_mb", lambda: next(sizes))
    cb = C.TrimHeap(every_n_steps=1000, slack_mb=512)
    cb.on_train_epoch_start(None, None)  # trim; floor = 400
    cb.on_train_batch_end(None, None, None, None, 0)  # 700 <= 912: no trim
    cb.on_train_batch_end(None, None, None, None, 1)  # 950 > 912: trim, floor = 420
    cb.on_train_batch_end(None, None, None, None, 2)  # 600 <= 932: no trim
    assert len(calls) == 2 and cb.floor == 420.0
