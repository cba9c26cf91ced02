"""Derived input channels (``model.inputs``: 6-D rotations, velocities) and the keyframe-consistency output
(``forward(..., with_raw=True)``) of the InbetweenModel contract, for every trainable model of the registry."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from conftest import TINY_PARENTS, compose_cfg, tiny_model
from inbetweening.geometry.quaternion import qmul, qnormalize, quat_to_matrix_np, quat_to_rot6d
from inbetweening.models import MODELS
from inbetweening.models.base import INPUTS, VELOCITY_SCALE, rot6d_input, velocity_input
from inbetweening.training import losses as L
from inbetweening.training.config import ConfigError, validate
from test_models_base import make_batch, onnx_round_trip

J = len(TINY_PARENTS)
POS, QUAT = slice(0, 3), slice(3, 7)  # the default representation's channels (GlobalPosLocalQuat)
TRAINABLE = [n for n in sorted(MODELS) if MODELS[n].trainable]
BOTH = ("rot6d", "velocity")


def test_rot6d_is_the_first_two_matrix_columns_and_sign_free():
    rng = np.random.default_rng(0)
    q = qnormalize(rng.normal(size=(5, 3, 4)))
    m = quat_to_matrix_np(q)
    want = np.concatenate([m[..., :, 0], m[..., :, 1]], axis=-1)
    np.testing.assert_allclose(quat_to_rot6d(q), want, atol=1e-12)
    np.testing.assert_allclose(quat_to_rot6d(-q), want, atol=1e-12)  # q and -q: one rotation, one value
    t = torch.from_numpy(q)
    np.testing.assert_allclose(quat_to_rot6d(t).numpy(), want, atol=1e-12)  # the torch path is the same function
    # composition is seen: rot6d of q*r differs from rot6d of q unless r is the identity
    r = qnormalize(rng.normal(size=(5, 3, 4)))
    assert np.abs(quat_to_rot6d(qmul(q, r)) - want).max() > 1e-3


def test_velocity_input_is_the_scaled_frame_difference_of_the_positions():
    x, _, _ = make_batch(2, 9)
    v = velocity_input(x, POS, QUAT)
    assert v.shape == (2, 9, J, 3)
    assert torch.equal(v[:, 0], torch.zeros_like(v[:, 0]))
    torch.testing.assert_close(v[:, 1:], (x[:, 1:, :, :3] - x[:, :-1, :, :3]) * VELOCITY_SCALE)
    assert rot6d_input(x, POS, QUAT).shape == (2, 9, J, 6)


@pytest.mark.parametrize("name", TRAINABLE)
def test_inputs_widen_the_input_only(name):
    """``input_dim`` grows by the channels of each input; the output keeps ``F``; the contract still holds:
    keyframes bit-exact, unit quaternions, an untrained residual model returns the interpolation exactly."""
    plain, wide = tiny_model(name), tiny_model(name, inputs=list(BOTH))
    assert plain.input_dim == 7 and wide.input_dim == 7 + sum(INPUTS[n][0] for n in BOTH) == 16
    assert sum(p.numel() for p in wide.parameters()) > sum(p.numel() for p in plain.parameters())
    x, known, interp = make_batch(3, 13, seed=3)
    out = wide.eval()(x, known, interp)
    assert out.shape == x.shape and torch.equal(out[known], x[known])
    qn = out[..., 3:7].norm(dim=-1)[~known]
    assert torch.allclose(qn, torch.ones_like(qn), atol=1e-5)
    res = tiny_model(name, inputs=["velocity"], residual_to_interpolation=True)
    assert torch.equal(res(x, known, interp), res.finalize(interp, x, known))


@pytest.mark.parametrize("name", TRAINABLE)
def test_the_network_reads_the_derived_channels(name):
    """The network is given ``x`` followed by exactly the derived channels, and the output depends on them (they
    receive gradients)."""
    model = tiny_model(name, inputs=list(BOTH))
    x, known, interp = make_batch()
    x.requires_grad_()
    seen = {}
    orig = model.network

    def spy(xin, *a):
        seen["x"] = xin
        xin.retain_grad()
        return orig(xin, *a)

    model.network = spy
    out = model(x, known, interp)
    assert seen["x"].shape[-1] == 16
    with torch.no_grad():
        assert torch.equal(seen["x"][..., :7], x)
        torch.testing.assert_close(seen["x"][..., 7:13], rot6d_input(x, POS, QUAT))
        torch.testing.assert_close(seen["x"][..., 13:], velocity_input(x, POS, QUAT))
    out[~known].sum().backward()
    assert seen["x"].grad[..., 7:].abs().sum() > 0


@pytest.mark.parametrize("name", ["frame_transformer", "graph_transformer"])
def test_onnx_export_with_inputs_matches_onnxruntime(name, tmp_path):
    ort = pytest.importorskip("onnxruntime")
    pytest.importorskip("onnx")
    model = tiny_model(name, inputs=list(BOTH), residual_to_interpolation=True).eval()
    with torch.no_grad():
        for p in model.output_head():
            p.normal_(0.0, 0.1)
    onnx_round_trip(ort, model, tmp_path / f"{name}.onnx")


@pytest.mark.parametrize("bad, match", [("[kicks]", r"unknown input\(s\) \['kicks'\]"),
                                        ("rot6d", "must be a list of names"),
                                        ("[rot6d,rot6d]", "names must be distinct")])
def test_bad_inputs_name_the_key(bad, match, tmp_path, cache_dir):
    cfg = compose_cfg("train", ["model=frame_transformer", f"model.inputs={bad}"], tmp_path, cache_dir)
    with pytest.raises(ConfigError, match=rf"model\.inputs: {match}"):
        validate(cfg)


@pytest.mark.parametrize("name", TRAINABLE)
def test_with_raw_returns_the_output_before_the_keyframes_are_copied_back(name):
    model = tiny_model(name)  # not residual: the raw output is the network's own guess everywhere
    x, known, interp = make_batch()
    pred, raw = model(x, known, interp, with_raw=True)
    assert torch.equal(pred, model(x, known, interp))
    assert torch.equal(raw[~known], pred[~known])
    assert not torch.allclose(raw[known], x[known])  # a random network does not reproduce its keyframes
    qn = raw[..., 3:7].norm(dim=-1)
    assert torch.allclose(qn, torch.ones_like(qn), atol=1e-5)
    # the keyframe loss reaches the network through the known frames only
    L.keyframe(raw, x, known).backward()
    assert any(p.grad is not None and p.grad.abs().sum() > 0 for p in model.output_head())


def test_keyframe_loss_is_zero_on_its_keyframes_and_needs_raw():
    x, known, interp = make_batch()
    raw = x.clone()
    raw[~known] += 5.0  # transition frames are not in the term
    assert float(L.keyframe(raw, x, known)) == 0.0
    raw[known] += 1.0
    assert float(L.keyframe(raw, x, known)) == pytest.approx(1.0)
    with pytest.raises(ValueError, match="loss.keyframe: needs the network's raw output"):
        L.total_loss(x, x, ~known, {"l1": 1.0, "keyframe": 1.0}, None)
    total, terms = L.total_loss(x, x, ~known, {"l1": 0.0, "keyframe": 2.0}, None, raw=raw, known=known)
    assert float(total) == pytest.approx(2.0) and set(terms) == {"l1", "keyframe"}
