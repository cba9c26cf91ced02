"""Checkpoint loading: no code runs, non-finite weights and foreign files are one clear error."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from inbetweening.predictor.checkpoint import CheckpointError, non_finite_tensor, read_checkpoint
from inbetweening.training.module import load_module

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "models" / "bn2_reference" / "model.ckpt"


class _Payload:
    """Unpickling this object runs ``os.system`` (the classic pickle exploit)."""

    def __init__(self, marker: Path):
        self.marker = marker

    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


def _malicious_checkpoint(tmp_path: Path) -> tuple[Path, Path]:
    marker = tmp_path / "payload_ran"
    ckpt = torch.load(REFERENCE, map_location="cpu", weights_only=True)
    ckpt["hyper_parameters"]["note"] = _Payload(marker)
    path = tmp_path / "evil.ckpt"
    torch.save(ckpt, path)
    return path, marker


def test_code_payload_is_refused_without_running(tmp_path):
    path, marker = _malicious_checkpoint(tmp_path)
    with pytest.raises(CheckpointError, match=r"refused: it holds a Python object \(posix.system\) that could run code"):
        read_checkpoint(path)
    with pytest.raises(CheckpointError, match="refused"):
        load_module(path)
    assert not marker.exists()
    # the payload is real: an unsafe load would have run it
    torch.load(path, weights_only=False)
    assert marker.exists()


@pytest.mark.slow
def test_predict_and_eval_refuse_payload_in_a_subprocess(tmp_path):
    path, marker = _malicious_checkpoint(tmp_path)
    import numpy as np

    from inbetweening.data.bvh_writer import write_bvh
    from inbetweening.data.synthetic import generate_clip, make_bvh

    bvh = tmp_path / "in.bvh"
    q, r = generate_clip(np.random.default_rng(0), 40)
    write_bvh(make_bvh(q, r), bvh)
    for cmd in ([sys.executable, "-m", "inbetweening.predict", f"ckpt_path={path}", f"input={bvh}",
                 f"output={tmp_path / 'o.bvh'}", "keyframes=[0,10]"],
                [sys.executable, "-m", "inbetweening.export", f"ckpt_path={path}", f"output={tmp_path / 'o.onnx'}"]):
        r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=300)
        assert r.returncode == 2, r.stderr
        assert r.stderr.startswith("error: ckpt_path:") and "refused" in r.stderr and len(r.stderr.splitlines()) == 1
        assert not marker.exists()


def test_non_finite_weights_are_named(tmp_path):
    ckpt = torch.load(REFERENCE, map_location="cpu", weights_only=True)
    key = next(k for k, v in ckpt["state_dict"].items() if v.is_floating_point())
    ckpt["state_dict"][key] = ckpt["state_dict"][key].clone()
    ckpt["state_dict"][key].view(-1)[3] = float("nan")
    path = tmp_path / "nan.ckpt"
    torch.save(ckpt, path)
    assert non_finite_tensor(ckpt["state_dict"]) == key
    with pytest.raises(CheckpointError, match=rf"{path}.*non-finite weights \({key} holds NaN or inf\)"):
        load_module(path)
    assert non_finite_tensor({"a": torch.zeros(2), "step": torch.tensor(3)}) is None
    assert non_finite_tensor({"a": float("inf")}) == "a"


@pytest.mark.parametrize("content, match", [
    (None, "does not exist"),
    (b"not a checkpoint", "is not a readable PyTorch checkpoint"),
    ({"state_dict": {}}, "is not an inbetweening checkpoint"),
])
def test_foreign_files(tmp_path, content, match):
    path = tmp_path / "x.ckpt"
    if isinstance(content, bytes):
        path.write_bytes(content)
    elif content is not None:
        torch.save(content, path)
    with pytest.raises(CheckpointError, match=match):
        read_checkpoint(path)


def test_reference_model_loads_safely_in_eval_mode():
    module = load_module(REFERENCE)
    assert not module.training and module.skeleton.num_joints == 21


def test_architecture_mismatch_is_one_error(tmp_path):
    ckpt = torch.load(REFERENCE, map_location="cpu", weights_only=True)
    ckpt["hyper_parameters"]["model"] = dict(ckpt["hyper_parameters"]["model"], d_model=32)
    path = tmp_path / "other.ckpt"
    torch.save(ckpt, path)
    with pytest.raises(CheckpointError, match="does not match this version's models"):
        load_module(path)
