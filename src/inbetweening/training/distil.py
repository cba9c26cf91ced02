"""Distillation: a student network trained on what a teacher fill's networks predict for the same task, beside the data
(``teacher=`` group, ``experiment=distil``).

The teacher is the fill's own network part: one checkpoint, or several combined exactly as the fill combines an
ensemble (:class:`~inbetweening.runtime.ensemble.EnsembleBackend`: each member weighted by its calibrated weight for
the gap's length), run through :meth:`FillRuntime.predict_windows <inbetweening.runtime.fill.FillRuntime.
predict_windows>` on the window the fill would give it for the training task: ``n_past`` context frames before the
transition, the transition (its intermediate and partial keys known), the target key.  Its prediction replaces the
transition's frames of a copy of the training window; the student's loss then adds ``weight`` times the L1 between its
prediction and that copy's features, at the same values as the data's loss (``loss_mask``).  So any ensemble a
researcher trains distils the same way, and the student is judged by the same protocols as its teacher.

The do-no-harm blend, the self-check and foot locking stay the fill's: they apply to the student as to any network.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from inbetweening.geometry.quaternion import remove_discontinuities
from inbetweening.runtime.ensemble import EnsembleBackend
from inbetweening.runtime.fill import FillRuntime
from inbetweening.runtime.torch_backend import TorchBackend
from inbetweening.training.config import ConfigError, check_teacher_settings

__all__ = ["Teacher"]


class Teacher:
    """The teacher's networks (``checkpoints``: one path or several, an ensemble) on ``device``; ``weight``: the
    distillation term's weight in the student's loss."""

    def __init__(self, checkpoints: Sequence[str] | str, weight: float = 1.0, device: str | torch.device = "cpu"):
        paths = check_teacher_settings(checkpoints, weight)
        members = [TorchBackend.from_checkpoint(p, device) for p in paths]
        backend = members[0] if len(members) == 1 else EnsembleBackend(members, paths)
        self.paths, self.weight = paths, float(weight)
        self.runtime = FillRuntime(backend, foot_lock=False, self_check=False)  # its windows and canonical frame only
        self.info = backend.info

    def check(self, skeleton, fps: float) -> None:
        """The student's data must be the teacher's skeleton (joints in the same order) at its frame rate
        (:meth:`ModelInfo.same_rate <inbetweening.runtime.model.ModelInfo.same_rate>`)."""
        mine = self.info.skeleton
        if list(mine.names) != list(skeleton.names) or list(mine.parents) != list(skeleton.parents):
            raise ConfigError(f"teacher.checkpoints: {self.paths[0]} is a model of another skeleton than the data's "
                              f"({len(mine.names)} joints {list(mine.names)[:3]}..., the data "
                              f"{len(skeleton.names)} joints {list(skeleton.names)[:3]}...)")
        if not self.info.same_rate(fps):
            raise ConfigError(f"teacher.checkpoints: {self.paths[0]} was trained at {self.info.fps} fps, the data is "
                              f"at {fps} fps")

    def targets(self, root: torch.Tensor, local_q: torch.Tensor, known: torch.Tensor, n_trans: torch.Tensor,
                n_context: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Training windows ``root (B, T, 3)``, ``local_q (B, T, J, 4)`` (the clip's frame), their ``known (B, T, J)``,
        transition lengths ``n_trans (B,)`` and context lengths ``n_context (B,)`` (the transition starts there; its
        own intermediate and partial keys are known to the teacher) -> copies whose transition frames hold the
        teacher's prediction."""
        r = root.detach().cpu().numpy().astype(np.float64)
        q = local_q.detach().cpu().numpy().astype(np.float64)
        k = known.detach().cpu().numpy()
        n = n_trans.detach().cpu().numpy().astype(int)
        start = n_context.detach().cpu().numpy().astype(int)  # the transition's first frame
        p = self.info.n_past
        for gap in np.unique(n):
            rows = np.flatnonzero(n == gap)
            idx = start[rows, None] - p + np.arange(p + gap + 1)[None, :]  # context, transition, target key
            idx = np.clip(idx, 0, r.shape[1] - 1)  # a short context repeats the first frame, as the fill's windows do
            wr, wq = r[rows[:, None], idx], remove_discontinuities(q[rows[:, None], idx], axis=1)
            wk = k[rows[:, None], idx]
            wk[:, :p] = True
            pr, pq, _ = self.runtime.predict_windows(wr, wq, wk)
            frames = start[rows, None] + np.arange(gap)[None, :]
            r[rows[:, None], frames], q[rows[:, None], frames] = pr, pq
        return torch.from_numpy(r), torch.from_numpy(q)
