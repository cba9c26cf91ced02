"""Window canonicalisation (geometry/canonical.py) and the single interpolation (geometry/interp.py)."""
from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from inbetweening.data import windows as W
from inbetweening.evaluation import benchmark as B
from inbetweening.geometry import canonical as C
from inbetweening.geometry.interp import interpolate_keyframes, interpolate_pose, lerp
from inbetweening.geometry.quaternion import qmul, qrot, slerp_np
from inbetweening.predictor.masks import lerp_fill
from inbetweening.representation import GlobalPosLocalQuat


def _windows(seed=0, b=3, t=9, j=4):
    rng = np.random.default_rng(seed)
    root = np.cumsum(rng.normal(size=(b, t, 3)), axis=-2) * 10
    q = rng.normal(size=(b, t, j, 4))
    return root, q / np.linalg.norm(q, axis=-1, keepdims=True)


def _yaw(deg):
    return np.array([math.cos(math.radians(deg) / 2), 0.0, math.sin(math.radians(deg) / 2), 0.0])


@pytest.mark.parametrize("lib", ["numpy", "torch"])
@pytest.mark.parametrize("axis", [(0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (0.3, 0.5, 0.8)])
def test_canonicalise_then_inverse_is_identity_and_faces_plus_x(lib, axis):
    root, q = _windows()
    known = np.zeros(root.shape[:2], dtype=bool)
    known[:, :4] = True
    known[:, -1] = True
    if lib == "torch":
        root, q, known = torch.from_numpy(root), torch.from_numpy(q), torch.from_numpy(known)
    centre, rot = C.canonical_frame(root, q, axis, 3, known)
    assert tuple(centre.shape) == (3, 1, 3) and tuple(rot.shape) == (3, 1, 4)
    cr, cq = C.canonicalise(root, q, centre, rot)
    cr_, cq_ = (np.asarray(cr), np.asarray(cq))
    # the known frames' root XZ is centred, heights are unchanged, other joints' local rotations untouched
    np.testing.assert_allclose(np.asarray(C.masked_mean(cr, known))[..., [0, 2]], 0.0, atol=1e-9)
    np.testing.assert_allclose(cr_[..., 1], np.asarray(root)[..., 1], atol=1e-9)
    assert np.array_equal(cq_[..., 1:, :], np.asarray(q)[..., 1:, :])
    # the root's forward axis at frame 3 now points to +X (in the XZ plane)
    fwd = qrot(cq_[:, 3, 0], np.asarray(axis))
    assert (fwd[:, 0] > 0).all()
    np.testing.assert_allclose(fwd[:, 2], 0.0, atol=1e-7)
    br, bq = C.uncanonicalise(cr, cq, centre, rot)
    np.testing.assert_allclose(np.asarray(br), np.asarray(root), atol=1e-6)
    np.testing.assert_allclose(np.asarray(bq), np.asarray(q), atol=1e-7)


def test_canonical_frame_is_equivariant_to_a_world_yaw_and_shift():
    root, q = _windows(1, b=1)
    y, shift = _yaw(70.0), np.array([30.0, 0.0, -12.0])
    moved_root, moved_q = qrot(y, root) + shift, q.copy()
    moved_q[..., 0, :] = qmul(y, q[..., 0, :])
    outs = []
    for r, qq in ((root, q), (moved_root, moved_q)):
        centre, rot = C.canonical_frame(r, qq, (0.0, 0.0, 1.0), 2)
        outs.append(C.canonicalise(r, qq, centre, rot))
    np.testing.assert_allclose(outs[0][0], outs[1][0], atol=1e-6)
    np.testing.assert_allclose(outs[0][1], outs[1][1], atol=1e-7)


def test_xz_centre_reads_only_known_frames():
    root = np.array([[[1.0, 5.0, 2.0], [3.0, 6.0, 4.0], [np.nan, np.nan, np.nan]]])
    known = np.array([[True, True, False]])
    np.testing.assert_array_equal(C.xz_centre(root, known), [[[2.0, 0.0, 3.0]]])
    t = C.xz_centre(torch.from_numpy(root), torch.from_numpy(known))
    np.testing.assert_array_equal(t.numpy(), [[[2.0, 0.0, 3.0]]])
    assert np.isnan(C.xz_centre(root)).any()  # the whole-window centre does read every frame


def test_facing_rotation_degenerate_cases_are_rotations():
    axis = (1.0, 0.0, 0.0)
    back = C.facing_rotation(_yaw(180.0), axis)  # facing exactly -X: a half turn, not a zero quaternion
    np.testing.assert_allclose(np.abs(back), [0.0, 0.0, 1.0, 0.0], atol=1e-7)
    up = C.facing_rotation(np.array([math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5)]), axis)  # +X turned to +Y
    np.testing.assert_allclose(up, [1.0, 0.0, 0.0, 0.0])
    tb = C.facing_rotation(torch.from_numpy(_yaw(180.0)), axis)
    np.testing.assert_allclose(np.abs(tb.numpy()), [0.0, 0.0, 1.0, 0.0], atol=1e-7)
    q90 = C.facing_rotation(_yaw(90.0), axis)
    np.testing.assert_allclose(q90, _yaw(90.0), atol=1e-8)


