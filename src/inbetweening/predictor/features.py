"""Model features: per joint ``[x, y, z, qw, qx, qy, qz]`` = z-scored GLOBAL position + LOCAL rotation.

``encode`` turns (root position, local quaternions) into ``(B, T, J, 7)`` features; ``decode`` takes
features back to what the benchmark scores (root position = joint 0's de-normalised position,
local quaternions normalised).  Positions are z-scored with the training statistics.
:class:`GlobalPosLocalQuat` is this layout as a registered :class:`~inbetweening.predictor.representation.Representation`.
"""
from __future__ import annotations

import numpy as np
import torch

from inbetweening.geometry.canonical import masked_mean
from inbetweening.geometry.fastkin import fk_np
from inbetweening.geometry.quaternion import qnormalize
from inbetweening.geometry.skeleton import Skeleton
from inbetweening.predictor.representation import Representation, register_representation

__all__ = ["FEATURES", "POS", "QUAT", "GlobalPosLocalQuat", "decode", "encode", "global_positions",
           "known_centre_shift", "anchor_xz", "qnormalize"]

FEATURES = 7
POS = slice(0, 3)
QUAT = slice(3, 7)


def _stats(mean, std, like: torch.Tensor, num_joints: int) -> tuple[torch.Tensor, torch.Tensor]:
    m = torch.as_tensor(mean, dtype=like.dtype, device=like.device).reshape(num_joints, 3)
    s = torch.as_tensor(std, dtype=like.dtype, device=like.device).reshape(num_joints, 3)
    return m, s


def encode(root: torch.Tensor, local_q: torch.Tensor, skeleton: Skeleton, mean, std) -> torch.Tensor:
    """``root (..., T, 3), local_q (..., T, J, 4) -> features (..., T, J, 7)``."""
    _, gp = skeleton.pose(root, local_q)
    m, s = _stats(mean, std, gp, skeleton.num_joints)
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


def anchor_xz(feats: torch.Tensor, known: torch.Tensor, how: str = "known") -> torch.Tensor:
    """The root XZ a window is re-centred on, in the root's feature units.  ``(B, T, J, F), (B, T, J) -> (B, 2)``.

    ``how="known"``: the mean over the root's known frames; ``how="last"``: the root at the last context frame (the
    last known frame before the first unknown one; the first known frame when the window starts unknown).  Unknown
    values are never read (NaN is fine); with no known frame at all the anchor is 0."""
    k = known[:, :, 0]
    if how == "known":
        return masked_mean(feats[:, :, 0, [0, 2]], k)[:, 0]
    if how != "last":
        raise ValueError(f"centre: unknown anchor {how!r}; choose 'known' or 'last'")
    t = k.shape[1]
    idx = torch.arange(t, device=k.device)[None, :].expand_as(k)
    first_unknown = torch.where(~k, idx, torch.full_like(idx, t)).min(dim=1).values
    first_known = torch.where(k, idx, torch.full_like(idx, t)).min(dim=1).values
    frame = torch.where(first_unknown > 0, first_unknown - 1, first_known).clamp(max=t - 1)
    safe = torch.where(k[..., None], feats[:, :, 0, :][..., [0, 2]], torch.zeros((), dtype=feats.dtype,
                                                                                   device=feats.device))
    return torch.gather(safe, 1, frame[:, None, None].expand(-1, 1, 2))[:, 0]


def known_centre_shift(feats: torch.Tensor, known: torch.Tensor, std, how: str = "known") -> torch.Tensor:
    """Feature-space shift that moves the root XZ anchor of the KNOWN frames (:func:`anchor_xz`) to the origin.
    ``-> (B, 1, J, 7)``.

    Benchmark windows are centred on the mean root XZ over all their frames, including the ones to be
    predicted, so absolute positions leak where the transition goes.  Subtracting this shift (and adding
    it back to the prediction) makes the network see only what is known: ``centre="known"`` (mean of the known
    frames) or ``centre="last"`` (the last context frame, as TST and the delta-interpolator feed their inputs).
    The root's known frames decide (per-joint masks included); unknown values are never read (NaN is fine).
    """
    s = torch.as_tensor(std, dtype=feats.dtype, device=feats.device).reshape(-1, 3)
    xz = anchor_xz(feats, known, how)  # (B, 2) in the root's feature units
    shift = torch.zeros(feats.shape[0], 1, feats.shape[2], feats.shape[3], dtype=feats.dtype, device=feats.device)
    # positions are z-scored per joint coordinate: a world shift d is d / std_j in each joint's features
    shift[:, 0, :, 0] = xz[:, None, 0] * s[0, 0] / s[:, 0]
    shift[:, 0, :, 2] = xz[:, None, 1] * s[0, 2] / s[:, 2]
    return shift


@register_representation
class GlobalPosLocalQuat(Representation):
    """Z-scored global joint positions + local quaternions (the method's features, 7 per joint)."""

    name = "global_pos_local_quat"
    features = FEATURES
    pos = POS
    quat = QUAT
    description = "per joint [(p - pos_mean) / pos_std (xyz, global position), local quaternion wxyz]"

    def __init__(self, skeleton: Skeleton, mean, std):
        super().__init__(skeleton, mean, std)
        j = skeleton.num_joints
        self._mean_np, self._std_np = self.mean.reshape(j, 3), self.std.reshape(j, 3)
        self._tensors: dict = {}  # (dtype, device) -> (mean, std) tensors, built once

    def _stats(self, like: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        key = (like.dtype, like.device)
        if key not in self._tensors:
            self._tensors[key] = _stats(self.mean, self.std, like, self.skeleton.num_joints)
        return self._tensors[key]

    def encode(self, root, local_q):
        return encode(root, local_q, self.skeleton, self.mean, self.std)

    def encode_np(self, root, local_q):
        """FK in float64 numpy (:func:`inbetweening.geometry.fastkin.fk_np`, the torch path's arithmetic, bit for
        bit), z-scored: the same features as :meth:`encode`."""
        gp = fk_np(local_q, self.skeleton.local_positions(root), self.skeleton.parents, positions_only=True)
        return np.concatenate([(gp - self._mean_np) / self._std_np, local_q], axis=-1)

    def decode(self, feats):
        m, s = self._stats(feats)
        return feats[..., 0, POS] * s[0] + m[0], qnormalize(feats[..., QUAT])

    def global_positions(self, feats):
        return global_positions(feats, self.mean, self.std)

    def centre_shift(self, feats, known, how="known"):
        return known_centre_shift(feats, known, self.std, how)
