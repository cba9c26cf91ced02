"""Model features: per joint ``[x, y, z, qw, qx, qy, qz]`` = z-scored GLOBAL position + LOCAL rotation.

``encode`` turns (root position, local quaternions) into ``(B, T, J, 7)`` features; ``decode`` takes
features back to what the benchmark scores (root position = joint 0's de-normalised position,
local quaternions normalised).  Positions are z-scored with the training statistics.
"""
from __future__ import annotations

import torch

from inbetweening.geometry.quaternion import qnormalize

__all__ = ["FEATURES", "POS", "QUAT", "decode", "encode", "global_positions", "qnormalize"]
from inbetweening.geometry.skeleton import Skeleton, fk

FEATURES = 7
POS = slice(0, 3)
QUAT = slice(3, 7)


def _stats(mean, std, like: torch.Tensor, num_joints: int) -> tuple[torch.Tensor, torch.Tensor]:
    m = torch.as_tensor(mean, dtype=like.dtype, device=like.device).reshape(num_joints, 3)
    s = torch.as_tensor(std, dtype=like.dtype, device=like.device).reshape(num_joints, 3)
    return m, s


def encode(root: torch.Tensor, local_q: torch.Tensor, skeleton: Skeleton, mean, std) -> torch.Tensor:
    """``root (..., T, 3), local_q (..., T, J, 4) -> features (..., T, J, 7)``."""
    j = skeleton.num_joints
    _, gp = fk(local_q, skeleton.local_positions(root), skeleton.parents)
    m, s = _stats(mean, std, gp, j)
    return torch.cat([(gp - m) / s, local_q], dim=-1)


def decode(feat: torch.Tensor, mean, std) -> tuple[torch.Tensor, torch.Tensor]:
    """``features (..., T, J, 7) -> root (..., T, 3), local_q (..., T, J, 4)`` (normalised)."""
    j = feat.shape[-2]
    m, s = _stats(mean, std, feat, j)
    root = feat[..., 0, POS] * s[0] + m[0]
    return root, qnormalize(feat[..., QUAT])


def global_positions(feat: torch.Tensor, mean, std) -> torch.Tensor:
    """De-normalised global positions carried by the features.  ``(..., J, 7) -> (..., J, 3)``."""
    m, s = _stats(mean, std, feat, feat.shape[-2])
    return feat[..., POS] * s + m
