"""How much of the network's correction the fill keeps, per gap: the do-no-harm blend.

Every generated frame is ``interpolation + w (network - interpolation)`` (the root linearly, rotations by slerp), with
one weight ``w`` in [0, 1] per gap, the product of two pieces of evidence:

* **what the model knows about gaps of this length**: its calibrated weight for the gap's length
  (:meth:`~inbetweening.runtime.model.ModelInfo.blend_weight`, fitted on validation windows; 1 for a model without);
* **what it knows about this motion: the self-check on the user's own keys.**  For each interior key ``k`` whose
  neighbours' window fits the length the model was trained on, the key is hidden and the network predicts it across
  ``(previous key, next key)`` (context: the interpolation of the keys before); ``x`` = the network's mean joint
  error at ``k`` over interpolation's there, pooled over the checked keys within ``reach`` gaps of the gap.  The
  trust is ``clip((x_none - x) / (x_none - x_full), 0, 1)``: all of the calibrated weight where the network predicts
  the user's keys at under ``x_full`` of interpolation's error, none where it does no better than ``x_none`` (the
  keys are ground truth the user gave: a motion the model does not know shows there first).  Gaps under
  ``dense_gap`` frames are judged more strictly (``dense_x_full``, ``dense_x_none``): with
  dense keys the hidden key lies mid-way in a window twice as long as the gaps filled, where the network gains more
  over interpolation than in the gaps themselves, so the check overrates it there (RESULTS.md section 5.2).  Checks
  whose windows are near the longest gap the model trained on (over ``long_check`` of it) can take their own pair
  (``long_x_full``, ``long_x_none``): there the network is judged where it is weakest (RESULTS.md section 3.5).

A gap with no checked key near it (two keys only; keys so far apart that the check's window is longer than the
model's trained gap) keeps the calibrated weight.  RESULTS.md section 5.2 measures the rule against its alternatives.
The thresholds are :class:`~inbetweening.runtime.settings.FillSettings` fields (defaults 0.65 / 1.05, 5 frames,
0.60 / 0.95, 3 gaps).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from inbetweening.geometry.interp import interpolate_pose
from inbetweening.geometry.skeleton import Skeleton

from .settings import DEFAULT_SETTINGS, FillSettings

__all__ = ["blend", "Check", "checks_of", "gap_share", "gap_weights", "is_long", "trust_of"]


def blend(interp_root: np.ndarray, interp_q: np.ndarray, net_root: np.ndarray, net_q: np.ndarray,
          weight: float) -> tuple[np.ndarray, np.ndarray]:
    """The do-no-harm blend: the network's frames ``net_root (..., 3)``, ``net_q (..., J, 4)`` taken ``weight`` of the
    way from the interpolation's (roots linearly, rotations by slerp); ``weight`` 1 is the network, 0 interpolation.
    (The training-time blend on features is :meth:`Predictor.blended`.)"""
    return interpolate_pose(interp_root, interp_q, net_root, net_q, np.full(np.shape(net_root)[:-1], float(weight)))

@dataclass(frozen=True)
class Check:
    """One self-check: the key ``key`` hidden in the window ``(a, b)``; ``net``/``interp``: the mean joint position
    error there of the network and of interpolation (the skeleton's length unit)."""

    a: int
    key: int
    b: int
    net: float = float("nan")
    interp: float = float("nan")


def checks_of(keys: Sequence[int], trained_gap: int) -> list[Check]:
    """The self-checks of a fill's keys (sorted): every interior key whose neighbours are at most ``trained_gap + 1``
    frames apart."""
    return [Check(a, k, b) for a, k, b in zip(keys, keys[1:], keys[2:]) if b - a - 1 <= trained_gap]


def scored(check: Check, skeleton: Skeleton, root: np.ndarray, q: np.ndarray, pred_root: np.ndarray,
           pred_q: np.ndarray) -> Check:
    """``check`` with its errors: the network's prediction of the hidden key ``pred_root (3,), pred_q (J, 4)`` and the
    interpolation between ``a`` and ``b``, against the key itself (``root (F, 3)``, ``q (F, J, 4)``: the clip)."""
    a, k, b = check.a, check.key, check.b
    ir, iq = interpolate_pose(root[a], q[a], root[b], q[b], np.array((k - a) / (b - a)))
    poses = skeleton.pose(np.stack([root[k], pred_root, ir]), np.stack([q[k], pred_q, iq]))[1]
    err = np.linalg.norm(poses[1:] - poses[0], axis=-1).mean(-1)
    return Check(a, k, b, float(err[0]), float(err[1]))


def trust_of(x: float, gap: int | None = None, settings: FillSettings = DEFAULT_SETTINGS, long: bool = False) -> float:
    """The self-check's trust for an error ratio ``x`` in a gap of ``gap`` frames (module docstring; ``None``: a gap
    of ``settings.dense_gap`` frames or more); ``long``: checked on windows over ``settings.long_check`` of the
    trained gap (:func:`is_long`)."""
    s = settings
    full, none = ((s.dense_x_full, s.dense_x_none) if gap is not None and gap < s.dense_gap
                  else (s.long_x_full, s.long_x_none) if long else (s.x_full, s.x_none))
    return float(np.clip((none - x) / (none - full), 0.0, 1.0))


def is_long(checks: Sequence[Check], trained_gap: int | None, settings: FillSettings = DEFAULT_SETTINGS) -> bool:
    """Whether ``checks``' windows (``b - a - 1`` frames) are on average longer than ``settings.long_check`` of
    ``trained_gap`` (``None``: never): near the longest gap the network trained on it is judged where it is
    weakest, so such checks take their own thresholds (RESULTS.md 3.5)."""
    if trained_gap is None or not checks or settings.long_check >= 1.0:
        return False
    return float(np.mean([c.b - c.a - 1 for c in checks])) > settings.long_check * trained_gap


def gap_weights(segments: Sequence[tuple[int, int]], keys: Sequence[int], checks: Sequence[Check],
                prior, settings: FillSettings = DEFAULT_SETTINGS,
                trained_gap: int | None = None) -> dict[tuple[int, int], tuple[float, float | None]]:
    """``{(a, b): (weight, x)}`` for each generated window ``(a, b)`` of a clip: the calibrated ``prior(gap length)``
    (``None``: 1) times the trust of the self-checks near the key gap the window lies in (``x``: their pooled error
    ratio, ``None`` where there is none; ``trained_gap``: the model's, for :func:`is_long`)."""
    keys = list(keys)
    out = {}
    for a, b in segments:
        i = int(np.searchsorted(keys, a, side="right")) - 1  # the key gap (keys[i], keys[i + 1]) holding the window
        lo, hi = keys[i], keys[min(i + 1, len(keys) - 1)]
        reach = settings.reach * max(hi - lo, 1)
        near = [c for c in checks if lo - reach <= c.key <= hi + reach and c.interp > 0]
        p = prior(b - a - 1)
        p = 1.0 if p is None else float(p)
        if not near:
            out[(a, b)] = (p, None)
            continue
        x = sum(c.net for c in near) / sum(c.interp for c in near)
        out[(a, b)] = (p * trust_of(x, b - a - 1, settings, is_long(near, trained_gap, settings)), float(x))
    return out


def gap_share(shares: dict, gap: tuple[int, int]) -> float:
    """The network's least share over the windows of the key gap ``gap`` (``shares``: ``{(key, next key): (weight,
    ...)}``, as the fill's ``shares``); 1 for a gap it does not list."""
    return min(shares.get(gap, (1.0,)))
