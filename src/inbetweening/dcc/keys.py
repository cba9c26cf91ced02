"""Which frames are keys, and which keys a channel gets.

- **Whole and partial keys** (:func:`split_keys`): a frame where every bone keyed anywhere has a key of the animator
  is a *whole key*, and the gaps run between whole keys; a frame between two whole keys where only some bones have a
  key is a *partial key* of those bones (:mod:`inbetweening.runtime.partial`: they keep their keys, the model fills
  around them).  Frames before the first or after the last whole key, and every frame when fewer than two are whole,
  are whole keys.
- **The range** (:func:`fill_span`): the scene's, or with *Only Selected Range* the span of the selected keys (none
  selected: the preview range).
- **A channel's keys after a fill** (:func:`channel_keys`): the generated frames where the animator has no key of the
  channel, and the key frames the channel has no key at (keyed at its current value there, as a channel keyed at
  every key frame needs).
"""
from __future__ import annotations

import numpy as np

from .host import RigError

__all__ = ["channel_keys", "fill_span", "inside", "runs", "split_keys"]


def split_keys(by_frame: dict[int, set[str]], whole_only: bool = False) -> tuple[list[int], dict[int, set[str]]]:
    """The whole keys and the partial keys of ``{frame: bones keyed there}`` (:meth:`~.edits.Past.keyed_bones`): a
    frame is a whole key when every bone keyed anywhere is keyed there, a partial key (constraining its bones only)
    when it lies between two whole keys; frames outside them, and every frame when fewer than two are whole (or
    ``whole_only``), are whole keys, each channel not keyed there keyed at its current value."""
    frames = sorted(by_frame)
    every = set().union(*by_frame.values()) if by_frame else set()
    whole = [f for f in frames if by_frame[f] >= every]
    if whole_only or len(whole) < 2:
        return frames, {}
    partial = {f: by_frame[f] for f in frames if whole[0] < f < whole[-1] and f not in whole}
    return sorted(set(frames) - set(partial)), partial


def fill_span(lo: int, hi: int, selected: set[int] | None = None, preview: tuple[int, int] | None = None
              ) -> tuple[int, int]:
    """The frames to fill: ``[lo, hi]`` (the scene's range); with ``selected`` given (*Only Selected Range*: the
    frames of the selected keys) the span they cover, none selected: ``preview`` (the preview range) inside
    ``[lo, hi]``, no preview range: :class:`RigError`."""
    if selected is None:
        return lo, hi
    if selected:
        return min(selected), max(selected)
    if preview is not None:
        return max(lo, preview[0]), min(hi, preview[1])
    raise RigError("only selected range: no keys are selected and there is no preview range")


def inside(frames: np.ndarray, spans) -> np.ndarray:
    """Which of ``frames`` lie strictly inside one of ``spans`` ``[(lo, hi)]``."""
    out = np.zeros(len(frames), dtype=bool)
    for lo, hi in spans:
        out |= (frames > lo) & (frames < hi)
    return out


def runs(gaps, filled) -> list[list[int]]:
    """``[[lo, hi], ...]``: the runs of consecutive ``gaps`` (in order) that are in ``filled``."""
    out: list[list[int]] = []
    filled = set(filled)
    for i, (a, b) in enumerate(gaps):
        if (a, b) not in filled:
            continue
        if out and i > 0 and gaps[i - 1] in filled:
            out[-1][1] = b
        else:
            out.append([a, b])
    return out


def channel_keys(keys, gen: np.ndarray, all_keys: list[int], partial: dict[int, set[str]], bone: str,
                 spans) -> tuple[np.ndarray, list[int]]:
    """What a fill writes on one channel (``keys``: its :class:`~inbetweening.dcc.host.Keys` now; ``gen``: the
    generated frames, in the gaps ``spans``): ``(free, missing)``, the generated frames the animator has no key of the
    channel at (a bool mask over ``gen``) and the frames to key at the channel's current value: the whole keys from the
    first to the last span end where the channel has no key (the animator's, or the fill's outside the spans), and the
    partial keys of its ``bone`` where the animator has none."""
    first, last = spans[0][0], spans[-1][1]
    xr = np.round(keys.frames).astype(int)
    mine = xr[~keys.generated]
    have = set(mine.tolist()) | set(xr[keys.generated & ~inside(xr, spans)].tolist())
    missing = [k for k in all_keys if first <= k <= last and k not in have]
    if partial:  # a partial key of this channel's bone: the bone is keyed there, each of its channels too
        missing += [f for f, keyed in partial.items() if bone in keyed and first < f < last and f not in mine]
    free = ~np.isin(gen, mine) & ~np.isin(gen, missing)  # never over one of the animator's keys
    return free, missing
