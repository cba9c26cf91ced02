"""The retargeting task's LightningModule: the network (``model`` group, :data:`~inbetweening.models.RETARGETERS`)
trained on windows of normalised (source, analytic target) features with the seed's losses, weighted by
``retarget.loss``:

- ``mse``: the mean squared error of the target's features (rotations, hips offset, joint positions);
- ``smooth``: the output's boundary frames repeated, then a fixed smoothing operator (``retarget.smooth_kernel``,
  normalised) along time; the mean squared difference between the output and its smoothed self;
- ``bone``: the mean absolute error of the bone lengths of the position head against the rig's, relative to the
  mean bone length.

The checkpoint's hyperparameters hold everything :class:`~inbetweening.retarget.learned.LearnedRetarget` needs
(the source skeleton, the target rig as BVH text, the feature statistics).
"""
from __future__ import annotations

import lightning as L
import numpy as np
import torch
import torch.nn.functional as F

from inbetweening.models import build_retargeter
from inbetweening.training.schedules import build_optimizers

from .learned import LearnedRetarget

__all__ = ["RetargetModule", "smoothness"]


def smoothness(y: torch.Tensor, kernel: torch.Tensor) -> torch.Tensor:
    """``y (B, T, D)``: the mean squared difference between ``y`` and ``y`` smoothed along time by ``kernel (K,)``
    (odd ``K``, sums to 1) after repeating the first and last frames ``K // 2`` times."""
    k = kernel.numel() // 2
    x = y.transpose(1, 2)  # (B, D, T)
    x = torch.cat([x[..., :1].expand(-1, -1, k), x, x[..., -1:].expand(-1, -1, k)], dim=-1)
    s = F.conv1d(x.reshape(-1, 1, x.shape[-1]), kernel.view(1, 1, -1)).reshape(y.shape[0], y.shape[2], -1)
    return ((y - s.transpose(1, 2)) ** 2).mean()


class RetargetModule(L.LightningModule):
    """``model``: the network's config; ``loss``: ``{mse, smooth, bone}`` weights; ``smooth_kernel``; ``optim``: the
    ``optim`` group; ``skeleton``/``forward``/``rig_bvh``/``fps``: the source skeleton (dict), its root's facing axis,
    the target rig's hierarchy and reference frame (BVH text) and the frame rate; ``norm``: feature statistics;
    ``split``: the clips' selection and split (``contents``, ``train_fraction``), recorded for ``eval.py``."""

    def __init__(self, model: dict, loss: dict, smooth_kernel: list, optim: dict, skeleton: dict, forward: list,
                 rig_bvh: str, rig_name: str, fps: float, norm: dict, split: dict | None = None):
        super().__init__()
        self.save_hyperparameters()
        self.rig = LearnedRetarget.rig_of(self.hparams)
        self.net = build_retargeter(model, self.rig.source_dim(), self.rig.target_dim())
        kernel = torch.tensor(smooth_kernel, dtype=torch.float32)
        self.register_buffer("kernel", kernel / kernel.sum(), persistent=False)
        self.register_buffer("y_mean", torch.tensor(norm["y_mean"]), persistent=False)
        self.register_buffer("y_std", torch.tensor(norm["y_std"]), persistent=False)
        nj = self.rig.skeleton.num_joints
        self.pos = slice(self.rig.target_dim() - 3 * nj, None)
        self.register_buffer("bones", torch.as_tensor(self.rig.bones, dtype=torch.long), persistent=False)
        self.register_buffer("bone_parents", torch.as_tensor(self.rig.bone_parents), persistent=False)
        self.register_buffer("bone_lengths", torch.tensor(self.rig.bone_lengths, dtype=torch.float32),
                             persistent=False)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)

    def losses(self, y_hat: torch.Tensor, y: torch.Tensor) -> dict[str, torch.Tensor]:
        w = self.hparams.loss
        out = {"mse": F.mse_loss(y_hat, y)}
        if w.get("smooth", 0.0):
            out["smooth"] = smoothness(y_hat, self.kernel)
        if w.get("bone", 0.0) and len(self.bones):
            pos = (y_hat * self.y_std + self.y_mean)[..., self.pos].reshape(*y_hat.shape[:2], -1, 3)
            length = (pos[..., self.bones, :] - pos[..., self.bone_parents, :]).norm(dim=-1)
            out["bone"] = (length - self.bone_lengths).abs().mean() / self.bone_lengths.mean().clamp_min(1e-6)
        out["loss"] = sum(float(w.get(k, 0.0)) * v for k, v in out.items())
        return out

    def training_step(self, batch, batch_idx):
        x, y = batch
        parts = self.losses(self(x), y)
        self.log_dict({f"train/{k}": v.detach() for k, v in parts.items()}, prog_bar=False, on_step=True)
        return parts["loss"]

    def configure_optimizers(self):
        return build_optimizers(self.hparams.optim, self.parameters(),
                                lambda: int(self.trainer.estimated_stepping_batches))

    def retargeter(self) -> LearnedRetarget:
        return LearnedRetarget(self.net, {k: np.asarray(v) for k, v in self.hparams.norm.items()}, self.rig,
                               self.hparams.fps)
