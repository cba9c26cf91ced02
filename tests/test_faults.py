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
from inbetweening.training.train import train, write_benchmark

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


_HEAP_PROBE = """
import ctypes, sys, torch
from inbetweening.training.callbacks import map_large_allocations
class MallInfo2(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks",
                                               "fsmblks", "uordblks", "fordblks", "keepcost")]
libc = ctypes.CDLL("libc.so.6")
libc.mallinfo2.restype = MallInfo2
if sys.argv[1] == "mapped":
    map_large_allocations()
warm = torch.ones(2_500_000); del warm   # glibc's first large free raises its own threshold above 10 MB
before = libc.mallinfo2().hblkhd
block = torch.ones(2_500_000)            # 10 MB: its own map, or the heap
print((libc.mallinfo2().hblkhd - before) / 2**20)
"""


def test_large_allocations_are_mapped():
    """glibc keeps freed activations in a heap that fragments and is never returned; train/eval serve blocks of
    4 MB or more by their own memory maps (returned to the OS when freed)."""
    import platform

    if platform.libc_ver()[0] != "glibc":
        pytest.skip("glibc only")
    mapped_mb = {mode: float(subprocess.run([sys.executable, "-c", _HEAP_PROBE, mode], capture_output=True, text=True,
                                            check=True).stdout) for mode in ("default", "mapped")}
    assert mapped_mb["mapped"] >= 9.5  # the 10 MB block is a map of its own
    assert mapped_mb["default"] < 1  # glibc's default put it in the heap