def test_benchmark_windows_root_agrees_with_the_root_only_canonicalisation():
    """The benchmark's FK/IK normalisation and the root-only one of the tools are the same map."""
    root, q = _windows(2, b=2, t=12)
    offsets = np.array([[0.0, 0, 0], [0, 1.0, 0], [0, 1.0, 0], [1.0, 0, 0]])
    parents = (-1, 0, 1, 1)
    X = np.broadcast_to(offsets, q.shape[:-1] + (3,)).copy()
    X[..., 0, :] = root
    Xn, Qn = W.canonicalise_windows(X, q, parents, (0.0, 0.0, 1.0), 9)
    centre, rot = C.canonical_frame(root, q, (0.0, 0.0, 1.0), 9)
    cr, cq = C.canonicalise(root, q, centre, rot)
    np.testing.assert_allclose(Xn[..., 0, :], cr, rtol=1e-6, atol=1e-6)  # the reference's 1e-8 epsilons
    np.testing.assert_allclose(np.abs((Qn * cq).sum(-1)), 1.0, atol=1e-7)


# ------------------------------------------------------------------ interpolation
def test_interpolate_pose_hand_values():
    r0, r1 = np.array([0.0, 1.0, 0.0]), np.array([4.0, 1.0, -8.0])
    q0, q1 = _yaw(0.0)[None], _yaw(90.0)[None]
    r, q = interpolate_pose(r0, q0, r1, q1, np.array([0.0, 0.25, 1.0]))
    np.testing.assert_allclose(r, [[0, 1, 0], [1, 1, -2], [4, 1, -8]])
    np.testing.assert_allclose(q[:, 0], [_yaw(0.0), _yaw(22.5), _yaw(90.0)], atol=1e-12)
    rt, qt = interpolate_pose(torch.from_numpy(r0), torch.from_numpy(q0), torch.from_numpy(r1), torch.from_numpy(q1),
                              torch.tensor([0.0, 0.25, 1.0], dtype=torch.float64))
    np.testing.assert_allclose(rt.numpy(), r)
    np.testing.assert_allclose(qt.numpy(), q, atol=1e-7)


def test_benchmark_interpolation_is_interpolate_pose_with_float32_weights():
    root, q = _windows(3, b=4, t=10 + 5 + 1)
    w = np.linspace(0.0, 1.0, num=7, dtype=np.float32)[1:-1].astype(np.float64)
    assert not np.array_equal(w, np.linspace(0.0, 1.0, 7)[1:-1])  # float32 weights really differ from float64 ones
    r, qq = B.interpolation(root, q, 5)
    want_r = root[:, 9:10] + w[None, :, None] * (root[:, 15] - root[:, 9])[:, None]
    assert np.array_equal(r, want_r)  # bit for bit, the reference's formula
    assert np.array_equal(qq, slerp_np(q[:, 9][:, None], q[:, 15][:, None], w[None, :, None]))
    r_, q_ = interpolate_pose(root[:, 9:10], q[:, 9:10], root[:, 15:16], q[:, 15:16], w[None, :])
    assert np.array_equal(r, r_) and np.array_equal(qq, q_)


def test_interpolate_keyframes_never_reads_unknown_frames():
    root, q = _windows(4, b=1, t=8)
    root, q = root[0], q[0]
    keys = [0, 3, 7]
    holes_r, holes_q = root.copy(), q.copy()
    holes_r[[1, 2, 4, 5, 6]] = np.nan
    holes_q[[1, 2, 4, 5, 6]] = np.nan
    r, qq = interpolate_keyframes(holes_r, holes_q, keys)
    assert np.isfinite(r).all() and np.isfinite(qq).all()
    assert np.array_equal(r[keys], root[keys]) and np.array_equal(qq[keys], q[keys])
    np.testing.assert_allclose(r[5], lerp(root[3], root[7], 0.5))


def test_lerp_fill_features_agree_with_interpolate_pose():
    """The mask's feature interpolation is the same lerp/slerp as the pose interpolation."""
    _, q = _windows(5, b=1, t=6, j=3)
    pos = np.random.default_rng(6).normal(size=(1, 6, 3, 3))
    feats = torch.from_numpy(np.concatenate([pos, q], axis=-1))
    known = torch.zeros(1, 6, 3, dtype=torch.bool)
    known[:, [0, 5]] = True
    filled = lerp_fill(feats, known, GlobalPosLocalQuat).numpy()
    w = (np.arange(6) / 5.0)[:, None]
    np.testing.assert_allclose(filled[0, :, :, :3], lerp(pos[0, 0], pos[0, 5], w[..., None]), atol=1e-12)
    np.testing.assert_allclose(filled[0, 1:5, :, 3:], slerp_np(q[0, 0], q[0, 5], w)[1:5], atol=1e-7)
