"""Common contract of every in-betweening model of the zoo."""
from __future__ import annotations

import torch
from torch import Tensor, nn

FEATURE_DIM = 7  # per joint: [pos x, pos y, pos z, qw, qx, qy, qz]
POS = slice(0, 3)
QUAT = slice(3, 7)


class InbetweenModel(nn.Module):
    """Base class: ``forward(x, known, interp=None) -> (B, T, J, 7)``.

    * ``x``: ``(B, T, J, 7)`` masked input features (unknown values zeroed or interpolated by the data pipeline).
    * ``known``: ``(B, T, J)`` bool, ``True`` where the value is given (keyframes / context).
    * ``interp``: ``(B, T, J, 7)`` or ``None``: interpolation of the unknown frames (for residual prediction).

    Every subclass ends its ``forward`` with :meth:`finalize`, so known values pass through bit-identically and
    predicted quaternions have unit norm.  Baselines without parameters set ``trainable = False``.
    """

    trainable: bool = True
    quat_eps: float = 1e-8

    def forward(self, x: Tensor, known: Tensor, interp: Tensor | None = None) -> Tensor:  # pragma: no cover
        """``x (B, T, J, F), known (B, T, J), interp (B, T, J, F) | None -> (B, T, J, F)``."""
        raise NotImplementedError

    @classmethod
    def normalize_quaternions(cls, raw: Tensor) -> Tensor:
        """Scale features ``3:7`` of ``(..., F)`` to unit norm; other features unchanged."""
        q = raw[..., QUAT]
        norm = torch.sqrt((q * q).sum(dim=-1, keepdim=True)).clamp_min(cls.quat_eps)
        return torch.cat([raw[..., POS], q / norm, raw[..., QUAT.stop :]], dim=-1)

    def finalize(self, raw: Tensor, x: Tensor, known: Tensor) -> Tensor:
        """``raw, x (B, T, J, F), known (B, T, J) -> (B, T, J, F)``: unit quaternions, known values copied from ``x``."""
        pred = self.normalize_quaternions(raw)
        return torch.where(known[..., None].to(torch.bool), x, pred)
