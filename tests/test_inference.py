"""The windows -> predictions path: known-frame centring is leak-free, keyframes are exact, batching is invisible."""
from __future__ import annotations

import numpy as np
import pytest
import torch
from inbetweening.predictor.features import global_positions
from inbetweening.predictor.inference import (
    known_centre_shift,
    masked_forward,
    predict_features,
    predict_transitions,
    window_features,
)

from inbetweening.data import windows as W
from inbetweening.evaluation import benchmark as B
from inbetweening.geometry.skeleton import Skeleton
from inbetweening.models import build_model
from inbetweening.predictor.masks import transition_known

NAMES = ("root", "spine", "head", "leg")
PARENTS = (-1, 0, 1, 0)
OFFSETS = np.array([[0.0, 0, 0], [0.0, 1.0, 0], [0.0, 1.0, 0], [0.3, -1.0, 0]])
SK = Skeleton(NAMES, PARENTS, OFFSETS)
MEAN = np.linspace(-1, 1, 12)
STD = np.array([2.0, 1.0, 3.0, 0.5, 1.5, 4.0, 1.0, 2.5, 0.25, 3.0, 1.0, 0.75])  # per joint coordinate


def windows(seed=0, b=3, t=20):
    rng = np.random.default_rng(seed)
    root = np.cumsum(rng.normal(size=(b, t, 3)), axis=1)
    q = rng.normal(size=(b, t, 4, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return root, q


def net(seed=0):
    torch.manual_seed(seed)
    m = build_model("frame_transformer", num_joints=4, adjacency=SK.adjacency().tolist(), d_model=16, depth=1,
                    heads=2, ffn_dim=16, dropout=0.0, max_frames=64)
    with torch.no_grad():  # non-zero output head: a network that really mixes every input frame
        for p in m.parameters():
            p.add_(0.05 * torch.randn_like(p))
    return m.eval()


def test_window_features_numpy_torch_and_nan():
    root, q = windows()
    root[0, 5] = np.nan
    f = window_features(root, q, SK, MEAN, STD)
    ft = window_features(torch.from_numpy(root), torch.from_numpy(q), SK, MEAN, STD, dtype=torch.float64)
    assert f.dtype == torch.float32 and ft.dtype == torch.float64 and f.shape == (3, 20, 4, 7)
    assert torch.isnan(f[0, 5, :, :3]).all() and torch.isfinite(f[1]).all()
    np.testing.assert_allclose(f[1].numpy(), ft[1].numpy(), rtol=1e-6, atol=1e-6)


def test_known_centre_shift_hand_derived_per_joint_std():
    feats = torch.zeros(1, 4, 4, 7, dtype=torch.float64)
    feats[0, :, 0, 0] = torch.tensor([1.0, 3.0, 100.0, 5.0])  # root x (z-scored); frame 2 unknown
    feats[0, :, 0, 2] = torch.tensor([2.0, 2.0, -50.0, 8.0])  # root z
    known = torch.ones(1, 4, 4, dtype=torch.bool)
    known[0, 2] = False
    shift = known_centre_shift(feats, known, STD)
    assert shift.shape == (1, 1, 4, 7)
    # mean over known frames in root feature units: x 3, z 4; world shift = (3 * std_root_x, 4 * std_root_z)
    dx, dz = 3.0 * STD[0], 4.0 * STD[2]
    s = STD.reshape(4, 3)
    np.testing.assert_allclose(shift[0, 0, :, 0].numpy(), dx / s[:, 0], rtol=1e-12)
    np.testing.assert_allclose(shift[0, 0, :, 2].numpy(), dz / s[:, 2], rtol=1e-12)
    assert (shift[..., [1, 3, 4, 5, 6]] == 0).all()
    # per-joint masks (mocap recovery): the ROOT's known frames decide; a single known frame is its own mean
    per_joint = torch.zeros(1, 4, 4, dtype=torch.bool)
    per_joint[0, 3, 0] = True  # root known at frame 3 only
    per_joint[0, :, 1] = True  # joint 1 known everywhere
    one = known_centre_shift(feats, per_joint, STD)
    np.testing.assert_allclose(one[0, 0, 0, [0, 2]].numpy(), [5.0, 8.0], rtol=1e-12)


@pytest.mark.parametrize("mask", ["lerp", "zero"])
def test_known_and_last_centring_are_leak_free_and_window_centring_is_not(mask):
    """Change ONLY the ground truth of the frames to predict: with centre=known the prediction is unchanged;
    with centre=window (features built from whole-window-centred benchmark windows) it changes."""
    n_past, n = 10, 8
    root, q = windows(1, b=2, t=n_past + n + 1)
    other_root = root.copy()
    other_root[:, n_past : n_past + n] += np.array([40.0, 3.0, -25.0])  # the unknown frames move far away
    other_q = q.copy()
    other_q[:, n_past : n_past + n] = q[:, :1]
    model = net(2)
    preds = {}
    for centre in ("known", "last", "window"):
        outs = []
        for r, qq in ((root, q), (other_root, other_q)):
            Xn, Qn = W.centre_and_rotate(SK.local_positions(r), qq, PARENTS, forward_axis=(0.0, 0.0, 1.0))
            feats = window_features(Xn[:, :, 0], Qn, SK, MEAN, STD, dtype=torch.float64)
            known = transition_known(2, n_past + n + 1, 4, n_past, n)
            pred, _ = predict_features(model.double(), mask, feats, known, centre, STD)
            assert torch.equal(pred[known], feats[known])  # keyframes and context bit-exact
            # compare world positions relative to the first frame's root, which the unknown frames do not move
            gp = global_positions(pred, MEAN, STD)
            outs.append((gp - global_positions(feats, MEAN, STD)[:, :1, :1]).numpy())
        preds[centre] = outs
    # the whole-window centring moved every known frame too; compare after undoing it via the first root
    known_equal = np.abs(preds["known"][0] - preds["known"][1]).max()
    last_equal = np.abs(preds["last"][0] - preds["last"][1]).max()
    window_change = np.abs(preds["window"][0] - preds["window"][1]).max()
    assert known_equal < 1e-9, known_equal
    assert last_equal < 1e-9, last_equal
    assert window_change > 1e-3, window_change


def test_masked_forward_target_is_in_the_prediction_frame():
    root, q = windows(2)
    feats = window_features(root, q, SK, MEAN, STD, dtype=torch.float64)
    known = transition_known(3, 20, 4, 10, 6)
    model = net(3).double()
    pred, interp, target = masked_forward(model, "lerp", feats, known, "known", STD)
    np.testing.assert_allclose((feats - target).numpy(), known_centre_shift(feats, known, STD).expand_as(feats).numpy(),
                               atol=1e-12)
    assert pred.requires_grad
    _, _, same = masked_forward(model, "lerp", feats, known, "window", STD)
    assert torch.equal(same, feats)
    with pytest.raises(ValueError, match=r"centre must be one of \['window', 'known', 'last'\], got 'middle'"):
        masked_forward(model, "lerp", feats, known, "middle", STD)


def test_predict_transitions_matches_the_numpy_interpolation_and_ignores_batching():
    root, q = windows(3, b=5, t=10 + 7 + 1)
    root[:, 10:17] = np.nan
    q[:, 10:17] = np.nan
    interp = build_model("interpolation", num_joints=4, adjacency=SK.adjacency().tolist())
    for centre in ("known", "window"):
        r, qq = predict_transitions(interp, "lerp", root, q, 7, SK, MEAN, STD, centre=centre)
        assert r.dtype == np.float64 and r.shape == (5, 7, 3) and qq.shape == (5, 7, 4, 4)
        wr, wq = B.interpolation(root, q, 7)
        w = np.linspace(0, 1, 9)[1:-1]  # the torch path uses exact weights; the numpy reference float32 ones
        np.testing.assert_allclose(r, root[:, 9:10] + w[None, :, None] * (root[:, 17:18] - root[:, 9:10]), atol=1e-5)
        np.testing.assert_allclose(np.abs((qq * wq).sum(-1)), 1.0, atol=1e-5)
    model = net(4)
    big = predict_transitions(model, "lerp", root, q, 7, SK, MEAN, STD, centre="known")
    small = predict_transitions(model, "lerp", root, q, 7, SK, MEAN, STD, centre="known", batch_size=2)
    np.testing.assert_allclose(big[0], small[0], atol=1e-5)
    np.testing.assert_allclose(big[1], small[1], atol=1e-6)
    other = predict_transitions(model, "lerp", root[:, 2:], q[:, 2:], 7, SK, MEAN, STD, n_past=8, centre="known")
    assert other[0].shape == (5, 7, 3)
