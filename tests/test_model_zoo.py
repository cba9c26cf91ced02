"""Every registered model of the zoo honours the InbetweenModel contract: shapes, exact known pass-through (whole-frame
and per-joint masks), unit quaternions, dynamic length, residual-to-interpolation start, trainability, ONNX export."""
from __future__ import annotations

import warnings

import numpy as np
import pytest
import torch

from conftest import sinusoid_batch
from inbetweening.geometry.skeleton import Skeleton
from inbetweening.models import MODELS, Interpolation, ZeroVelocity, build_model
from inbetweening.predictor.masks import apply_mask

PARENTS = [-1, 0, 1, 2, 1, 4]  # small tree: 0-1-2-3 and 1-4-5
J = len(PARENTS)
MAX_FRAMES = 16


def adjacency(parents=PARENTS) -> list[list[float]]:
    """The parent/child relation matrix with self-loops, from the project's Skeleton."""
    return Skeleton([f"j{i}" for i in range(len(parents))], parents, [[0.0, 0.0, 0.0]] * len(parents)).adjacency(1).tolist()


TINY = {
    "graph_transformer": {"d_model": 16, "depth": 1, "heads": 2, "dropout": 0.0},
    "frame_transformer": {"d_model": 16, "depth": 2, "heads": 2, "ffn_dim": 32, "dropout": 0.0},
    "st_transformer": {"spatial_dim": 8, "spatial_depth": 1, "spatial_heads": 2, "d_model": 16, "temporal_depth": 1,
                       "heads": 2, "dropout": 0.0},
    "resnet_lstm": {"hidden_dim": 32, "res_blocks": 1, "lstm_hidden": 16, "lstm_layers": 2, "dropout": 0.0},
    "unet1d": {"base_channels": 16, "levels": 2, "norm_groups": 4},
    "zero_velocity": {},
    "interpolation": {},
}
ALL = sorted(MODELS)
TRAINABLE = [n for n in ALL if MODELS[n].trainable]
BASELINES = [n for n in ALL if not MODELS[n].trainable]


def tiny(name: str, **kw):
    args = {"num_joints": J, "adjacency": adjacency(), "max_frames": MAX_FRAMES, **TINY[name]}
    return build_model(name, **{**args, **kw})


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


# ------------------------------------------------------------------ contract
@pytest.mark.parametrize("mask", ["frame", "joint"])
@pytest.mark.parametrize("name", ALL)
def test_shape_known_passthrough_unit_quaternions(name, mask):
    model = tiny(name).eval()
    x, known, interp = make_batch(mask=mask)
    with torch.no_grad():
        out = model(x, known, interp)
    assert out.shape == x.shape
    assert torch.equal(out[known], x[known])
    qn = out[..., 3:7].norm(dim=-1)[~known]
    assert torch.allclose(qn, torch.ones_like(qn), atol=1e-5)


@pytest.mark.parametrize("name", ALL)
def test_dynamic_batch_and_length(name):
    model = tiny(name).eval()
    for b, t in [(1, 5), (3, 13)]:
        x, known, interp = make_batch(b, t)
        with torch.no_grad():
            out = model(x, known, interp)
        assert out.shape == (b, t, J, 7)
        assert torch.isfinite(out).all()


@pytest.mark.parametrize("name", TRAINABLE)
def test_too_many_frames_raises(name):
    x, known, _ = make_batch(1, MAX_FRAMES + 1)
    with pytest.raises(ValueError, match="max_frames"):
        tiny(name)(x, known)


@pytest.mark.parametrize("name", TRAINABLE)
def test_per_joint_flags_reach_the_model(name):
    """Only the known flag of one (zero-valued) slot changes: the other predictions must change too."""
    model = tiny(name).eval()
    x, known, _ = make_batch(mask="frame")
    known2 = known.clone()
    known2[:, 4, 2] = True  # x is 0 there in both cases, only the flag differs
    with torch.no_grad():
        a, b = model(x, known), model(x, known2)
    free = ~known2
    assert not torch.allclose(a[free], b[free], atol=1e-6)


