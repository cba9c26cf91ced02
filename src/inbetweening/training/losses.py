"""Training losses on ``(B, T, J, F)`` features; every term is averaged over the ``mask`` entries.

``mask`` is ``(B, T, J)`` bool: the values the model had to predict (unknown and inside the window).  ``reduce``
(the ``loss.reduce`` config entry) says how: ``frames`` averages over every masked value of the batch, so a window with
a 45-frame gap weighs nine times one with a 5-frame gap; ``windows`` averages each window over its own masked values,
then the windows, so every gap length weighs the same per sample.
Weights come from the ``loss`` config; only ``l1`` (the method's loss) is on by default.  What the channels mean
(positions, rotations, their units) is asked of the representation (``rep``,
:class:`inbetweening.representation.base.Representation`).
"""
from __future__ import annotations

from collections.abc import Sequence

import torch

from inbetweening.geometry.quaternion import qnormalize
from inbetweening.representation.base import Representation

LOSS_TERMS = ("l1", "fk_pos", "quat", "bone", "smooth", "foot", "keyframe")
REDUCTIONS = ("frames", "windows")


def _masked_mean(err: torch.Tensor, mask: torch.Tensor, reduce: str = "frames") -> torch.Tensor:
    """Mean of ``err (B, T, J[, ...])`` over ``mask (B, T, J)``; 0 when the mask is empty.  ``reduce="windows"``: the
    mean of each window's own masked mean, over the windows that have masked values."""
    m = mask.to(err.dtype)
    while m.dim() < err.dim():
        m = m[..., None]
    m = m.expand_as(err)
    if reduce == "frames":
        return (err * m).sum() / m.sum().clamp(min=1.0)
    dims = tuple(range(1, err.dim()))
    count = m.sum(dims)
    per_window = (err * m).sum(dims) / count.clamp(min=1.0)
    has = (count > 0).to(err.dtype)
    return (per_window * has).sum() / has.sum().clamp(min=1.0)


def l1(pred: torch.Tensor, gt: torch.Tensor, mask: torch.Tensor, reduce: str = "frames") -> torch.Tensor:
    """L1 on the normalised features (the method's loss)."""
    return _masked_mean((pred - gt).abs(), mask, reduce)


def fk_positions(pred: torch.Tensor, rep: Representation) -> torch.Tensor:
    """Global positions from FK of the predicted root + local quaternions, in the position channels' units.
    ``(B, T, J, F) -> (B, T, J, 3)``."""
    _, gp = rep.skeleton.pose(*rep.decode(pred))
    return rep.normalise_positions(gp)


def fk_pos(pred, gt, mask, rep: Representation, reduce: str = "frames") -> torch.Tensor:
    """L1 between FK global positions of the prediction and the true global positions (position units)."""
    return _masked_mean((fk_positions(pred, rep) - gt[..., rep.pos]).abs(), mask, reduce)


def quat(pred, gt, mask, rep: Representation, reduce: str = "frames") -> torch.Tensor:
    """Sign-invariant rotation distance ``1 - |<q_pred, q_gt>|``."""
    d = (qnormalize(pred[..., rep.quat]) * gt[..., rep.quat]).sum(-1).abs()
    return _masked_mean(1.0 - d, mask, reduce)


def bone(pred, gt, mask, rep: Representation, reduce: str = "frames") -> torch.Tensor:
    """Rigidity: difference of parent/child distances of predicted vs true global positions."""
    pairs = torch.as_tensor(rep.skeleton.bone_pairs(), device=pred.device)
    pp, gp = rep.global_positions(pred), rep.global_positions(gt)
    c, p = pairs[:, 0], pairs[:, 1]
    err = ((pp[..., c, :] - pp[..., p, :]).norm(dim=-1) - (gp[..., c, :] - gp[..., p, :]).norm(dim=-1)).abs()
    return _masked_mean(err / rep.position_scale(), mask[..., c] | mask[..., p], reduce)


