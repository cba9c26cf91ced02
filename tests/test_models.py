"""Behaviour of the individual models of the zoo: per-joint flags reach every network, every network trains, the
baselines' closed forms, each model's own setting checks.  The common contract (shapes, exact known pass-through,
unit quaternions, residual start, gradients, input checks, state_dict, ONNX) is tests/test_models_base.py."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from conftest import TINY_PARENTS, sinusoid_batch, tiny_model
from conftest import tiny_adjacency as adjacency
from inbetweening.models import MODELS, Interpolation, ZeroVelocity
from inbetweening.predictor.masks import apply_mask
from inbetweening.representation import GlobalPosLocalQuat

J = len(TINY_PARENTS)
ALL = sorted(MODELS)
TRAINABLE = [n for n in ALL if MODELS[n].trainable]


def make_batch(b=2, t=8, mask="frame", seed=0):
    """Masked input ``x``, ``known`` and a (stand-in) interpolation ``interp`` with unit quaternions."""
    g = torch.Generator().manual_seed(seed)
    y = torch.randn(b, t, J, 7, generator=g)
    y = torch.cat([y[..., :3], y[..., 3:] / y[..., 3:].norm(dim=-1, keepdim=True)], dim=-1)
    known = torch.zeros(b, t, J, dtype=torch.bool)
    known[:, :2] = True
    known[:, -1] = True
    if mask == "joint":  # mocap recovery: random joints missing over the window, some frames fully missing
        known = torch.rand(b, t, J, generator=g) > 0.4
        known[:, 0, 0] = True
    interp = torch.randn(b, t, J, 7, generator=g)
    return y * known[..., None], known, interp


@pytest.fixture(autouse=True)
def _seed():
    torch.manual_seed(0)


@pytest.mark.parametrize("name", TRAINABLE)
def test_per_joint_flags_reach_the_model(name):
    """Only the known flag of one (zero-valued) slot changes: the other predictions must change too."""
    model = tiny_model(name).eval()
    x, known, _ = make_batch(mask="frame")
    known2 = known.clone()
    known2[:, 4, 2] = True  # x is 0 there in both cases, only the flag differs
    with torch.no_grad():
        a, b = model(x, known), model(x, known2)
    free = ~known2
    assert not torch.allclose(a[free], b[free], atol=1e-6)


# ------------------------------------------------------------------ trainability
@pytest.mark.parametrize("name", TRAINABLE)
def test_trains(name):
    model = tiny_model(name)
    opt = torch.optim.Adam(model.parameters(), lr=3e-3)
    x, known, y = sinusoid_batch(J, b=8, island=True)
    free = ~known
    losses = []
    for _ in range(20):
        loss = (model(x, known) - y).abs()[free].mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(loss.item())
    assert sum(losses[-3:]) / 3 < 0.8 * losses[0], losses


# ------------------------------------------------------------------ baselines
def test_zero_velocity_holds_last_known_value():
    model = ZeroVelocity(num_joints=J, adjacency=adjacency())
    x, known, _ = make_batch(1, 8, mask="frame")
    known[0, 4, 3] = True  # a single known joint inside the gap
    x[0, 4, 3] = torch.tensor([9.0, 9.0, 9.0, 0.0, 1.0, 0.0, 0.0])
    out = model(x, known)
    assert torch.equal(out[0, 2:7, 0], x[0, 1, 0].expand(5, 7))  # whole-frame gap: last context frame repeated
    assert torch.equal(out[0, 2:4, 3], x[0, 1, 3].expand(2, 7))
    assert torch.equal(out[0, 5:7, 3], x[0, 4, 3].expand(2, 7))  # per-joint: the latest earlier known value
    known[0, 0, 5] = known[0, 1, 5] = False  # no earlier known frame -> the next known one
    out = model(x, known)
    assert torch.equal(out[0, 0:2, 5], x[0, 7, 5].expand(2, 7))


def test_zero_velocity_joint_never_known_gets_unit_quaternion():
    x, known, _ = make_batch(1, 6)
    known[:, :, 2] = False
    out = ZeroVelocity(num_joints=J, adjacency=adjacency())(x * known[..., None], known)
    assert torch.allclose(out[0, :, 2, 3:], torch.tensor([1.0, 0.0, 0.0, 0.0]).expand(6, 4))


def _yaw_q(theta):
    """Rotation by ``theta`` about y: ``[cos(theta/2), 0, sin(theta/2), 0]``."""
    theta = torch.as_tensor(theta, dtype=torch.float64)
    z = torch.zeros_like(theta)
    return torch.stack([torch.cos(theta / 2), z, torch.sin(theta / 2), z], -1)


def test_interpolation_model_is_lerp_and_slerp_in_closed_form():
    """Known frames 0, 1 and 6 (and joint 2 also at frame 4): the model's output in the gap is the hand-computed
    lerp of positions and, for rotations about one axis, slerp = linear interpolation of the angle."""
    t = 7
    g = torch.Generator().manual_seed(5)
    pos = torch.randn(1, t, J, 3, generator=g, dtype=torch.float64) * 10
    theta = torch.rand(1, t, J, generator=g, dtype=torch.float64) * 3.0  # frame 0 (and unknown frames): anything
    jj = torch.arange(J, dtype=torch.float64)
    theta[0, 1] = 0.3 * jj - 0.8
    theta[0, 6] = theta[0, 1] + (1.0 + 0.3 * jj) * (-1.0) ** jj  # 0.3 < |difference| < pi: slerp proper, short arc
    theta[0, 4, 2] = theta[0, 1, 2] - 0.9
    x = torch.cat([pos, _yaw_q(theta)], -1)
    known = torch.zeros(1, t, J, dtype=torch.bool)
    known[:, [0, 1, 6]] = True
    known[0, 4, 2] = True  # a per-joint island inside the gap
    want = x.clone()
    for j in range(J):
        keys = [1, 4, 6] if j == 2 else [1, 6]
        for a, b in zip(keys[:-1], keys[1:]):
            for f in range(a + 1, b):
                w = (f - a) / (b - a)
                want[0, f, j, :3] = pos[0, a, j] + w * (pos[0, b, j] - pos[0, a, j])
                want[0, f, j, 3:] = _yaw_q(theta[0, a, j] + w * (theta[0, b, j] - theta[0, a, j]))
    x_in = x.clone()
    x_in[~known] = float("nan")  # unknown values are never read
    model = Interpolation(num_joints=J, adjacency=adjacency())
    for mask in ("lerp", "zero"):  # with the zero mask the model's input holds zeros: the result must come from interp
        shown, interp = apply_mask(mask, x_in, known, GlobalPosLocalQuat)
        out = model(shown, known, interp)
        np.testing.assert_allclose(out[..., :3].numpy(), want[..., :3].numpy(), rtol=0, atol=1e-12)
        np.testing.assert_allclose(out[..., 3:].numpy(), want[..., 3:].numpy(), rtol=0, atol=1e-7)  # 1e-8 eps of qnormalize
        assert torch.equal(out[known], x[known])
    with pytest.raises(ValueError, match="interp"):
        model(x, known)


# ------------------------------------------------------------------ validation
@pytest.mark.parametrize(
    "name,kw,match",
    [
        ("frame_transformer", {"heads": 3}, r"^FrameTransformer: heads: 3 must divide d_model=16$"),
        ("frame_transformer", {"depth": 0}, r"^FrameTransformer: depth: must be an integer >= 1, got 0$"),
        ("frame_transformer", {"norm": "group"}, r"^FrameTransformer: norm: must be one of \['layer', 'batch'\]"),
        ("st_transformer", {"spatial_heads": 3}, r"^STTransformer: spatial_heads: 3 must divide spatial_dim=8$"),
        ("st_transformer", {"ffn_dim": 0}, r"^STTransformer: ffn_dim: must be an integer >= 1"),
        ("resnet_lstm", {"lstm_layers": 0}, r"^ResNetLSTM: lstm_layers: must be an integer >= 1"),
        ("resnet_lstm", {"res_blocks": -1}, r"^ResNetLSTM: res_blocks: must be an integer >= 0"),
        ("resnet_lstm", {"activation": "swish"}, r"^ResNetLSTM: activation: must be one of"),
        ("unet1d", {"norm_groups": 3}, r"^UNet1D: norm_groups: 3 must divide base_channels=16$"),
        ("unet1d", {"levels": 0}, r"^UNet1D: levels: must be an integer >= 1"),
        ("unet1d", {"base_channels": 16.0}, r"^UNet1D: base_channels: must be an integer >= 1, got 16.0$"),
    ],
)
def test_invalid_args(name, kw, match):
    with pytest.raises(ValueError, match=match):
        tiny_model(name, **kw)


def test_baselines_ignore_architecture_settings():
    for name in ("zero_velocity", "interpolation"):
        m = MODELS[name](num_joints=J, adjacency=None, dropout=0.0, depth=6)
        assert sum(p.numel() for p in m.parameters()) == 0
