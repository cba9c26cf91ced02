"""The method's features: per joint ``[x, y, z, qw, qx, qy, qz]`` = z-scored GLOBAL position + LOCAL rotation.

``encode`` turns (root position, local quaternions) into ``(..., T, J, 7)`` features; ``decode`` takes features
back to what the benchmark scores (root position = joint 0's de-normalised position, local quaternions
normalised).  Positions are z-scored per joint coordinate with the training statistics.
"""
from __future__ import annotations

import numpy as np
import torch

from inbetweening.geometry.kinematics_np import fk_np
from inbetweening.geometry.quaternion import qnormalize
from inbetweening.geometry.skeleton import Skeleton
from inbetweening.representation.base import Representation


class GlobalPosLocalQuat(Representation):
    """Z-scored global joint positions + local quaternions (the method's features, 7 per joint)."""

    name = "global_pos_local_quat"
    features = 7
    pos = slice(0, 3)
    quat = slice(3, 7)
    description = "per joint [(p - pos_mean) / pos_std (xyz, global position), local quaternion wxyz]"

    def __init__(self, skeleton: Skeleton, mean, std, **kw):
        super().__init__(skeleton, mean, std, **kw)
        j = skeleton.num_joints
        self._mean_np, self._std_np = self.mean.reshape(j, 3), self.std.reshape(j, 3)
        self._tensors: dict = {}  # (dtype, device) -> (mean, std) tensors, built once

    def stats(self, like: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``(mean, std)`` as ``(J, 3)`` tensors of ``like``'s dtype and device."""
        key = (like.dtype, like.device)
        if key not in self._tensors:
            self._tensors[key] = (torch.as_tensor(self._mean_np, dtype=like.dtype, device=like.device),
                                  torch.as_tensor(self._std_np, dtype=like.dtype, device=like.device))
        return self._tensors[key]

    def encode(self, root, local_q):
        _, gp = self.skeleton.pose(root, local_q)
        return torch.cat([self.normalise_positions(gp), local_q], dim=-1)

    def encode_np(self, root, local_q):
        """FK in float64 numpy (:func:`inbetweening.geometry.kinematics_np.fk_np`, the torch path's arithmetic, bit
        for bit), z-scored: the same features as :meth:`encode`."""
        gp = fk_np(local_q, self.skeleton.local_positions(root), self.skeleton.parents, positions_only=True)
        return np.concatenate([(gp - self._mean_np) / self._std_np, local_q], axis=-1)

    def decode(self, feats):
        m, s = self.stats(feats)
        return feats[..., 0, self.pos] * s[0] + m[0], qnormalize(feats[..., self.quat])

    def global_positions(self, feats):
        m, s = self.stats(feats)
        return feats[..., self.pos] * s + m

    def normalise_positions(self, positions):
        m, s = self.stats(positions)
        return (positions - m) / s
