"""torchmetrics wrappers pinned by hand values: per-joint errors, recovery RMSE, benchmark accumulation."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from inbetweening.evaluation import benchmark as B
from inbetweening.evaluation.metrics import BenchmarkMetric, PerJointError
from inbetweening.geometry.skeleton import Skeleton

S2 = np.sqrt(0.5)


def test_per_joint_error_hand_values_masked_entries_only():
    pred_gp = torch.zeros(1, 2, 2, 3, dtype=torch.float64)
    gt_gp = torch.zeros_like(pred_gp)
    pred_gp[0, 0, 0] = torch.tensor([3.0, 4.0, 0.0])  # 5 cm, joint 0
    pred_gp[0, 1, 0] = torch.tensor([0.0, 0.0, 1.0])  # 1 cm, joint 0
    pred_gp[0, 1, 1] = torch.tensor([0.0, 0.0, 100.0])  # joint 1, but known: not counted
    ident = torch.tensor([1.0, 0.0, 0.0, 0.0], dtype=torch.float64)
    gt_gq = ident.expand(1, 2, 2, 4).clone()
    pred_gq = gt_gq.clone()
    pred_gq[0, 0, 0] = torch.tensor([S2, S2, 0.0, 0.0])  # 90 degrees about x
    pred_gq[0, 1, 0] = -torch.tensor([S2, 0.0, 0.0, S2])  # 90 degrees about z, other sign
    mask = torch.tensor([[[True, False], [True, False]]])
    m = PerJointError(2)
    m.update(pred_gp[:, :1], gt_gp[:, :1], pred_gq[:, :1], gt_gq[:, :1], mask[:, :1])  # two updates accumulate
    m.update(pred_gp[:, 1:], gt_gp[:, 1:], pred_gq[:, 1:], gt_gq[:, 1:], mask[:, 1:])
    out = m.compute()
    np.testing.assert_allclose(out["pos"].numpy(), [3.0, 0.0])  # mean of 5 and 1; joint 1 has no masked entry
    np.testing.assert_allclose(out["rot"].numpy(), [90.0, 0.0], atol=1e-9)
    # RMSE over all masked entries: sqrt((25 + 1) / 2), not the mean distance 3
    assert float(out["rmse"]) == pytest.approx(np.sqrt(13.0), rel=1e-12)
    m.reset()
    assert float(m.compute()["rmse"]) == 0.0


def test_per_joint_error_pools_squares_over_entries_and_joints():
    """Several masked entries of the same joint in ONE update: RMSE squares each distance before summing and pools
    every masked entry of every joint (not the mean distance, not the mean of per-joint RMSEs)."""
    pred_gp = torch.zeros(2, 2, 2, 3, dtype=torch.float64)
    gt_gp = torch.full_like(pred_gp, 1.5)  # an offset common to both: only differences count
    pred_gp += 1.5
    pred_gp[0, 0, 0, 0] += 3.0  # joint 0: distance 3
    pred_gp[1, 1, 0, 2] -= 4.0  # joint 0: distance 4
    pred_gp[0, 1, 1] += torch.tensor([12.0, 0.0, 0.0])  # joint 1: distance 12
    pred_gp[1, 0, 1] += 100.0  # joint 1, not masked
    ident = torch.tensor([1.0, 0.0, 0.0, 0.0], dtype=torch.float64)
    gt_gq = ident.expand(2, 2, 2, 4).clone()
    pred_gq = gt_gq.clone()
    c, s_ = np.cos(np.pi / 6), np.sin(np.pi / 6)
    pred_gq[0, 0, 0] = torch.tensor([c, 0.0, s_, 0.0])  # 60 degrees about y
    pred_gq[1, 1, 0] = torch.tensor([0.0, 1.0, 0.0, 0.0])  # 180 degrees about x
    pred_gq[0, 1, 1] = torch.tensor([S2, 0.0, 0.0, -S2])  # 90 degrees about -z
    pred_gq[1, 0, 1] = torch.tensor([0.0, 0.0, 0.0, 1.0])  # not masked
    mask = torch.zeros(2, 2, 2, dtype=torch.bool)
    mask[0, 0, 0] = mask[1, 1, 0] = mask[0, 1, 1] = True
    m = PerJointError(2)
    m.update(pred_gp, gt_gp, pred_gq, gt_gq, mask)
    out = m.compute()
    np.testing.assert_allclose(out["pos"].numpy(), [3.5, 12.0], rtol=1e-12)
    np.testing.assert_allclose(out["rot"].numpy(), [(60.0 + 180.0) / 2, 90.0], rtol=1e-9)
    # sqrt((9 + 16 + 144) / 3); the mean distance would be 19 / 3, the mean of per-joint RMSEs sqrt(78.25)
    assert float(out["rmse"]) == pytest.approx(np.sqrt(169.0 / 3.0), rel=1e-12)


def test_benchmark_metric_accumulates_like_one_score_call():
    sk = Skeleton(("r", "c"), (-1, 0), np.array([[0.0, 0, 0], [0.0, 1.0, 0]]))
    rng = np.random.default_rng(0)

    def batch(b, n):
        q = rng.normal(size=(b, n, 2, 4))
        return rng.normal(size=(b, n, 3)), q / np.linalg.norm(q, axis=-1, keepdims=True)

    mean, std = np.zeros(6), np.array([1.0, 2.0, 3.0, 1.0, 2.0, 3.0])
    metric = BenchmarkMetric(mean, std, lengths=(3, 5))
    parts = [(batch(2, 5), batch(2, 5)), (batch(3, 5), batch(3, 5))]
    for (pr, pq), (gr, gq) in parts:  # the metric takes global poses (FK done once by the caller)
        metric.update(5, *sk.pose(torch.from_numpy(pr), torch.from_numpy(pq)),
                      *sk.pose(torch.from_numpy(gr), torch.from_numpy(gq)))
    res = metric.compute()
    assert set(res) == {"l2q@5", "l2p@5", "npss@5"}  # length 3 never updated: not reported
    cat = [np.concatenate([p[i][j] for p in parts]) for i in range(2) for j in range(2)]
    want = B.score(cat[2], cat[3], cat[0], cat[1], sk, mean, std, 5)
    for k, v in want.items():
        assert res[k] == pytest.approx(v, rel=1e-12)


def test_recovery_rmse_of_a_zero_velocity_model_hand_derived(monkeypatch):
    """The mocap-recovery score end to end: every joint moves at 5 cm/frame (root velocity (3, 0, 4), no
    rotation); zero-velocity holds each missing joint at its last known position, so the k-th missing frame of a
    gap is 5k cm off.  Missing: joint 1 at frames 2-4 (5, 10, 15), joint 2 at frames 6-7 (5, 10)."""
    from types import SimpleNamespace

    from inbetweening.training.module import InbetweenModule

    sk = Skeleton(("r", "a", "b"), (-1, 0, 1), np.array([[0.0, 0, 0], [0.0, 10.0, 0], [5.0, 0.0, 0]]))
    known = torch.ones(1, 9, 3, dtype=torch.bool)
    known[0, 2:5, 1] = False
    known[0, 6:8, 2] = False
    module = InbetweenModule(model={"name": "zero_velocity"}, skeleton=sk.to_dict(),
                             pos_mean=np.linspace(-3, 3, 9).tolist(), pos_std=np.linspace(0.5, 4, 9).tolist(),
                             mask="joints", centre="window")
    monkeypatch.setattr(module, "joint_gaps", SimpleNamespace(known=lambda *a, **k: known.clone()))
    monkeypatch.setattr(module, "log_dict", lambda *a, **k: None)  # no trainer to log to
    root = torch.arange(9, dtype=torch.float64)[None, :, None] * torch.tensor([3.0, 0.0, 4.0], dtype=torch.float64)
    q = torch.zeros(1, 9, 3, 4, dtype=torch.float64)
    q[..., 0] = 1.0
    module._recovery_step({"root": root, "q": q}, 0, module.test_recovery)
    out = module.test_recovery.compute()
    np.testing.assert_allclose(out["pos"].numpy(), [0.0, 10.0, 7.5], rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(out["rot"].numpy(), [0.0, 0.0, 0.0], atol=1e-3)
    logged = module._log_recovery(module.test_recovery, "test")
    # sqrt((25 + 100 + 225 + 25 + 100) / 5) = sqrt(95); the mean distance would be 9
    assert logged == {"recovery_rmse": pytest.approx(np.sqrt(95.0), rel=1e-5)}


def test_per_joint_error_nonzero_truth_single_counts_and_process_merge():
    """Errors against a non-zero truth, a joint and a whole metric with one masked entry, and two metrics merged
    the way DDP syncs them (states reduced by sum) equal one metric fed everything."""
    gt_gp = torch.tensor([[[[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]]], dtype=torch.float64)  # (1, 1, 2, 3)
    pred_gp = gt_gp + torch.tensor([[[[0.0, 0.0, 2.0], [0.0, 0.0, 0.0]]]], dtype=torch.float64)
    q = torch.tensor([1.0, 0.0, 0.0, 0.0], dtype=torch.float64).expand(1, 1, 2, 4)
    mask = torch.tensor([[[True, False]]])
    m = PerJointError(2)
    m.update(pred_gp, gt_gp, q, q, mask)
    out = m.compute()
    np.testing.assert_allclose(out["pos"].numpy(), [2.0, 0.0])  # one entry: divided by 1
    assert float(out["rmse"]) == pytest.approx(2.0)
    a, b, both = PerJointError(2), PerJointError(2), PerJointError(2)
    mask2 = torch.tensor([[[True, True]]])
    a.update(pred_gp, gt_gp, q, q, mask)
    b.update(pred_gp * 2, gt_gp, q, q, mask2)
    both.update(pred_gp, gt_gp, q, q, mask)
    both.update(pred_gp * 2, gt_gp, q, q, mask2)
    a.merge_state(b)
    for k, v in both.compute().items():
        np.testing.assert_allclose(a.compute()[k].numpy(), v.numpy(), rtol=1e-12)


def test_benchmark_metric_merges_like_ddp_gathering():
    sk = Skeleton(("r", "c"), (-1, 0), np.array([[0.0, 0, 0], [0.0, 1.0, 0]]))
    rng = np.random.default_rng(1)

    def batch(b):
        q = rng.normal(size=(b, 5, 2, 4))
        return torch.from_numpy(rng.normal(size=(b, 5, 3))), torch.from_numpy(q / np.linalg.norm(q, axis=-1, keepdims=True))

    mean, std = np.zeros(6), np.ones(6)
    a, b, both = (BenchmarkMetric(mean, std, lengths=(5,)) for _ in range(3))
    parts = [(batch(2), batch(2)), (batch(3), batch(3))]
    for metric, (p, g) in ((a, parts[0]), (b, parts[1])):
        metric.update(5, *sk.pose(*p), *sk.pose(*g))
    for p, g in parts:
        both.update(5, *sk.pose(*p), *sk.pose(*g))
    a.merge_state(b)
    assert a.compute() == pytest.approx(both.compute(), rel=1e-12)
