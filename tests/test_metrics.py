"""torchmetrics wrappers pinned by hand values: per-joint errors, recovery RMSE, benchmark accumulation."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from inbetweening import benchmark as B
from inbetweening.metrics import BenchmarkMetric, PerJointError
from inbetweening.skeleton import Skeleton

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


def test_benchmark_metric_accumulates_like_one_score_call():
    sk = Skeleton(("r", "c"), (-1, 0), np.array([[0.0, 0, 0], [0.0, 1.0, 0]]))
    rng = np.random.default_rng(0)

    def batch(b, n):
        q = rng.normal(size=(b, n, 2, 4))
        return rng.normal(size=(b, n, 3)), q / np.linalg.norm(q, axis=-1, keepdims=True)

    mean, std = np.zeros(6), np.array([1.0, 2.0, 3.0, 1.0, 2.0, 3.0])
    metric = BenchmarkMetric(sk, mean, std, lengths=(3, 5))
    parts = [(batch(2, 5), batch(2, 5)), (batch(3, 5), batch(3, 5))]
    for (pr, pq), (gr, gq) in parts:
        metric.update(5, torch.from_numpy(pr), torch.from_numpy(pq), torch.from_numpy(gr), torch.from_numpy(gq))
    res = metric.compute()
    assert set(res) == {"l2q@5", "l2p@5", "npss@5"}  # length 3 never updated: not reported
    cat = [np.concatenate([p[i][j] for p in parts]) for i in range(2) for j in range(2)]
    want = B.score(cat[2], cat[3], cat[0], cat[1], sk, mean, std, 5)
    for k, v in want.items():
        assert res[k] == pytest.approx(v, rel=1e-12)
