"""Non-trainable reference baselines (no parameters, ``trainable = False``).

* :class:`ZeroVelocity`: every missing value is the last known value of the same joint feature at an earlier frame
  (a whole-frame gap repeats the last context frame); before the first known frame, the next known one.
* :class:`Interpolation`: the masked-input interpolation computed by the data pipeline (``interp``).

Both end with :meth:`InbetweenModel.finalize` (known values copied bit-identically, unit quaternions).
"""
from __future__ import annotations

import torch
from torch import Tensor

from .base import FEATURE_DIM, QUAT, InbetweenModel
from .blocks import check_input, validate_common


class _Baseline(InbetweenModel):
    """Shared constructor: plain values, same leading signature as the trainable models, no parameters."""

    trainable = False

    def __init__(
        self,
        num_joints: int,
        adjacency: list[list[float]] | None = None,
        feature_dim: int = FEATURE_DIM,
        max_frames: int = 128,
        residual_to_interpolation: bool = False,
        **architecture: object,
    ):
        # architecture settings shared by a sweep (dropout, depth, ...) mean nothing to a baseline: ignored
        super().__init__()
        validate_common(type(self).__name__, num_joints, adjacency, feature_dim, max_frames)
        self.num_joints, self.feature_dim, self.max_frames = num_joints, feature_dim, max_frames
        # accepted for config uniformity; a baseline has nothing to add to the interpolation
        self.residual_to_interpolation = bool(residual_to_interpolation)


class ZeroVelocity(_Baseline):
    """Hold the last known value of each joint (zero-velocity / step extrapolation).

    Args: ``num_joints``, ``adjacency`` (checked, unused), ``feature_dim``; ``max_frames`` and
    ``residual_to_interpolation`` are accepted for config uniformity and ignored (any ``T`` works).
    A joint with no known frame at all keeps its (masked) input with, if degenerate, the identity quaternion.
    """

    def forward(self, x: Tensor, known: Tensor, interp: Tensor | None = None) -> Tensor:
        """``x (B, T, J, F), known (B, T, J) bool, interp ignored -> (B, T, J, F)``."""
        check_input(type(self).__name__, x, known, self.num_joints, self.feature_dim)
        known = known.to(torch.bool)
        t = x.shape[1]
        frame = torch.arange(t, device=x.device).view(1, t, 1).expand_as(known)
        last = torch.where(known, frame, torch.full_like(frame, -1)).cummax(dim=1).values
        nxt = torch.where(known, frame, torch.full_like(frame, t)).flip(1).cummin(dim=1).values.flip(1)
        src = torch.where(last >= 0, last, torch.where(nxt < t, nxt, frame))  # (B, T, J) source frame
        raw = torch.gather(x, 1, src[..., None].expand(-1, -1, -1, x.shape[-1]))
        q = raw[..., QUAT]
        identity = torch.zeros_like(q)
        identity[..., 0] = 1.0
        degenerate = (q * q).sum(dim=-1, keepdim=True) < self.quat_eps
        raw = torch.cat([raw[..., : QUAT.start], torch.where(degenerate, identity, q), raw[..., QUAT.stop :]], -1)
        return self.finalize(raw, x, known)


class Interpolation(_Baseline):
    """Return the data pipeline's interpolation ``interp`` (linear positions / slerp rotations) of the unknown
    values; ValueError if ``interp`` is ``None``.  Constructor as :class:`ZeroVelocity`."""

    def forward(self, x: Tensor, known: Tensor, interp: Tensor | None = None) -> Tensor:
        """``x (B, T, J, F), known (B, T, J) bool, interp (B, T, J, F) -> (B, T, J, F)``."""
        check_input(type(self).__name__, x, known, self.num_joints, self.feature_dim)
        if interp is None:
            raise ValueError("Interpolation: interp is required (the masked-input interpolation of the data pipeline)")
        if tuple(interp.shape) != tuple(x.shape):
            raise ValueError(f"Interpolation: interp must have the shape of x {tuple(x.shape)}, got {tuple(interp.shape)}")
        return self.finalize(interp, x, known)
