"""``python -m inbetweening.predict`` without a render imports no training, config or plotting stack.

Structural, not timed: a subprocess fills keyframes through the real CLI entry point and reports which heavy
packages ended up in ``sys.modules`` (the start-up time they cost is measured in ``benchmarks/predict_startup.py``).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np

from inbetweening.data.bvh_writer import format_bvh
from inbetweening.data.synthetic import generate_clip, make_bvh

HEAVY = ("lightning", "pytorch_lightning", "hydra", "omegaconf", "matplotlib", "roma", "torch._dynamo", "onnx",
         "onnxruntime", "inbetweening.training")

PROBE = """
import json, runpy, sys
sys.argv = ["inbetweening.predict", *json.loads(sys.argv[1])]
try:
    runpy.run_module("inbetweening.predict", run_name="__main__", alter_sys=True)
except SystemExit as e:
    code = e.code
else:
    code = 0
print("MODULES=" + json.dumps(sorted(m for m in sys.modules)))
print("CODE=" + json.dumps(code))
"""


def _probe(args: list[str], cwd) -> tuple[int, set[str], str]:
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    r = subprocess.run([sys.executable, "-c", PROBE, json.dumps(args)], cwd=cwd, env=env, capture_output=True,
                       text=True, timeout=300, check=False)
    lines = {ln.split("=", 1)[0]: ln.split("=", 1)[1] for ln in r.stdout.splitlines() if "=" in ln[:8]}
    assert "MODULES" in lines, r.stderr
    return json.loads(lines["CODE"]), set(json.loads(lines["MODULES"])), r.stdout + r.stderr


def test_predict_without_render_imports_no_heavy_stack(tiny_checkpoint, tmp_path):
    (tmp_path / "clip.bvh").write_text(format_bvh(make_bvh(*generate_clip(np.random.default_rng(0), 61))))
    code, mods, out = _probe([f"ckpt_path={tiny_checkpoint}", "input=clip.bvh", "keyframes=[0,15,30,45,60]",
                              "output=out.bvh"], tmp_path)
    assert code == 0, out
    assert (tmp_path / "out.bvh").is_file() and "61 frames (5 keyframes, 56 generated" in out
    assert "torch" in mods and "inbetweening.api.inbetweener" in mods  # it really ran the model
    assert [m for m in HEAVY if m in mods] == []


def test_the_shipped_default_imports_no_torch(tmp_path):
    """Without ckpt_path the shipped ensemble's window graphs run on ONNX Runtime: not even PyTorch is imported."""
    (tmp_path / "clip.bvh").write_text(format_bvh(make_bvh(*generate_clip(np.random.default_rng(0), 61))))
    code, mods, out = _probe(["input=clip.bvh", "keyframes=[0,30,60]", "output=out.bvh"], tmp_path)
    assert code == 0, out
    assert "model.onnx" in out and "onnxruntime" in mods and "inbetweening.runtime.onnx_backend" in mods
    assert "torch" not in mods and [m for m in HEAVY if m in mods] == ["onnxruntime"]


def test_help_and_bad_input_import_not_even_torch(tmp_path):
    code, mods, out = _probe(["--help"], tmp_path)
    assert code == 0 and "usage: python -m inbetweening.predict" in out
    assert "torch" not in mods
    code, mods, out = _probe(["ckpt_path=x.ckpt", "input=missing.bvh", "output=o.bvh", "gap=3"], tmp_path)
    assert code == 2 and "error: input: missing.bvh does not exist" in out
    assert "torch" not in mods


def test_threads_option_is_checked(tmp_path):
    (tmp_path / "clip.bvh").write_text(format_bvh(make_bvh(*generate_clip(np.random.default_rng(0), 20))))
    code, mods, out = _probe(["ckpt_path=x.ckpt", "input=clip.bvh", "output=o.bvh", "gap=3", "threads=0"], tmp_path)
    assert code == 2 and "error: threads: must be >= 1, got 0" in out and "torch" not in mods
