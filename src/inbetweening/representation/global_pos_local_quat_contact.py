"""The method's features plus foot contact: per joint ``[x, y, z, qw, qx, qy, qz, c]``.

``c`` is 1 where the joint is a foot joint of the data (:class:`~inbetweening.data.contacts.FootContact`) planted
on the floor in that frame, 0 otherwise (every other joint: always 0).  A frame is planted when the joint's height is
below the contact height and its speed (to the next frame, else from the previous one) below the contact speed; a
frame whose neighbours are both unknown (an isolated keyframe) is judged on its height alone; unknown frames stay
NaN.  The network predicts ``c`` like any channel; the tools read it back with :meth:`contacts` to lock the feet
(:mod:`inbetweening.runtime.foot_lock`).
"""
from __future__ import annotations

import numpy as np
import torch

from inbetweening.data.contacts import planted_frames
from inbetweening.geometry.kinematics_np import fk_np
from inbetweening.representation.global_pos_local_quat import GlobalPosLocalQuat

UP = 1


def _speed_torch(p: torch.Tensor, fps: float) -> torch.Tensor:
    """Per-frame speed (to the next frame, else from the previous one) of positions ``(..., T, K, 3)``: the torch
    twin of :func:`~inbetweening.data.contacts.planted_frames`' (tests check they agree)."""
    d = p[..., 1:, :, :] - p[..., :-1, :, :]  # (slices export to ONNX; sqrt of a sum, not vector_norm: ONNX
    step = (d * d).sum(-1).sqrt() * fps  # Runtime 1.19, which the Blender extension bundles, has no float64 ReduceL2)
    pad = torch.full_like(step[..., :1, :], float("nan"))
    fwd, bwd = torch.cat([step, pad], dim=-2), torch.cat([pad, step], dim=-2)
    return torch.where(torch.isnan(fwd), bwd, fwd)


class GlobalPosLocalQuatContact(GlobalPosLocalQuat):
    """Z-scored global positions + local quaternions + foot contact (8 per joint)."""

    name = "global_pos_local_quat_contact"
    features = 8
    contact_channel = slice(7, 8)
    description = ("per joint [(p - pos_mean) / pos_std (xyz, global position), local quaternion wxyz, foot contact "
                   "(1 planted, 0 not; 0 for joints that are not feet)]")

    @classmethod
    def channels(cls) -> dict[str, slice]:
        return {**super().channels(), "contact": cls.contact_channel}

    def _feet(self) -> list[int]:
        return list(self.contact.indices(self.skeleton.names, "representation contact feet"))

    def labels_np(self, gp: np.ndarray) -> np.ndarray:
        """Contact labels of global positions ``(..., T, J, 3) -> (..., T, J, 1)`` (numpy): the data's rule,
        :func:`~inbetweening.data.contacts.planted_frames`, on the feet; NaN where the positions are."""
        out = np.zeros(gp.shape[:-1] + (1,), dtype=gp.dtype)
        feet = self._feet()
        if feet:
            out[..., feet, 0] = planted_frames(gp[..., feet, :], self.fps, self.contact.height, self.contact.speed)
        out[np.isnan(gp[..., :1])] = np.nan
        return out

    def labels(self, gp: torch.Tensor) -> torch.Tensor:
        """Contact labels of global positions ``(..., T, J, 3) -> (..., T, J, 1)`` (torch; every joint computed and
        the non-feet zeroed, so the graph has no indexed writes and exports to ONNX)."""
        is_foot = torch.zeros(gp.shape[-2], dtype=gp.dtype, device=gp.device)
        feet = self._feet()
        if feet:
            is_foot[feet] = 1.0
        speed = _speed_torch(gp, self.fps)
        c = (gp[..., UP] < self.contact.height) & ((speed < self.contact.speed) | torch.isnan(speed))
        c = c.to(gp.dtype) * is_foot
        nan = torch.isnan(gp[..., UP])
        return torch.where(nan, torch.full_like(c, float("nan")), c)[..., None]

    def encode(self, root, local_q):
        _, gp = self.skeleton.pose(root, local_q)
        return torch.cat([self.normalise_positions(gp), local_q, self.labels(gp)], dim=-1)

    def encode_np(self, root, local_q):
        gp = fk_np(local_q, self.skeleton.local_positions(root), self.skeleton.parents, positions_only=True)
        return np.concatenate([(gp - self._mean_np) / self._std_np, local_q, self.labels_np(gp)], axis=-1)

    def contacts(self, feats):
        return feats[..., self.contact_channel.start].clamp(0.0, 1.0)