@pytest.mark.parametrize("name", [*TRAINABLE, "interpolation"])
def test_residual_to_interpolation_starts_at_interp(name):
    model = tiny(name, residual_to_interpolation=True)
    x, known, interp = make_batch(mask="joint")
    out = model(x, known, interp)
    assert torch.allclose(out, model.finalize(interp, x, known), atol=1e-6)
    if model.trainable:
        out.abs().sum().backward()
        assert sum(p.grad.abs().sum() for p in model.parameters() if p.grad is not None) > 0
        assert model(x, known).shape == x.shape  # interp stays optional


@pytest.mark.parametrize("name", ALL)
def test_parameter_count(name):
    n = sum(p.numel() for p in tiny(name).parameters())
    assert (n > 0) == MODELS[name].trainable


# ------------------------------------------------------------------ trainability
@pytest.mark.parametrize("name", TRAINABLE)
def test_trains(name):
    model = tiny(name)
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


# ------------------------------------------------------------------ ONNX
@pytest.mark.parametrize("name", TRAINABLE)
def test_onnx_export_matches_onnxruntime(name, tmp_path):
    ort = pytest.importorskip("onnxruntime")
    pytest.importorskip("onnx")
    model = tiny(name).eval()
    x, known, _ = make_batch(2, 8, mask="joint")
    path = tmp_path / f"{name}.onnx"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(
            model, (x, known), str(path), dynamo=False, opset_version=17,
            input_names=["x", "known"], output_names=["out"],
            dynamic_axes={"x": {0: "B", 1: "T"}, "known": {0: "B", 1: "T"}, "out": {0: "B", 1: "T"}},
        )
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    x2, known2, _ = make_batch(3, 13, mask="joint", seed=3)  # another B and T (other padding remainder for U-Net)
    (got,) = session.run(None, {"x": x2.numpy(), "known": known2.numpy()})
    with torch.no_grad():
        ref = model(x2, known2).numpy()
    assert got.shape == ref.shape
    np.testing.assert_allclose(got, ref, atol=1e-4, rtol=0)


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
        shown, interp = apply_mask(mask, x_in, known)
        out = model(shown, known, interp)
        np.testing.assert_allclose(out[..., :3].numpy(), want[..., :3].numpy(), rtol=0, atol=1e-12)
        np.testing.assert_allclose(out[..., 3:].numpy(), want[..., 3:].numpy(), rtol=0, atol=1e-7)  # 1e-8 eps of qnormalize
        assert torch.equal(out[known], x[known])
    with pytest.raises(ValueError, match="interp"):
        model(x, known)


# ------------------------------------------------------------------ registry / validation
def test_registry():
    assert set(MODELS) == {"graph_transformer", "frame_transformer", "st_transformer", "resnet_lstm", "unet1d",
                           "zero_velocity", "interpolation"}
    assert set(BASELINES) == {"zero_velocity", "interpolation"}
    for name in ALL:
        assert isinstance(tiny(name), MODELS[name])


@pytest.mark.parametrize(
    "name,kw,match",
    [
        ("frame_transformer", {"heads": 3}, "heads"),
        ("frame_transformer", {"depth": 0}, "depth"),
        ("st_transformer", {"spatial_heads": 3}, "spatial_heads"),
        ("resnet_lstm", {"lstm_layers": 0}, "lstm_layers"),
        ("unet1d", {"norm_groups": 3}, "norm_groups"),
        ("unet1d", {"levels": 0}, "levels"),
        ("zero_velocity", {"feature_dim": 3}, "feature_dim"),
        ("resnet_lstm", {"adjacency": [[1.0] * J] * (J - 1)}, "adjacency"),
    ],
)
def test_invalid_args(name, kw, match):
    with pytest.raises(ValueError, match=match):
        tiny(name, **kw)


@pytest.mark.parametrize("name", ALL)
def test_wrong_input_shape_raises(name):
    x, known, interp = make_batch()
    with pytest.raises(ValueError, match="x must be"):
        tiny(name)(x[:, :, :4], known[:, :, :4], interp[:, :, :4])


def test_baselines_ignore_architecture_settings():
    for name in ("zero_velocity", "interpolation"):
        m = MODELS[name](num_joints=J, adjacency=None, dropout=0.0, depth=6)
        assert sum(p.numel() for p in m.parameters()) == 0
