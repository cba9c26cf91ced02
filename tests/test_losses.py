"""Training loss terms (training/losses.py), each asking the representation what its channels mean."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from inbetweening.data.synthetic import NAMES, OFFSETS, PARENTS
from inbetweening.geometry.quaternion import qnormalize
from inbetweening.geometry.skeleton import Skeleton
from inbetweening.representation import GlobalPosLocalQuat
from inbetweening.training import losses as L

SK = Skeleton(NAMES, PARENTS, OFFSETS)
MEAN, STD = np.zeros(66), np.ones(66)
REP = GlobalPosLocalQuat(SK, MEAN, STD)
FEET = {"feet": [NAMES.index(n) for n in ("LeftFoot", "LeftToe", "RightFoot", "RightToe")], "foot_speed": 0.5}


def _features(b=2, t=12, noise=0.0, seed=0):
    g = torch.Generator().manual_seed(seed)
    f = torch.randn(b, t, 22, 7, generator=g, dtype=torch.float64)
    f[..., 3:] = qnormalize(f[..., 3:])
    return f


def test_l1_only_counts_masked_entries():
    gt = _features()
    pred = gt.clone()
    mask = torch.zeros(2, 12, 22, dtype=torch.bool)
    mask[:, 5] = True
    pred[:, 3] += 10.0  # outside the mask: ignored
    assert float(L.l1(pred, gt, mask)) == 0.0
    pred[:, 5, :, 0] += 7.0
    assert float(L.l1(pred, gt, mask)) == pytest.approx(1.0)  # 7 over 7 features


@pytest.mark.parametrize("term", ["fk_pos", "quat", "bone", "smooth", "foot"])
def test_each_term_is_zero_on_truth_and_positive_when_wrong(term):
    rng = np.random.default_rng(0)
    root = torch.from_numpy(np.cumsum(rng.normal(size=(2, 12, 3)), 1) * 3)
    q = qnormalize(torch.from_numpy(rng.normal(size=(2, 12, 22, 4))) * 0.1 + torch.tensor([1.0, 0, 0, 0]))
    gt = REP.encode(root, q)
    mask = torch.zeros(2, 12, 22, dtype=torch.bool)
    mask[:, 4:8] = True
    weights = {"l1": 0.0, term: 1.0}
    zero, _ = L.total_loss(gt, gt, mask, weights, REP, **FEET)
    wrong = gt.clone()
    wrong[:, 4:8, :, :3] += torch.randn(2, 4, 22, 3, dtype=torch.float64)  # positions off
    wrong[:, 4:8, :, 3:] = qnormalize(wrong[:, 4:8, :, 3:] + 0.5)  # rotations off
    bad, terms = L.total_loss(wrong, gt, mask, weights, REP, **FEET)
    if term == "smooth":  # zero on linear motion, positive once frames are jittered
        lin = gt.clone()
        lin[..., :3] = torch.linspace(0, 1, 12, dtype=torch.float64)[None, :, None, None] * gt[:, -1:, :, :3]
        assert float(L.total_loss(lin, lin, mask, weights, REP, **FEET)[0]) == pytest.approx(0.0, abs=1e-9)
        jitter = lin.clone()
        jitter[:, 4:8, :, :3] += torch.randn(2, 4, 22, 3, dtype=torch.float64)
        assert float(L.total_loss(jitter, lin, mask, weights, REP, **FEET)[0]) > 0.1
    elif term == "foot":
        gt_static = gt.clone()
        gt_static[:, :, :, :3] = gt[:, :1, :, :3]  # feet in contact all along
        w2 = gt_static.clone()
        w2[:, 4:8, :, :3] += 1.0
        w2[:, 6, :, :3] += 1.0
        assert float(L.total_loss(gt_static, gt_static, mask, weights, REP, **FEET)[0]) == 0.0
        assert float(L.total_loss(w2, gt_static, mask, weights, REP, **FEET)[0]) > 0.0
    else:
        assert float(zero) == pytest.approx(0.0, abs=1e-6)
        assert float(bad) > 1e-3
    assert term in terms


def test_unknown_loss_term_raises():
    gt = _features()
    with pytest.raises(ValueError, match="unknown term"):
        L.total_loss(gt, gt, torch.ones(2, 12, 22, dtype=torch.bool), {"l1": 1.0, "l3": 1.0}, REP, **FEET)


def test_foot_term_needs_the_feet():
    """No feet given (a dataset without a contact rule): the foot term is 0, whatever the motion."""
    gt = _features()
    mask = torch.ones(2, 12, 22, dtype=torch.bool)
    assert float(L.foot(gt + 1.0, gt, mask, (), REP, 0.5)) == 0.0


def _all_terms_nonzero_case():
    """Prediction/truth where every loss term is non-zero: feet still in the first frames (contact), then moving."""
    rng = np.random.default_rng(7)
    steps = rng.normal(size=(2, 12, 3)) * 3
    steps[:, :6] = 0.0  # frames 0-5: the whole body stands still, so the feet are in contact
    root = torch.from_numpy(np.cumsum(steps, 1))
    q = qnormalize(torch.from_numpy(rng.normal(size=(2, 12, 22, 4))) * 0.1 + torch.tensor([1.0, 0, 0, 0]))
    q[:, :6] = q[:, :1]
    gt = REP.encode(root, q)
    pred = gt.clone()
    g = torch.Generator().manual_seed(1)
    pred[:, 2:9, :, :3] += torch.randn(2, 7, 22, 3, generator=g, dtype=torch.float64)
    pred[:, 2:9, :, 3:] = qnormalize(pred[:, 2:9, :, 3:] + 0.3 * torch.randn(2, 7, 22, 4, generator=g, dtype=torch.float64))
    mask = torch.zeros(2, 12, 22, dtype=torch.bool)
    mask[:, 2:9] = True
    return pred, gt, mask


def test_loss_weights_scale_each_term_and_zero_removes_it():
    pred, gt, mask = _all_terms_nonzero_case()
    raw = {"raw": pred + 0.1, "known": ~mask}  # the network's output before the keyframes are copied back
    alone = {}
    for term in L.LOSS_TERMS:
        weights = {"l1": 0.0, term: 1.0} if term != "l1" else {"l1": 1.0}
        total, terms = L.total_loss(pred, gt, mask, weights, REP, **raw, **FEET)
        alone[term] = float(total)
        assert alone[term] > 1e-3, term  # every term is active in this case
        assert float(terms[term]) == pytest.approx(alone[term], rel=1e-12)
        for w in (0.25, 3.0):  # weight w on a term alone: w times the term
            scaled, _ = L.total_loss(pred, gt, mask, {**weights, term: w}, REP, **raw, **FEET)
            assert float(scaled) == pytest.approx(w * alone[term], rel=1e-12), (term, w)
    # l1 by hand: mean absolute feature difference over the masked entries (7 features each)
    sel = mask[..., None].expand_as(pred)
    assert alone["l1"] == pytest.approx(float((pred - gt).abs()[sel].mean()), rel=1e-12)
    # all terms together: the weighted sum; a weight of 0 removes exactly that term
    w = {"l1": 0.5, "fk_pos": 2.0, "quat": 3.0, "bone": 0.7, "smooth": 1.5, "foot": 4.0, "keyframe": 2.5}
    total, terms = L.total_loss(pred, gt, mask, w, REP, **raw, **FEET)
    assert float(total) == pytest.approx(sum(w[k] * alone[k] for k in w), rel=1e-12)
    for term in L.LOSS_TERMS:
        total0, terms0 = L.total_loss(pred, gt, mask, {**w, term: 0.0}, REP, **raw, **FEET)
        assert float(total0) == pytest.approx(sum(w[k] * alone[k] for k in w if k != term), rel=1e-12), term
        if term != "l1":  # disabled terms are not even computed (l1 is always logged)
            assert term not in terms0


def test_reduce_windows_weighs_every_window_the_same():
    """loss.reduce: frames pools every predicted value of the batch (a long gap outweighs a short one); windows
    averages each window first, so a 1-frame gap counts as much as an 8-frame one."""
    gt = _features()
    pred = gt.clone()
    mask = torch.zeros(2, 12, 22, dtype=torch.bool)
    mask[0, 2:10] = True   # window 0: an 8-frame gap, error 0
    mask[1, 5] = True      # window 1: a 1-frame gap, error 7 over 7 features
    pred[1, 5, :, 0] += 7.0
    frames, _ = L.total_loss(pred, gt, mask, {"l1": 1.0}, REP)
    windows, _ = L.total_loss(pred, gt, mask, {"l1": 1.0, "reduce": "windows"}, REP)
    assert float(frames) == pytest.approx(1.0 / 9)
    assert float(windows) == pytest.approx(0.5)
    empty = mask.clone()
    empty[1] = False  # a window with nothing to predict does not count
    assert float(L.total_loss(pred, gt, empty, {"l1": 1.0, "reduce": "windows"}, REP)[0]) == 0.0
    with pytest.raises(ValueError, match="loss.reduce"):
        L.total_loss(pred, gt, mask, {"l1": 1.0, "reduce": "clips"}, REP)
