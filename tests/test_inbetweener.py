"""The batched fill (the runtime's windows, ``Inbetweener.fill_many``) is the one-at-a-time fill and the path written
out by hand, and the fast numpy features are the torch ones; checked on the shipped default model
(``models/bn2_reference``)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from inbetweening.api.inbetweener import Inbetweener, InbetweenError
from inbetweening.geometry import canonical
from inbetweening.predictor.checkpoint import load_predictor
from inbetweening.predictor.masks import apply_mask
from inbetweening.runtime import FillRuntime
from inbetweening.runtime.torch_backend import TorchBackend

MODEL = Path(__file__).resolve().parents[1] / "models" / "bn2_reference" / "model.ckpt"


@pytest.fixture(scope="module")
def predictor():
    return load_predictor(MODEL)


def _motion(rng, frames: int, joints: int, yaw: float = 0.0):
    """A smooth random motion: root walking along a curve, joint rotations drifting."""
    t = np.arange(frames)[:, None]
    root = np.concatenate([np.cos(yaw) * 3.0 * t, 90 + 2 * np.sin(t / 7.0), np.sin(yaw) * 3.0 * t], axis=1)
    root = root + rng.normal(size=(1, 3)) * 50
    q = np.cumsum(rng.normal(size=(frames, joints, 4)) * 0.05, axis=0) + np.array([1.0, 0, 0, 0])
    return root, q / np.linalg.norm(q, axis=-1, keepdims=True)


def _old_fill_window(pr, root, q):
    """The single-window path by hand: canonical frame of the known frames, torch float64 FK features, mask, network,
    decode, taken back."""
    p, t = pr.n_past, len(root)
    n = t - p - 1
    known_t = np.zeros(t, dtype=bool)
    known_t[:p] = known_t[-1] = True
    centre, rot = canonical.canonical_frame(root, q, pr.forward_axis, p - 1, known_t)
    wr, wq = canonical.canonicalise(root, q, centre, rot)
    feats = pr.representation.encode(torch.from_numpy(wr[None]), torch.from_numpy(wq[None])).float()
    known = pr.transition_known(1, t, n)
    with torch.no_grad():
        x, interp = apply_mask(pr.mask_name, feats, known, pr.representation)
        pred = pr.net(x, known, interp)
    dr, dq = pr.representation.decode(pred.double())
    dr, dq = dr[0, p : p + n].numpy(), dq[0, p : p + n].numpy()
    dq /= np.linalg.norm(dq, axis=-1, keepdims=True)
    return canonical.uncanonicalise(dr, dq, centre, rot)


def test_numpy_features_are_the_torch_features_bit_for_bit(predictor):
    rng = np.random.default_rng(0)
    root, q = _motion(rng, 41, predictor.skeleton.num_joints)
    root[12] = np.nan  # unknown frames stay NaN
    rep = predictor.representation
    f_np = rep.encode_windows(root[None], q[None], dtype=torch.float64)
    f_t = rep.encode(torch.from_numpy(root[None]), torch.from_numpy(q[None]))
    assert torch.equal(torch.nan_to_num(f_np, nan=7.0), torch.nan_to_num(f_t, nan=7.0))
    assert torch.isnan(f_np[0, 12, :, :3]).all() and torch.isfinite(f_np[0, 11]).all()


def test_batched_windows_are_one_at_a_time_and_the_path_by_hand(predictor):
    rng = np.random.default_rng(1)
    j = predictor.skeleton.num_joints
    wins = [_motion(rng, 41, j, yaw) for yaw in (0.0, 1.3, -2.5, 3.0)]
    root = np.stack([w[0] for w in wins])
    q = np.stack([w[1] for w in wins])
    root[:, 10:40] = np.nan  # the transition frames are never read
    q[:, 10:40] = np.nan
    runtime = FillRuntime(TorchBackend(predictor))
    br, bq, _ = runtime.predict_windows(root, q)
    assert br.shape == (4, 30, 3) and bq.shape == (4, 30, j, 4)
    for i in range(4):
        r1, q1, _ = runtime.predict_windows(root[i : i + 1], q[i : i + 1])
        r1, q1 = r1[0], q1[0]
        np.testing.assert_allclose(br[i], r1, atol=1e-4)
        np.testing.assert_allclose(bq[i], q1, atol=1e-5)
        r0, q0 = _old_fill_window(predictor, np.nan_to_num(root[i]), np.nan_to_num(q[i]))
        np.testing.assert_allclose(r1, r0, atol=1e-4)
        np.testing.assert_allclose(q1, q0, atol=1e-5)
    # the windows really differ (a batch that repeated one window would pass the loop above only by luck)
    assert np.abs(br[0] - br[1]).max() > 1.0


def test_fill_many_is_fill_arrays_clip_by_clip(predictor):
    ib = Inbetweener(predictor)
    rng = np.random.default_rng(2)
    j = predictor.skeleton.num_joints
    specs = [(121, [0, 30, 60, 90, 120]), (80, [0, 20, 79]), (130, [0, 5, 129])]  # the last gap is segmented
    clips = []
    for frames, keys in specs:
        root, q = _motion(rng, frames, j, rng.uniform(-3, 3))
        unknown = np.setdiff1d(np.arange(frames), keys)
        root[unknown], q[unknown] = np.nan, np.nan
        clips.append((root, q, keys))
    pseudo = [f.pseudo_keyframes for f in ib.runtime.fill_many(clips)]
    assert pseudo[2] and not pseudo[0]
    many = ib.fill_many(clips, batch_size=2)  # the first gaps: a batch of 2, then one of 1
    for (root, q, keys), (mr, mq) in zip(clips, many):
        one_r, one_q = ib.fill_arrays(root, q, keys)
        assert np.isfinite(mr).all() and np.isfinite(mq).all()
        np.testing.assert_allclose(mr, one_r, atol=1e-4)
        np.testing.assert_allclose(mq, one_q, atol=1e-5)
        assert np.array_equal(mr[keys], root[keys]) and np.array_equal(mq[keys], q[keys])


def test_fill_many_checks_every_clip_before_generating(predictor):
    ib = Inbetweener(predictor)
    root, q = _motion(np.random.default_rng(3), 40, predictor.skeleton.num_joints)
    with pytest.raises(InbetweenError, match="known_frames must start at frame 0"):
        ib.fill_many([(root, q, [0, 39]), (root, q, [3, 39])])
    with pytest.raises(InbetweenError, match="batch_size must be a positive integer"):
        ib.fill_many([(root, q, [0, 39])], batch_size=0)