def smooth(pred, mask, rep: Representation, reduce: str = "frames") -> torch.Tensor:
    """Distance of each predicted frame's positions to the mean of its two neighbours (position units)."""
    p = pred[..., rep.pos]
    mid = 0.5 * (p[:, :-2] + p[:, 2:])
    return _masked_mean((p[:, 1:-1] - mid).norm(dim=-1), mask[:, 1:-1], reduce)


def foot(pred, gt, mask, foot_joints: Sequence[int], rep: Representation, threshold: float,
         reduce: str = "frames") -> torch.Tensor:
    """Foot sliding: predicted foot velocity where the true foot is in contact (true speed < ``threshold`` length units
    per frame: the data's contact speed over its frame rate, :class:`~inbetweening.data.contacts.FootContact`)."""
    if not foot_joints:
        return pred.new_zeros(())
    idx = torch.as_tensor(foot_joints, device=pred.device)
    pp, gp = rep.global_positions(pred)[..., idx, :], rep.global_positions(gt)[..., idx, :]
    pv = (pp[:, 1:] - pp[:, :-1]).norm(dim=-1)
    contact = (gp[:, 1:] - gp[:, :-1]).norm(dim=-1) < threshold
    return _masked_mean(pv / rep.position_scale(), mask[:, 1:][..., idx] & contact, reduce)


def keyframe(raw: torch.Tensor, gt: torch.Tensor, known: torch.Tensor, reduce: str = "frames") -> torch.Tensor:
    """Keyframe consistency: L1 between the network's own output at the KNOWN values (``raw``, before the model copies
    the keyframes back over it) and the keyframes.  A prediction that agrees with its keyframes joins them without a
    jump; the transition frames are not in this term."""
    return l1(raw, gt, known, reduce)


def total_loss(pred, gt, mask, weights: dict, rep: Representation, raw=None, known=None, feet: Sequence[int] = (),
               foot_speed: float = 0.0) -> tuple[torch.Tensor, dict]:
    """Weighted sum of the enabled terms and a dict of every computed term (for logging).  ``weights``: the ``loss``
    config, a weight per term and optionally ``reduce`` (``frames``, the default, or ``windows``; module docstring).
    ``raw`` / ``known``: the network's output before the keyframes are copied back and the known mask, needed by
    ``keyframe``; ``feet`` (joint indices) and ``foot_speed`` (contact speed per frame): the data's foot contact rule,
    needed by ``foot``."""
    weights = dict(weights)
    r = weights.pop("reduce", "frames")
    if r not in REDUCTIONS:
        raise ValueError(f"loss.reduce: {r!r} is not one of {list(REDUCTIONS)}")
    unknown = [k for k in weights if k not in LOSS_TERMS]
    if unknown:
        raise ValueError(f"loss: unknown term(s) {unknown}; known: {list(LOSS_TERMS)} and reduce")
    terms: dict[str, torch.Tensor] = {}
    for name, w in weights.items():
        if not w and name != "l1":
            continue
        if name == "l1":
            terms[name] = l1(pred, gt, mask, r)
        elif name == "fk_pos":
            terms[name] = fk_pos(pred, gt, mask, rep, r)
        elif name == "quat":
            terms[name] = quat(pred, gt, mask, rep, r)
        elif name == "bone":
            terms[name] = bone(pred, gt, mask, rep, r)
        elif name == "smooth":
            terms[name] = smooth(pred, mask, rep, r)
        elif name == "foot":
            terms[name] = foot(pred, gt, mask, feet, rep, foot_speed, r)
        elif name == "keyframe":
            if raw is None or known is None:
                raise ValueError("loss.keyframe: needs the network's raw output and the known mask (raw=, known=)")
            terms[name] = keyframe(raw, gt, known, r)
    total = sum(float(weights[k]) * v for k, v in terms.items())
    return total, terms
