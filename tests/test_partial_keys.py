"""Partial keys: the runtime's constraint (runtime/partial.py, runtime/fill.py), the per-joint interpolation
(geometry/interp.py interpolate_known) and the protocol's schedule (evaluation/partial_keys.py)."""
from __future__ import annotations

import numpy as np
import pytest

from inbetweening.evaluation import keyframes as KF
from inbetweening.evaluation import partial_keys as PK
from inbetweening.evaluation.schedules import check_schedule, partial_interval
from inbetweening.geometry.interp import interpolate_keyframes, interpolate_known
from inbetweening.predictor.predictor import Predictor
from inbetweening.runtime import FillRuntime, InbetweenError
from inbetweening.runtime.partial import check_partial
from inbetweening.runtime.torch_backend import TorchBackend
from test_runtime import SK, Recorder, hparams, info, motion

ARM = np.array([False, False, False, True, True, True])  # thigh, shin, foot (the leg below the hips)


def test_interpolate_known_is_the_keys_interpolation_joint_by_joint():
    root, q = motion(30, seed=3)
    known = np.zeros((30, SK.num_joints), dtype=bool)
    known[[0, 12, 29]] = True
    r0, q0 = interpolate_known(root, q, known)
    r1, q1 = interpolate_keyframes(root, q, [0, 12, 29])
    assert np.array_equal(r0, r1) and np.allclose(q0, q1, atol=1e-12)
    known[20, 4] = True  # the shin keyed at 20: it passes through that key, nothing else moves
    r2, q2 = interpolate_known(root, q, known)
    assert np.array_equal(q2[20, 4], q[20, 4]) and np.array_equal(r2, r1)
    others = [j for j in range(SK.num_joints) if j != 4]
    assert np.allclose(q2[:, others], q1[:, others], atol=1e-12)
    assert np.abs(q2[13:29, 4] - q1[13:29, 4]).max() > 1e-3


def test_partial_keys_are_checked_with_one_clear_error():
    names = list(SK.names)
    with pytest.raises(InbetweenError, match="frame 40 lies outside the keys"):
        check_partial({40: ["shin"]}, [0, 20, 30], 50, names)
    with pytest.raises(InbetweenError, match="frame 20 is also a whole key"):
        check_partial({20: ["shin"]}, [0, 20, 30], 50, names)
    with pytest.raises(InbetweenError, match="no joint named 'elbow'"):
        check_partial({10: ["elbow"]}, [0, 20, 30], 50, names)
    with pytest.raises(InbetweenError, match="needs 6 values"):
        check_partial({10: np.ones(3, bool)}, [0, 20, 30], 50, names)
    part, keys = check_partial({10: ["shin", 5], 25: np.ones(6, bool), 27: []}, [0, 20, 30], 50, names)
    assert keys == [0, 20, 25, 30]  # a frame keyed on every joint is a whole key, one keyed on none nothing
    assert list(part) == [10] and part[10].tolist() == [False, False, False, False, True, True]


def test_a_partial_key_reaches_the_network_as_known_values_of_its_joints_and_comes_back_exactly():
    root, q = motion(40, seed=4)
    keys = [0, 20, 39]
    rec = Recorder(info(trained_gap=20, hard_max_gap=40))
    junk_r, junk_q = np.full_like(root, np.nan), np.full_like(q, np.nan)
    junk_r[keys], junk_q[keys] = root[keys], q[keys]
    junk_q[10, ARM] = q[10, ARM]  # the leg keyed at frame 10 alone; the rest of that frame never read
    out = FillRuntime(rec, foot_lock=False, self_check=False).fill(junk_r, junk_q, keys, partial={10: ARM})
    p = rec.info.n_past
    first = [k for _, _, k, _ in rec.seen if k.shape[1] == p + 19 + 1][0][0]
    assert first[p + 9].tolist() == ARM.tolist()  # frame 10 of the gap 0..20: known on the leg only
    assert not first[p:p + 9].any() and not first[p + 10:-1].any()
    assert np.array_equal(out.local_q[10, ARM], q[10, ARM])  # the keyed joints exactly as given
    assert np.isfinite(out.root).all() and np.isfinite(out.local_q).all()
    assert np.abs(out.local_q[10, ~ARM] - q[10, ~ARM]).max() > 1e-3  # the others generated
    for k in keys:
        assert np.array_equal(out.root[k], root[k]) and np.array_equal(out.local_q[k], q[k])


def test_a_zero_blend_with_partial_keys_gives_each_joints_own_interpolation():
    """The fall-back of the do-no-harm blend honours the partial keys: with the network's share 0 the fill is every
    joint interpolated between its own keys, through a real (untrained) network; long gaps split at pseudo-keyframes
    that take the same interpolation."""
    root, q = motion(60, seed=5)
    keys, part = [0, 24, 59], {8: ARM, 40: ~ARM}
    net = {"name": "frame_transformer", "d_model": 16, "depth": 1, "heads": 2, "ffn_dim": 16, "dropout": 0.0,
           "residual_to_interpolation": False}
    pr = Predictor.from_hparams(hparams(model=net, blend=[0.0], train_window=30)).eval()
    out = FillRuntime(TorchBackend(pr), foot_lock=False, self_check=False).fill(root, q, keys, partial=part)
    assert out.pseudo_keyframes  # the 34-frame gap was split (windows of 19)
    known = np.zeros((60, SK.num_joints), dtype=bool)
    known[keys] = True
    for t, m in part.items():
        known[t] = m
    ir, iq = interpolate_known(root, q, known)
    assert np.abs(out.root - ir).max() < 1e-4
    assert np.abs(np.abs((out.local_q * iq).sum(-1)) - 1).max() < 1e-6
    assert np.array_equal(out.local_q[40, ~ARM], q[40, ~ARM]) and np.array_equal(out.root[40], root[40])


def test_the_partial_schedule_and_its_scores():
    parts = PK.body_parts(SK)
    assert [n for n, _ in parts] == ["spine", "thigh"]  # the hips branch into spine and leg
    keys, partial = PK.partial_schedule(70, 30, parts)
    assert keys == [0, 30, 60] and list(partial) == [15, 45]
    assert partial[15].tolist() == parts[0][1].tolist() and partial[45].tolist() == parts[1][1].tolist()
    assert partial_interval("partial30") == 30 and partial_interval("partial3") is None and partial_interval(30) is None
    check_schedule("partial15")
    with pytest.raises(ValueError, match="partial<K>"):
        check_schedule("partial2")

    class Clip:
        def __init__(self, seed):
            self.root_pos, self.local_q = motion(70, seed=seed)
            self.name = f"c{seed}"

    clips = [Clip(s) for s in range(3)]
    base = KF.evaluate_clips(clips, SK, None, ["partial30"], 30.0)["partial30"]
    assert base["ratio"] == pytest.approx(1.0) and base["n_clips"] == 3 and base["worse_share"] == 0.0
    assert base["free_interp_cm"] > 0

    def whole_only(root, q, keys, partial=None):  # a fill that ignores partial keys
        return interpolate_keyframes(root, q, keys)

    worse = KF.evaluate_clips(clips, SK, whole_only, ["partial30"], 30.0)["partial30"]
    assert worse["ratio"] > 1.0 and worse["free_model_cm"] >= worse["free_interp_cm"]
    assert "partial30" in KF.format_table({"partial30": worse})
