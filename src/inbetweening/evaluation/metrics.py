"""torchmetrics wrappers: the benchmark (L2Q/L2P/NPSS of global poses, scored by
:func:`inbetweening.evaluation.benchmark.score_global`, what ``eval.py``'s scores come from) and per-joint position /
rotation errors."""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torchmetrics import Metric
from torchmetrics.utilities import dim_zero_cat

from inbetweening.evaluation.benchmark import score_global
from inbetweening.geometry.quaternion import qangle


class BenchmarkMetric(Metric):
    """Accumulates predicted and true transitions per length; ``compute()`` returns ``{"l2q@n": ...}``."""

    full_state_update = False
    higher_is_better = False

    def __init__(self, mean, std, lengths: Sequence[int], **kwargs):
        super().__init__(**kwargs)
        self.mean, self.std = np.asarray(mean, np.float64), np.asarray(std, np.float64)
        self.lengths = tuple(int(n) for n in lengths)
        for n in self.lengths:
            for k in self.STATES:
                self.add_state(f"{k}_{n}", default=[], dist_reduce_fx="cat")

    STATES = ("pred_gq", "pred_gp", "gt_gq", "gt_gp")

    def update(self, n: int, pred_gq, pred_gp, gt_gq, gt_gp) -> None:
        """Global poses of ``n`` transition frames (FK done once by the caller): quaternions ``(B, n, J, 4)``,
        positions ``(B, n, J, 3)``, prediction then ground truth."""
        for k, v in zip(self.STATES, (pred_gq, pred_gp, gt_gq, gt_gp)):
            getattr(self, f"{k}_{n}").append(torch.as_tensor(v, dtype=torch.float64, device=self.device))

    def compute(self) -> dict[str, float]:
        out: dict[str, float] = {}
        for n in self.lengths:
            state = getattr(self, f"gt_gq_{n}")  # a list of batches, or one tensor after a DDP sync
            if (len(state) if isinstance(state, list) else state.numel()) == 0:
                continue
            arrays = [dim_zero_cat(getattr(self, f"{k}_{n}")).cpu().numpy() for k in self.STATES]
            out.update(score_global(*arrays, self.mean, self.std, n))
        return out


class PerJointError(Metric):
    """Mean global position error (data units, e.g. cm) and rotation error (degrees) per joint, plus the
    overall position RMSE, over the predicted (masked) entries."""

    full_state_update = False
    higher_is_better = False

    def __init__(self, num_joints: int, **kwargs):
        super().__init__(**kwargs)
        z = torch.zeros(num_joints, dtype=torch.float64)
        self.add_state("pos_sum", default=z.clone(), dist_reduce_fx="sum")
        self.add_state("sq_sum", default=z.clone(), dist_reduce_fx="sum")
        self.add_state("rot_sum", default=z.clone(), dist_reduce_fx="sum")
        self.add_state("count", default=z.clone(), dist_reduce_fx="sum")

    def update(self, pred_gp, gt_gp, pred_gq, gt_gq, mask) -> None:
        """``(B, T, J, 3) x2, (B, T, J, 4) x2, mask (B, T, J) bool``."""
        m = mask.to(torch.float64)
        d = (pred_gp - gt_gp).double().norm(dim=-1)
        self.pos_sum += (d * m).sum(dim=(0, 1))
        self.sq_sum += (d * d * m).sum(dim=(0, 1))
        self.rot_sum += (torch.rad2deg(qangle(pred_gq.double(), gt_gq.double())) * m).sum(dim=(0, 1))
        self.count += m.sum(dim=(0, 1))

    def compute(self) -> dict[str, torch.Tensor]:
        c = self.count.clamp(min=1)
        return {
            "pos": self.pos_sum / c,
            "rot": self.rot_sum / c,
            "rmse": (self.sq_sum.sum() / self.count.sum().clamp(min=1)).sqrt(),
        }
