"""Training options for speed: ``trainer.precision=bf16-mixed`` and ``compile=true`` (tiny runs on the CPU)."""
from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from conftest import TINY, TINY_PARENTS, compose_cfg, sinusoid_batch, tiny_model
from inbetweening.models import MODELS
from inbetweening.predictor.masks import apply_mask
from inbetweening.representation import GlobalPosLocalQuat
from inbetweening.training.config import ConfigError, validate
from inbetweening.training.module import InbetweenModule
from inbetweening.training.train import train

BASE = [*TINY, "callbacks=none", "logger=none", "threads=1"]


def run_train(tmp_path, cache_dir, overrides, name):
    cfg = compose_cfg("train", [*BASE, *overrides], tmp_path / name, cache_dir)
    metrics = train(cfg)
    ckpts = sorted((tmp_path / name / "checkpoints").glob("*.ckpt"))
    assert ckpts, f"no checkpoint under {tmp_path / name}"
    return metrics, ckpts[-1]


@pytest.mark.parametrize("name", sorted(MODELS))
@pytest.mark.parametrize("residual", [False, True])
def test_outputs_stay_float32_with_unit_quaternions_under_bf16_autocast(name, residual):
    """The contract under ``torch.autocast("cpu", bfloat16)``: float32 out, unit quaternions at float32 precision,
    known values bit-exact (before the fix, four models returned quaternions 7e-3 off unit norm)."""
    _, known, y = sinusoid_batch(len(TINY_PARENTS))
    x, interp = apply_mask("lerp", y, known, GlobalPosLocalQuat)
    model = tiny_model(name, residual_to_interpolation=residual)
    with torch.autocast("cpu", dtype=torch.bfloat16):
        out = model(x, known, interp)
    assert out.dtype == torch.float32
    assert torch.isfinite(out).all()
    assert (out[..., 3:7].norm(dim=-1) - 1).abs().max() < 1e-5
    assert torch.equal(out[known], x[known])


def test_bf16_mixed_training_gives_finite_metrics_and_a_float32_checkpoint(tmp_path, cache_dir):
    metrics, ckpt = run_train(tmp_path, cache_dir, ["trainer.precision=bf16-mixed"], "bf16")
    assert metrics and all(np.isfinite(v) for v in metrics.values())
    res = json.loads((tmp_path / "bf16" / "benchmark.json").read_text())
    assert all(np.isfinite(v) for v in res["metrics"].values())
    state = torch.load(ckpt, map_location="cpu", weights_only=True)["state_dict"]
    floats = {k: v.dtype for k, v in state.items() if v.is_floating_point()}
    assert floats and set(floats.values()) == {torch.float32}, floats
    module = InbetweenModule.load_from_checkpoint(ckpt, map_location="cpu").eval()
    pr, j = module.predictor, module.skeleton.num_joints
    g = torch.Generator().manual_seed(0)
    root = torch.randn(2, pr.n_past + 6, 3, generator=g, dtype=torch.float64) * 10
    q = torch.nn.functional.normalize(torch.randn(2, pr.n_past + 6, j, 4, generator=g, dtype=torch.float64), dim=-1)
    out = pr.predict_windows(root, q, pr.transition_known(2, pr.n_past + 6, 5))
    pred = out.pred
    assert pred.dtype == torch.float32 and torch.isfinite(pred).all()
    assert torch.isfinite(out.root).all() and torch.isfinite(out.local_q).all()
    assert (pred[..., 3:7].norm(dim=-1) - 1).abs().max() < 1e-5


def test_compile_trains_through_the_compiled_forward_and_keeps_the_state_dict_keys(tmp_path, cache_dir):
    """``compile=true`` (6-30 s for the tiny model on this CPU, warm or cold inductor cache): the training steps run the
    compiled forward, and the checkpoint has the keys of an eager run's and loads as one."""
    from torch._dynamo.utils import counters

    torch._dynamo.reset()
    counters.clear()
    metrics, ckpt = run_train(tmp_path, cache_dir, ["compile=true"], "compiled")
    assert counters["stats"]["unique_graphs"] >= 1  # something was compiled
    # one graph per forward: a data-dependent check inside it (e.g. reading the attention mask's values per layer)
    # would split it at every layer, and the split graphs cannot fuse across the break
    assert not counters["graph_break"], dict(counters["graph_break"])
    assert all(np.isfinite(v) for v in metrics.values())
    _, eager = run_train(tmp_path, cache_dir, [], "eager")
    keys = list(torch.load(ckpt, map_location="cpu", weights_only=True)["state_dict"])
    assert keys == list(torch.load(eager, map_location="cpu", weights_only=True)["state_dict"])
    assert not any("_orig_mod" in k for k in keys)
    module = InbetweenModule.load_from_checkpoint(ckpt, map_location="cpu")
    assert module._train_forward is None  # a loaded checkpoint runs eagerly unless asked
    torch._dynamo.reset()


def test_compile_network_leaves_validation_eager_and_can_be_turned_off(tmp_path, cache_dir):
    """The compiled forward is used for the training loss only (no compilation here: nothing is run)."""
    cfg = compose_cfg("train", BASE, tmp_path, cache_dir)
    from inbetweening.training.builders import make_datamodule, make_module

    dm = make_datamodule(cfg)
    dm.prepare_data()
    dm.setup("fit")
    module = make_module(cfg, dm)
    keys = list(module.state_dict())
    module.compile_network(True)
    assert callable(module._train_forward) and list(module.state_dict()) == keys
    module.compile_network(False)
    assert module._train_forward is None


@pytest.mark.parametrize("override, message", [
    ("compile=maybe", "compile: must be true or false, got 'maybe'"),
    ("trainer.precision=bf17", "trainer.precision: must be one of"),
])
def test_bad_speed_options_fail_with_one_line(override, message, tmp_path, cache_dir):
    cfg = compose_cfg("train", [*BASE, override], tmp_path, cache_dir)
    with pytest.raises(ConfigError, match=message.replace("(", r"\(")):
        validate(cfg)
