"""The LAFAN1 benchmark protocol pinned by hand-derived values: windows, normalisation, baselines, metrics."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import torch

from inbetweening.data import windows as W
from inbetweening.evaluation import benchmark as B
from inbetweening.geometry.quaternion import qrot
from inbetweening.geometry.skeleton import Skeleton, fk

NAMES = ("root", "spine", "head", "leg")
PARENTS = (-1, 0, 1, 0)
OFFSETS = np.array([[0.0, 0, 0], [0.0, 1.0, 0], [0.0, 1.0, 0], [0.3, -1.0, 0]])
SK = Skeleton(NAMES, PARENTS, OFFSETS)


def about(axis, rad):
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    return np.concatenate([[np.cos(rad / 2)], np.sin(rad / 2) * a])


def random_clip(rng, frames, name="c"):
    q = rng.normal(size=(frames, 4, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    root = np.cumsum(rng.normal(size=(frames, 3)), axis=0)
    return SimpleNamespace(name=name, local_q=q, root_pos=root)


# ------------------------------------------------------------------ windows
def test_window_starts_bounds_and_errors():
    assert W.window_starts(5, 1, 1) == [0, 1, 2, 3]  # window and offset of 1 are valid
    assert W.window_starts(10, 4, 3) == [0, 3]  # strict: start + window < frames
    assert W.window_starts(3, 5, 1) == []
    for window, offset in ((0, 1), (1, 0)):
        with pytest.raises(ValueError, match=rf"window \({window}\) and offset \({offset}\) must be >= 1"):
            W.window_starts(10, window, offset)


def test_extract_windows_values_dtype_and_empty():
    rng = np.random.default_rng(0)
    clip = random_clip(rng, 12)
    clip.local_q = clip.local_q.astype(np.float32)
    clip.root_pos = clip.root_pos.astype(np.float32)
    X, Q = W.extract_windows([clip], SK, 5, 4)  # starts 0, 4
    assert X.shape == (2, 5, 4, 3) and Q.shape == (2, 5, 4, 4)
    assert X.dtype == np.float64 and Q.dtype == np.float64
    np.testing.assert_array_equal(X[1, :, 0], clip.root_pos[4:9])
    np.testing.assert_array_equal(X[1, 2, 1:], OFFSETS[1:])
    np.testing.assert_array_equal(Q[1], clip.local_q[4:9])
    X0, Q0 = W.extract_windows([random_clip(rng, 3)], SK, 5, 4)
    assert X0.shape == (0, 5, 4, 3) and Q0.shape == (0, 5, 4, 4)


# ------------------------------------------------------------------ normalisation
def test_centre_and_rotate_hand_derived_and_leaves_input_alone():
    # one window of 2 frames, n_past = 2: the root faces +z (forward axis +x turned -90 deg about y)
    X = np.zeros((1, 2, 4, 3))
    X[0, :, 0] = [[2.0, 5.0, 4.0], [4.0, 7.0, 8.0]]
    X[0, :, 1:] = OFFSETS[1:]
    Q = np.tile(np.array([1.0, 0, 0, 0]), (1, 2, 4, 1))
    Q[0, :, 0] = about([0, 1, 0], -np.pi / 2)  # +x -> +z
    X_in, Q_in = X.copy(), Q.copy()
    Xn, Qn = W.centre_and_rotate(X, Q, PARENTS, forward_axis=(1.0, 0.0, 0.0), n_past=2)
    np.testing.assert_array_equal(X, X_in)
    np.testing.assert_array_equal(Q, Q_in)
    # centred: mean root XZ (3, 6) removed -> (-1, -2), (1, 2); then turned +90 about y so forward = +x:
    # Ry(90) maps (x, z) -> (z, -x)
    np.testing.assert_allclose(Xn[0, :, 0], [[-2.0, 5.0, 1.0], [2.0, 7.0, -1.0]], atol=1e-12)
    np.testing.assert_allclose(np.abs(Qn[0, :, 0, 0]), 1.0, atol=1e-12)  # root rotation is now the identity


def test_centre_and_rotate_turns_about_y_only_numpy_and_torch_agree():
    rng = np.random.default_rng(1)
    X, Q = W.extract_windows([random_clip(rng, 30)], SK, 12, 5)
    axis = (0.3, 0.5, 0.8)  # a forward axis with a vertical component and no exact float32 value
    Xn, Qn = W.centre_and_rotate(X, Q, PARENTS, forward_axis=axis)
    _, gp = fk(Q, X, PARENTS)
    gq_n, gp_n = fk(Qn, Xn, PARENTS)
    # heights unchanged (a rotation about y), up to the 1e-8 eps of qnormalize kept for parity with the reference
    np.testing.assert_allclose(gp_n[..., 1], gp[..., 1], atol=5e-6)
    fwd = qrot(gq_n[:, W.N_PAST - 1, 0], np.asarray(axis))
    np.testing.assert_allclose(fwd[:, 2], 0.0, atol=1e-6)
    assert (fwd[:, 0] > 0).all()
    np.testing.assert_allclose(Xn[:, :, 0, [0, 2]].mean(axis=1), 0.0, atol=1e-9)  # centred before the turn
    Xt, Qt = W.centre_and_rotate(torch.from_numpy(X), torch.from_numpy(Q), PARENTS, forward_axis=axis)
    np.testing.assert_allclose(Xt.numpy(), Xn, atol=1e-12, rtol=0)
    np.testing.assert_allclose(Qt.numpy(), Qn, atol=1e-12, rtol=0)


def test_prepare_windows_normalises_each_window_with_the_axis_given():
    rng = np.random.default_rng(2)
    clip = random_clip(rng, 14)
    X, Q = W.prepare_windows([clip], SK, 12, 5, (0.0, 0.0, 1.0))  # exactly one window
    want = W.centre_and_rotate(*W.extract_windows([clip], SK, 12, 5), PARENTS, forward_axis=(0.0, 0.0, 1.0))
    assert X.shape == (1, 12, 4, 3)
    np.testing.assert_array_equal(X, want[0])
    np.testing.assert_array_equal(Q, want[1])
    X0, Q0 = W.prepare_windows([random_clip(rng, 5)], SK, 12, 5, (0.0, 0.0, 1.0))
    assert X0.shape == (0, 12, 4, 3) and Q0.shape == (0, 12, 4, 4)


def test_position_stats_per_coordinate():
    X = np.zeros((2, 2, 4, 3))
    X[:, :, 1:] = OFFSETS[1:]
    X[0, :, 0] = [[0.0, 0, 0], [2.0, 0, 0]]
    X[1, :, 0] = [[4.0, 2.0, 0], [6.0, 2.0, 0]]
    Q = np.tile(np.array([1.0, 0, 0, 0]), (2, 2, 4, 1))
    mean, std = W.position_stats(X, Q, PARENTS)
    assert mean.shape == (12,) and std.shape == (12,)
    # root x over 4 frames: 0, 2, 4, 6 -> mean 3, std sqrt(5); root y: 0, 0, 2, 2 -> 1, 1
    np.testing.assert_allclose(mean[:3], [3.0, 1.0, 0.0])
    np.testing.assert_allclose(std[:3], [np.sqrt(5.0), 1.0, 0.0])
    np.testing.assert_allclose(mean[3:6], [3.0, 2.0, 0.0])  # spine = root + (0, 1, 0)
    np.testing.assert_allclose(mean[9:12], [3.3, 0.0, 0.0])  # leg = root + (0.3, -1, 0)


# ------------------------------------------------------------------ metrics
def test_l2p_per_frame_norm_of_z_scored_positions():
    gt = np.zeros((2, 3, 2, 3))
    pred = gt.copy()
    pred[0, 0, 0] = [2.0, 0, 0]  # frame error: x of joint 0 by 2 with std 2 -> 1
    pred[1, 2, 1] = [0.0, 3.0, 4.0]  # joint 1: y by 3 (std 1), z by 4 (std 0.5) -> sqrt(9 + 64)
    mean = np.arange(6.0)
    std = np.array([2.0, 1.0, 1.0, 1.0, 1.0, 0.5])
    want = (1.0 + np.sqrt(73.0)) / 6  # mean over 2 windows x 3 frames
    assert B.l2p(pred, gt, mean, std) == pytest.approx(want, rel=1e-12)


def test_l2q_norm_over_all_joints_per_frame():
    gt = np.tile(np.array([1.0, 0, 0, 0]), (1, 2, 2, 1))
    pred = gt.copy()
    pred[0, 1, 0] = [0.0, 1.0, 0, 0]  # difference (-1, 1, 0, 0)
    pred[0, 1, 1] = [1.0, 0, 0, 2.0]  # difference (0, 0, 0, 2)
    assert B.l2q(pred, gt) == pytest.approx(np.sqrt(2.0 + 4.0) / 2, rel=1e-12)


def test_npss_four_frames_real_part_and_power_weighting():
    # independent DFT: P_k = (sum_t x_t cos(2 pi k t / T))^2 (the real part only), T = 4
    t = np.arange(4)

    def power(x):
        return np.array([np.sum(x * np.cos(2 * np.pi * k * t / 4)) ** 2 for k in range(4)])

    def emd(g, p):
        pg, pp = power(g), power(p)
        return np.abs(np.cumsum(pp / pp.sum()) - np.cumsum(pg / pg.sum())).sum(), pg.sum()

    g1, p1 = np.array([1.0, 2.0, 0.0, -1.0]), np.array([0.0, 1.0, 3.0, 1.0])  # imaginary parts non-zero
    g2, p2 = np.array([3.0, 3.0, 2.0, 3.0]), np.array([3.0, 2.0, 2.0, 4.0])
    (e1, w1), (e2, w2) = emd(g1, p1), emd(g2, p2)
    want = (e1 * w1 + e2 * w2) / (w1 + w2)
    got = B.npss(np.stack([g1, g2], -1)[None], np.stack([p1, p2], -1)[None])
    assert got == pytest.approx(want, rel=1e-12)
    assert abs(w1 - w2) > 1 and abs(e1 - e2) > 0.05  # weighting matters for this case
    mag = np.abs(np.fft.fft(g1))
    assert not np.allclose(mag**2, power(g1))  # the real part and the magnitude differ here


def test_npss_several_windows_odd_length_hand_dft():
    """B=2 windows, T=5 frames (odd: no Nyquist bin), D=2: every (window, dimension) pair is weighted by its own
    ground-truth power, over windows as well as dimensions (not a mean of per-window averages)."""
    t = np.arange(5)

    def power(x):  # the real part of the DFT only, written out: P_k = (sum_t x_t cos(2 pi k t / T))^2
        return np.array([np.sum(x * np.cos(2 * np.pi * k * t / 5)) ** 2 for k in range(5)])

    gt = np.array([[[1.0, 0.5], [2.0, -1.0], [0.0, 2.0], [-1.0, 1.0], [3.0, 0.0]],
                   [[4.0, 0.2], [4.0, 0.1], [5.0, 0.3], [3.0, 0.0], [4.0, 0.4]]])
    pred = np.array([[[0.0, 0.5], [1.0, 1.0], [3.0, 1.0], [1.0, 0.0], [0.0, 1.0]],
                     [[4.0, 0.0], [3.0, 0.4], [4.0, 0.1], [4.0, 0.3], [5.0, 0.2]]])
    emds, weights = [], []
    for b in range(2):
        for d in range(2):
            pg, pp = power(gt[b, :, d]), power(pred[b, :, d])
            emds.append(np.abs(np.cumsum(pp / pp.sum()) - np.cumsum(pg / pg.sum())).sum())
            weights.append(pg.sum())
    emds, weights = np.array(emds), np.array(weights)
    want = float((emds * weights).sum() / weights.sum())
    assert B.npss(gt, pred) == pytest.approx(want, rel=1e-12)
    # the case separates the usual slips: unweighted, per-window then averaged, magnitude instead of real part
    assert abs(want - emds.mean()) > 0.01
    per_window = np.mean([(emds[2 * b : 2 * b + 2] * weights[2 * b : 2 * b + 2]).sum() / weights[2 * b : 2 * b + 2].sum()
                          for b in range(2)])
    assert abs(want - per_window) > 0.01
    assert not np.allclose(np.abs(np.fft.fft(gt, axis=1)) ** 2, np.stack([[power(gt[b, :, d]) for d in range(2)]
                                                                          for b in range(2)]).transpose(0, 2, 1))


# ------------------------------------------------------------------ the whole benchmark, step by step
def _hand_qmul(a, b):
    """Hamilton product, written out component by component."""
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw], -1)


def _hand_rotmat(q):
    """3x3 rotation matrix of a unit quaternion (w, x, y, z).  ``(..., 4) -> (..., 3, 3)``."""
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def _hand_fk(root, q, parents, offsets):
    """Global quaternions and positions: root from the data, every other joint from its parent and offset."""
    gq, gp = np.empty_like(q), np.empty(q.shape[:-1] + (3,))
    gq[..., 0, :], gp[..., 0, :] = q[..., 0, :], root
    for j in range(1, len(parents)):
        p = parents[j]
        gq[..., j, :] = _hand_qmul(gq[..., p, :], q[..., j, :])
        gp[..., j, :] = gp[..., p, :] + np.einsum("...ab,b->...a", _hand_rotmat(gq[..., p, :]), offsets[j])
    return gq, gp


def test_whole_benchmark_step_by_step_on_a_three_joint_skeleton():
    """evaluate_transitions == a literal, independent transcription of the protocol (own FK, own DFT) to 1e-9:
    the predictor sees n_past context frames and the target at n_past + n; frames n_past .. n_past+n-1 are scored;
    L2P z-scores every coordinate with its own mean/std and takes the per-frame norm over all joints."""
    parents = (-1, 0, 1)
    offsets = np.array([[0.0, 0.0, 0.0], [0.0, 2.0, 0.5], [1.0, 0.0, -0.5]])
    sk = Skeleton(("root", "mid", "tip"), parents, offsets)
    rng = np.random.default_rng(11)
    w, frames, n_past = 3, 17, 3
    X = np.broadcast_to(offsets, (w, frames, 3, 3)).copy()
    X[:, :, 0] = np.cumsum(rng.normal(size=(w, frames, 3)), axis=1)
    Q = rng.normal(size=(w, frames, 3, 4))
    Q /= np.linalg.norm(Q, axis=-1, keepdims=True)
    mean = rng.normal(size=9) * 3.0  # per coordinate, all different
    std = rng.uniform(0.5, 3.0, size=9)
    bench = W.BenchmarkSet(X.copy(), Q.copy(), sk, mean, std)

    def rule(ctx_root, target_root, last_q, target_q, n):
        """A predictor that uses every context frame and the target keyframe."""
        a = (np.arange(1, n + 1) / (n + 1))[None, :, None]
        r = ctx_root.mean(axis=1)[:, None] + a * (target_root - ctx_root.mean(axis=1))[:, None] + np.array([0.3, -0.2, 0.1])
        qq = (1 - a[..., None]) * last_q[:, None] + a[..., None] * target_q[:, None] + 0.2
        return r, qq / np.linalg.norm(qq, axis=-1, keepdims=True)

    def predictor(root, q, n):
        assert root.shape == (w, n_past + n + 1, 3) and q.shape == (w, n_past + n + 1, 3, 4)
        assert np.isnan(root[:, n_past : n_past + n]).all() and np.isnan(q[:, n_past : n_past + n]).all()
        assert np.isfinite(root[:, :n_past]).all() and np.isfinite(root[:, n_past + n]).all()
        return rule(root[:, :n_past], root[:, n_past + n], q[:, n_past - 1], q[:, n_past + n], n)

    got = B.evaluate_transitions(bench, predictor, lengths=(4, 2), n_past=n_past)
    assert set(got) == {f"{m}@{n}" for m in ("l2q", "l2p", "npss") for n in (4, 2)}

    for n in (4, 2):
        # the predictor's output, computed straight from the raw windows
        pr_root, pr_q = rule(X[:, :n_past, 0], X[:, n_past + n, 0], Q[:, n_past - 1], Q[:, n_past + n], n)
        gt_root, gt_q = X[:, n_past : n_past + n, 0], Q[:, n_past : n_past + n]
        pgq, pgp = _hand_fk(pr_root, pr_q, parents, offsets)
        ggq, ggp = _hand_fk(gt_root, gt_q, parents, offsets)
        l2q_frames = [[np.sqrt(np.sum((pgq[b, f] - ggq[b, f]) ** 2)) for f in range(n)] for b in range(w)]
        zp = (pgp.reshape(w, n, 9) - mean) / std
        zg = (ggp.reshape(w, n, 9) - mean) / std
        l2p_frames = [[np.sqrt(np.sum((zp[b, f] - zg[b, f]) ** 2)) for f in range(n)] for b in range(w)]
        t = np.arange(n)
        num = den = 0.0
        for b in range(w):
            for d in range(12):  # 3 joints x 4 quaternion components
                g, p = ggq[b, :, d // 4, d % 4], pgq[b, :, d // 4, d % 4]
                pg = np.array([np.sum(g * np.cos(2 * np.pi * k * t / n)) ** 2 for k in range(n)])
                pp = np.array([np.sum(p * np.cos(2 * np.pi * k * t / n)) ** 2 for k in range(n)])
                emd = np.abs(np.cumsum(pp / pp.sum()) - np.cumsum(pg / pg.sum())).sum()
                num, den = num + emd * pg.sum(), den + pg.sum()
        want = {f"l2q@{n}": np.mean(l2q_frames), f"l2p@{n}": np.mean(l2p_frames), f"npss@{n}": num / den}
        for k, v in want.items():
            assert got[k] == pytest.approx(v, rel=1e-9, abs=1e-9), k
        assert min(want.values()) > 1e-3  # none of the three is trivially zero here
    np.testing.assert_array_equal(bench.X, X)  # the benchmark's windows are not modified
    np.testing.assert_array_equal(bench.Q, Q)


# ------------------------------------------------------------------ baselines
def test_zero_velocity_and_interpolation_hand_values():
    n_past, n = 3, 4
    root = np.zeros((1, n_past + n + 1, 3))
    root[0, :, 0] = np.arange(n_past + n + 1) * 10.0  # frame 2 at x=20, target frame 7 at x=70
    q = np.tile(np.array([1.0, 0, 0, 0]), (1, n_past + n + 1, 2, 1))
    q[0, 1, :] = about([0, 1, 0], 0.7)
    q[0, 2, :] = about([0, 1, 0], 0.2)
    q[0, 7, :] = about([0, 1, 0], 1.2)
    zr, zq = B.zero_velocity(root, q, n, n_past)
    assert zr.shape == (1, n, 3) and zq.shape == (1, n, 2, 4)
    np.testing.assert_array_equal(zr[0, :, 0], [20.0] * n)
    np.testing.assert_array_equal(zq[0, :, 1], np.tile(about([0, 1, 0], 0.2), (n, 1)))
    ir, iq = B.interpolation(root, q, n, n_past)
    w = np.linspace(0, 1, n + 2, dtype=np.float32)[1:-1].astype(np.float64)  # the reference's float32 weights
    np.testing.assert_array_equal(ir[0, :, 0], 20.0 + w * 50.0)
    assert not np.array_equal(ir[0, :, 0], 20.0 + np.linspace(0, 1, n + 2)[1:-1] * 50.0)
    for i in range(n):
        np.testing.assert_allclose(iq[0, i, 1], about([0, 1, 0], 0.2 + w[i]), atol=1e-7)


def _bench(rng, windows=3, frames=30):
    X = np.zeros((windows, frames, 4, 3))
    X[:, :, 0] = rng.normal(size=(windows, frames, 3))
    X[:, :, 1:] = OFFSETS[1:]
    Q = rng.normal(size=(windows, frames, 4, 4))
    Q /= np.linalg.norm(Q, axis=-1, keepdims=True)
    return W.BenchmarkSet(X, Q, SK, np.zeros(12), np.ones(12) * 2)


def test_transition_inputs_hide_exactly_the_transition():
    bench = _bench(np.random.default_rng(3))
    root, q = W.transition_inputs(bench, 3, n_past=4)
    assert root.shape == (3, 8, 3) and q.shape == (3, 8, 4, 4)
    assert np.isnan(root[:, 4:7]).all() and np.isnan(q[:, 4:7]).all()
    np.testing.assert_array_equal(root[:, [0, 1, 2, 3, 7]], bench.X[:, [0, 1, 2, 3, 7], 0])
    np.testing.assert_array_equal(q[:, [0, 3, 7]], bench.Q[:, [0, 3, 7]])
    assert not np.isnan(bench.X).any()  # the benchmark's own arrays are untouched


def test_evaluate_transitions_scores_the_right_frames_and_checks_predictors():
    rng = np.random.default_rng(4)
    bench = _bench(rng)
    n_past, n = 4, 6
    seen = {}

    def oracle_plus_one(root, q, length):  # the truth shifted by +1 in x: L2P = 1/std = 0.5 on root x only...
        seen["shape"] = root.shape
        r = bench.X[:, n_past : n_past + length, 0].copy()
        r[..., 0] += 1.0
        return r, bench.Q[:, n_past : n_past + length]

    res = B.evaluate_transitions(bench, oracle_plus_one, lengths=(n,), n_past=n_past)
    assert seen["shape"] == (3, n_past + n + 1, 3)
    # ... and every joint moves with the root: 4 joints x (1 / 2)^2 -> sqrt(1) = 1
    assert res == {f"l2q@{n}": pytest.approx(0.0, abs=1e-12), f"l2p@{n}": pytest.approx(1.0, rel=1e-12),
                   f"npss@{n}": pytest.approx(0.0, abs=1e-12)}
    # the longest transition a window allows: n_past + n + N_FUTURE == window
    ok = B.evaluate_transitions(bench, oracle_plus_one, lengths=(30 - n_past - W.N_FUTURE,), n_past=n_past)
    assert len(ok) == 3
    with pytest.raises(ValueError, match=r"transition length 17 needs windows of 31 frames, have 30"):
        B.evaluate_transitions(bench, oracle_plus_one, lengths=(17,), n_past=n_past)

    def bad_q_shape(root, q, length):
        return bench.X[:, n_past : n_past + length, 0], bench.Q[:, n_past : n_past + length, :3]

    with pytest.raises(ValueError, match=r"predictor returned shapes \(3, 6, 3\), \(3, 6, 3, 4\) for n=6; expected "
                                         r"\(3, 6, 3\), \(3, 6, 4, 4\)"):
        B.evaluate_transitions(bench, bad_q_shape, lengths=(n,), n_past=n_past)

    def nan_q(root, q, length):
        qq = bench.Q[:, n_past : n_past + length].copy()
        qq[0, 0, 0, 0] = np.nan
        return bench.X[:, n_past : n_past + length, 0], qq

    with pytest.raises(ValueError, match="non-finite values for transition length 6"):
        B.evaluate_transitions(bench, nan_q, lengths=(n,), n_past=n_past)


def test_score_transition_compares_with_the_root_joint_frames():
    bench = _bench(np.random.default_rng(5))
    n, n_past = 5, 10
    sl = slice(n_past, n_past + n)
    res = B.score_transition(bench, bench.X[:, sl, 0], bench.Q[:, sl], n, n_past)
    assert res[f"l2p@{n}"] == pytest.approx(0.0, abs=1e-12) and res[f"l2q@{n}"] == 0.0
    wrong = B.score_transition(bench, bench.X[:, sl, 1], bench.Q[:, sl], n, n_past)
    assert wrong[f"l2p@{n}"] > 0.1


def test_format_table():
    table = B.format_table({"m": {"l2q@5": 0.12345, "l2p@5": 1.0, "npss@5": 0.001234}}, lengths=(5,))
    assert table.splitlines() == ["| model | L2Q@5 | L2P@5 | NPSS@5 |", "|---|---:|---:|---:|",
                                  "| m | 0.123 | 1.000 | 0.0012 |"]


def test_format_table_missing_metric():
    table = B.format_table({"m": {"l2p@5": 2.0}}, lengths=(5,))
    assert table.splitlines()[-1] == "| m |  | 2.000 |  |"
