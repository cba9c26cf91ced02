"""The gap plan: which windows fill which frames, and where long gaps are split.

For keys ``a < b`` with ``b - a > 1`` the frames ``a+1 .. b-1`` are generated in one window when the gap is at most
``limit`` frames.  A longer gap is split into ``m = ceil((b - a) / (limit + 1))`` equal segments; the poses at the
``m - 1`` split points are *pseudo-keyframes* interpolated between ``a`` and ``b`` (:func:`~inbetweening.geometry.
interp.interpolate_pose`: root linearly, every joint by slerp), then each segment is generated left to right, its
context the end of the previous one.  The true keys are never modified.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from .model import InbetweenError

__all__ = ["GapPlan", "check_keys", "plan_gaps"]


def check_keys(keys, length: int, what: str = "keyframes") -> list[int]:
    """``keys`` as a list of ints: at least 2, strictly increasing, inside ``[0, length)``; otherwise
    :class:`InbetweenError` naming ``what`` and the offending frame."""
    if keys is None or isinstance(keys, (str, bytes)):
        raise InbetweenError(f"{what} must be a list of frame indices, got {keys!r}")
    out = []
    for k in list(keys):
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)):
            raise InbetweenError(f"{what}: {k!r} is not an integer frame index")
        out.append(int(k))
    if len(out) < 2:
        raise InbetweenError(f"{what}: need at least 2 keyframes, got {len(out)} ({out})")
    for k in out:
        if not 0 <= k < length:
            raise InbetweenError(f"{what}: frame {k} is out of range for a clip of {length} frames (valid: 0..{length - 1})")
    for i in range(1, len(out)):
        if out[i] == out[i - 1]:
            raise InbetweenError(f"{what}: frame {out[i]} is listed twice")
        if out[i] < out[i - 1]:
            raise InbetweenError(f"{what}: must be sorted in increasing order ({out[i - 1]} comes before {out[i]})")
    return out


@dataclass(frozen=True)
class GapPlan:
    """``segments``: the windows' ``(a, b)`` (context ends at ``a``, target ``b``), in the order they are generated;
    ``pseudo``: per split gap ``(a, b, [split points])``."""

    segments: list[tuple[int, int]]
    pseudo: list[tuple[int, int, list[int]]]

    @property
    def pseudo_keyframes(self) -> list[int]:
        return sorted(p for _, _, points in self.pseudo for p in points)


def plan_gaps(keys: list[int], limit: int, segment: bool = True, trained_gap: int | None = None) -> GapPlan:
    """The :class:`GapPlan` of sorted ``keys`` for windows of at most ``limit`` generated frames; with
    ``segment=False`` a longer gap is an :class:`InbetweenError` (naming ``trained_gap`` when given)."""
    segments, pseudo = [], []
    for a, b in itertools.pairwise(keys):
        gap = b - a - 1
        if gap == 0:
            continue
        if gap > limit and not segment:
            trained = f" (the model was trained on gaps up to {trained_gap})" if trained_gap else ""
            raise InbetweenError(f"the gap between keyframes {a} and {b} is {gap} frames, longer than max_gap={limit}"
                                 f"{trained}; enable segmentation or add keyframes")
        m = math.ceil((b - a) / (limit + 1))
        points = [a + round(i * (b - a) / m) for i in range(m + 1)]
        if m > 1:
            pseudo.append((a, b, points[1:-1]))
        segments += [(s, e) for s, e in itertools.pairwise(points) if e - s > 1]
    return GapPlan(segments, pseudo)
