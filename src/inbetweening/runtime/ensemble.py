"""Several trained networks of one skeleton as one backend: :class:`EnsembleBackend`.

Each member predicts the same canonical windows; the ensemble's prediction is their mean, each member weighted by
its calibrated do-no-harm weight for the window's gap length (:meth:`ModelInfo.blend_weight`: how much it beat
interpolation on validation windows of that length; 1 for a member without a blend) raised to the power
``share_power`` (:class:`~inbetweening.runtime.settings.FillSettings`, default 4),
so a member much less trusted at a length has almost no say there (RESULTS.md section 2.1): the root's position, the
rotations' weighted, normalised sum (sign-aligned to the first member's), the foot contacts of the members that
predict them.  Two models trained differently fail in different places, so their mean is closer to the motion than
either.  The fill runtime treats the ensemble as one network: its blend weight per gap length is its most trusted
member's (the largest of the members' weights; their weighted mean kept less of the better prediction: RESULTS.md
appendix, which measures it), and the self-check on the user's keys weighs the ensemble's own prediction.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from .model import Backend, ModelError, ModelInfo
from .settings import DEFAULT_SETTINGS

__all__ = ["EnsembleBackend", "ensemble_info", "member_weights"]


def _same_skeleton(a: ModelInfo, b: ModelInfo) -> bool:
    sa, sb = a.skeleton, b.skeleton
    return (list(sa.names) == list(sb.names) and list(sa.parents) == list(sb.parents)
            and np.allclose(sa.offsets, sb.offsets, atol=1e-4))


def ensemble_info(infos: Sequence[ModelInfo], where: Sequence[str] | None = None) -> ModelInfo:
    """The :class:`ModelInfo` of an ensemble of models ``infos`` (:class:`ModelError` naming the member, ``where``,
    that does not fit the first: another skeleton, context, canonical frame, frame rate or file convention).  Its
    gaps are the shortest any member was trained on; its blend weight per gap length is the largest of the
    members' (a member without a blend counts 1); it predicts contact when a member does."""
    names = list(where) if where is not None else [f"model {i + 1}" for i in range(len(infos))]
    if not infos:
        raise ModelError("ensemble: no models given")
    first = infos[0]
    for info, name in zip(infos[1:], names[1:]):
        for what, ok in (("skeleton", _same_skeleton(first, info)), ("n_past", info.n_past == first.n_past),
                         ("forward axis", np.allclose(info.forward_axis, first.forward_axis)),
                         ("canonical centre", info.centre == first.centre), ("fps", info.fps == first.fps),
                         ("file convention", info.convention == first.convention)):
            if not ok:
                raise ModelError(f"ensemble: {name} has another {what} than {names[0]}; "
                                 "the members of an ensemble must be models of one skeleton and data")
    blend = None
    if any(i.blend is not None for i in infos):
        n = max(len(i.blend or ()) for i in infos)
        blend = tuple(float(_weights(infos, g).max()) for g in range(1, n + 1))
    return replace(first, trained_gap=min(i.trained_gap for i in infos),
                   hard_max_gap=min(i.hard_max_gap for i in infos), blend=blend,
                   has_contacts=any(i.has_contacts for i in infos))


def _weights(infos: Sequence[ModelInfo], gap: int) -> np.ndarray:
    w = [i.blend_weight(gap) for i in infos]
    return np.array([1.0 if x is None else x for x in w])


def member_weights(infos: Sequence[ModelInfo], gap: int, power: float = DEFAULT_SETTINGS.share_power) -> np.ndarray:
    """``(M,)``: each member's share of the ensemble's prediction in a gap of ``gap`` frames, its calibrated weight
    for that length to the power ``power`` (``FillSettings.share_power``), normalised to sum 1 (equal shares where
    every weight is 0)."""
    w = _weights(infos, gap) ** power
    return w / w.sum() if w.sum() > 0 else np.full(len(w), 1.0 / len(w))


class EnsembleBackend:
    """The members' mean prediction (module docstring); ``members``: backends of one skeleton, ``where``: their names
    for error messages (e.g. the checkpoint paths).  ``share_power``: the power of the members' shares (the
    :class:`~inbetweening.runtime.FillRuntime` filling with it sets it from its settings).  ``calls``: the batches
    predicted, as a single backend counts them."""

    def __init__(self, members: Sequence[Backend], where: Sequence[str] | None = None):
        self.members, self.share_power = list(members), DEFAULT_SETTINGS.share_power
        self.info = ensemble_info([m.info for m in self.members], where)
        self.calls = 0

    def adapted(self, groups, steps: int, lr: float) -> EnsembleBackend:
        """Test-time adaptation (:mod:`.adapt`): each member adapted on ``groups`` (its ``adapted``)."""
        out = EnsembleBackend([m.adapted(groups, steps, lr) for m in self.members])
        out.info, out.share_power = self.info, self.share_power
        return out

    def predict(self, root, local_q, known, weight, contacts=True):
        """The members' weighted mean (module docstring).  A member with no share in the pose at the window's gap
        length (a calibrated weight of 0) is not run unless its contact is needed (``contacts`` and it predicts
        one): the result is the same, without its network's time (the rotations are sign-aligned to the first member
        with a share; where the first member itself has none, the same rotation may come out with the other sign)."""
        self.calls += 1
        a = member_weights([m.info for m in self.members], np.shape(root)[1] - self.info.n_past - 1,
                           self.share_power)
        run = [i for i, m in enumerate(self.members) if a[i] > 0 or (contacts and m.info.has_contacts)]
        outs = {i: self.members[i].predict(root, local_q, known, weight, contacts=contacts) for i in run}
        posed = [i for i in run if a[i] > 0]
        roots = sum(a[i] * np.asarray(outs[i][0], np.float64) for i in posed)
        qs = [np.asarray(outs[i][1], np.float64) for i in posed]
        total = a[posed[0]] * qs[0]
        for i, q in zip(posed[1:], qs[1:]):  # the same hemisphere as the first member's, then the normalised sum
            total = total + a[i] * np.where(np.sum(q * qs[0], axis=-1, keepdims=True) < 0, -q, q)
        q = total / np.linalg.norm(total, axis=-1, keepdims=True)
        contact = [np.asarray(outs[i][2], np.float64) for i in run if outs[i][2] is not None] if contacts else []
        return roots, q, (np.mean(contact, axis=0) if contact else None)
