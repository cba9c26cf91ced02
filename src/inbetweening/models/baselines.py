"""Non-trainable reference baselines (no parameters, ``trainable = False``).

* :class:`ZeroVelocity`: every missing value is the last known value of the same joint feature at an earlier frame
  (a whole-frame gap repeats the last context frame); before the first known frame, the next known one.
* :class:`Interpolation`: the masked-input interpolation computed by the data pipeline (``interp``).

Both go through :meth:`InbetweenModel.forward` (known values copied bit-identically, unit quaternions).
"""
from __future__ import annotations

import torch
from torch import Tensor

from .base import InbetweenModel


class _Baseline(InbetweenModel):
    """Shared constructor: plain values, the same common arguments as the trainable models, no parameters."""

    trainable = False
    length_limited = False  # any T works
    ignores_unknown_settings = True
    COMMON_SETTINGS = ("feature_dim", "max_frames", "residual_to_interpolation", "dropout", "layout")

    def __init__(self, num_joints: int, adjacency: list[list[float]] | None = None, **settings: object):
        # architecture settings shared by a sweep (depth, ...) mean nothing to a baseline: ignored; and a baseline has
        # nothing to add to the interpolation: residual_to_interpolation is accepted for config uniformity only
        common = {k: settings[k] for k in self.COMMON_SETTINGS if k in settings and k != "residual_to_interpolation"}
        super().__init__(num_joints, adjacency, residual_to_interpolation=False, **common)


class ZeroVelocity(_Baseline):
    """Hold the last known value of each joint (zero-velocity / step extrapolation).

    Args: ``num_joints``, ``adjacency`` (checked, unused), ``feature_dim``; ``max_frames``, ``dropout`` and
    ``residual_to_interpolation`` are accepted for config uniformity and ignored (any ``T`` works).
    A joint with no known frame at all keeps its (masked) input with, if degenerate, the identity quaternion.
    """

    def network(self, x: Tensor, known: Tensor, interp: Tensor | None) -> Tensor:
        """``x (B, T, J, F), known (B, T, J) bool, interp ignored -> raw (B, T, J, F)``."""
        known = known.to(torch.bool)
        t = x.shape[1]
        frame = torch.arange(t, device=x.device).view(1, t, 1).expand_as(known)
        last = torch.where(known, frame, torch.full_like(frame, -1)).cummax(dim=1).values
        nxt = torch.where(known, frame, torch.full_like(frame, t)).flip(1).cummin(dim=1).values.flip(1)
        src = torch.where(last >= 0, last, torch.where(nxt < t, nxt, frame))  # (B, T, J) source frame
        raw = torch.gather(x, 1, src[..., None].expand(-1, -1, -1, x.shape[-1]))
        q = raw[..., self.quat]
        identity = torch.zeros_like(q)
        identity[..., 0] = 1.0
        degenerate = (q * q).sum(dim=-1, keepdim=True) < self.quat_eps
        return torch.cat([raw[..., : self.quat.start], torch.where(degenerate, identity, q), raw[..., self.quat.stop :]], -1)


class Interpolation(_Baseline):
    """Return the data pipeline's interpolation ``interp`` (linear positions / slerp rotations) of the unknown
    values; ValueError if ``interp`` is ``None``.  Constructor as :class:`ZeroVelocity`."""

    def network(self, x: Tensor, known: Tensor, interp: Tensor | None) -> Tensor:
        """``x (B, T, J, F), known (B, T, J) bool, interp (B, T, J, F) -> raw = interp``."""
        if interp is None:
            raise ValueError("Interpolation: interp is required (the masked-input interpolation of the data pipeline)")
        return interp
