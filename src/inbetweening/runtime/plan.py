"""The gap plan: which windows fill which frames, and where long gaps are split.

For keys ``a < b`` with ``b - a > 1`` the frames ``a+1 .. b-1`` are generated in one window when the gap is at most
``limit`` frames.  A longer gap is split into ``m = ceil((b - a) / (limit + 1))`` equal segments; the poses at the
``m - 1`` split points are *pseudo-keyframes* interpolated between ``a`` and ``b`` (:func:`~inbetweening.geometry.
interp.interpolate_pose`: root linearly, every joint by slerp), then each segment is generated left to right, its
context the end of the previous one.  The true keys are never modified.

**Re-fills** (:func:`chosen_gaps`).  A caller that filled before and changed some keys can keep the frames of the
gaps nothing changed for: it hands over every key and, in the other gaps, the earlier fill's output, names the key
gaps whose own inputs changed (``only``) and the network shares the earlier fill gave each gap (``previous``).  A key
gap is generated when it is named; when its share now (the self-check on the keys, :mod:`.trust`, reaches
``reach`` gap lengths either side of a key, :class:`~.settings.FillSettings`) differs from the earlier one, or there
is none; when its
frames do not all hold finite values; or when one of its ``n_past - 1`` context frames lies in a gap generated now
(each window's context is the output so far: a generated gap re-generates the gaps it is context for).  The other gaps
keep their frames: where they hold what a fill of every gap gave, the result is what a fill of every gap gives now.
"""
from __future__ import annotations

import bisect
import itertools
import math
from dataclasses import dataclass

import numpy as np

from .model import InbetweenError

__all__ = ["GapPlan", "check_keys", "check_refill", "chosen_gaps", "gap_windows", "key_gaps", "plan_gaps"]

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


def key_gaps(keys: list[int]) -> list[tuple[int, int]]:
    """The gaps between consecutive ``keys`` that hold frames."""
    return [(a, b) for a, b in itertools.pairwise(keys) if b - a > 1]


def gap_windows(keys: list[int], segments) -> dict[tuple[int, int], list[tuple[int, int]]]:
    """The windows ``(a, b)`` of ``segments`` per key gap (every gap of :func:`key_gaps`), in order."""
    out: dict[tuple[int, int], list[tuple[int, int]]] = {g: [] for g in key_gaps(keys)}
    for a, b in segments:
        i = bisect.bisect_right(keys, a) - 1
        out[(keys[i], keys[i + 1])].append((a, b))
    return out


def check_refill(keys: list[int], only, previous) -> tuple[set | None, dict]:
    """``only`` as a set of key gaps (each a pair of consecutive ``keys``, else :class:`InbetweenError`; ``None``: a fill
    of every gap) and ``previous`` as ``{key gap: (share, ...)}`` (a number: a gap of one window; entries for gaps that
    are not the keys' are left out)."""
    if only is None:
        return None, {}
    gaps = set(itertools.pairwise(keys))
    out = set()
    for g in only:
        try:
            a, b = (int(x) for x in g)
        except (TypeError, ValueError):
            raise InbetweenError(f"only: {g!r} is not a gap (a pair of keys)") from None
        if (a, b) not in gaps:
            raise InbetweenError(f"only: ({a}, {b}) is not a gap between two consecutive keys")
        out.add((a, b))
    prev = {}
    for g, shares in dict(previous or {}).items():
        g = tuple(int(x) for x in g)
        if g in gaps:
            prev[g] = tuple(float(w) for w in np.atleast_1d(np.asarray(shares, dtype=np.float64)))
    return out, prev


def chosen_gaps(keys: list[int], shares: dict, only: set | None, previous: dict, n_past: int,
                finite, tolerance: float) -> list[tuple[int, int]]:
    """The key gaps a fill generates, left to right (module docstring): every gap when ``only`` is ``None``.
    ``shares``: ``{key gap: (share, ...)}`` now; ``previous``: the earlier ones (:func:`check_refill`), the same where
    they differ by at most ``tolerance`` (``FillSettings.share_tolerance``); ``finite(a, b)``: whether the input holds
    finite values on the gap's frames."""
    gaps = key_gaps(keys)
    if only is None:
        return gaps
    out: list[tuple[int, int]] = []
    generated = np.zeros(keys[-1] + 1, dtype=bool)
    for a, b in gaps:
        before = previous.get((a, b))
        take = ((a, b) in only or before is None or len(before) != len(shares[(a, b)])
                or any(abs(x - y) > tolerance for x, y in zip(before, shares[(a, b)]))
                or generated[max(a - n_past + 1, 0) : a].any() or not finite(a, b))
        if take:
            out.append((a, b))
            generated[a + 1 : b] = True
    return out
