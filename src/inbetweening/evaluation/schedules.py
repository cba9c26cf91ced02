"""Keyframe schedules: where the keys of a clip are.  One owner for every schedule a config may name (eval.py's
``keyframe_intervals``, train.py's ``test_keyframes``, checked by :func:`check_schedule`) and the keyframes-only
protocol that places the keys (:mod:`inbetweening.evaluation.keyframes`).

A schedule is an interval ``K >= 2``, a key every ``K`` frames (:func:`keyframe_indices`: frames ``0, K, 2K, ...,
mK``, the clip truncated to the last keyframe so its last frame is a key), or the name of a keypose schedule of
:data:`SCHEDULES` (animators do not key on a grid):

* ``random``: gaps drawn uniformly in ``3..45`` frames from frame 0 (:func:`random_keyframes`; the protocol seeds
  the generator per clip by the run's seed and the clip's position), the clip truncated to the last key;
* ``extremes``: keys at the motion's extremes (:func:`extreme_keyframes`) - frame 0, the last frame, and the local
  minima of the mean joint speed (the poses where the motion turns), taken lowest speed first at least 8 frames from
  every key already chosen; a gap longer than 45 frames is then split into equal parts (breakdown keys).

* ``partial<K>`` (e.g. ``partial30``): partial keys (:mod:`inbetweening.evaluation.partial_keys`): whole keys every
  ``K`` frames and, halfway between each two, a key of one body part only.

Adding a schedule is one function and one entry of :data:`SCHEDULES`.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ["MIN_INTERVAL", "PARTIAL", "SCHEDULES", "partial_interval", "KeyposeSchedule", "check_schedule",
           "extreme_keyframes", "keyframe_indices",
           "mean_joint_speed", "needs_positions", "random_keyframes", "schedule_keyframes"]

MIN_INTERVAL = 2  # the shortest interval a config may name (a key every K frames; K = 1 generates nothing)
RANDOM_GAPS = (3, 45)  # random: gaps drawn uniformly in this range (frames)
EXTREME_MIN_GAP, EXTREME_MAX_GAP = 8, 45  # extremes: minima at least this far apart; longer gaps split
PARTIAL = "partial"  # partial<K>: whole keys every K frames, a partial key halfway between each two


def keyframe_indices(num_frames: int, interval: int) -> list[int]:
    """Keyframes ``0, K, 2K, ..., mK`` with ``mK <= num_frames - 1`` (the clip is cut after ``mK``); ``[]`` when the
    clip is too short for two keyframes (``num_frames < K + 1``)."""
    if interval < 1:
        raise ValueError(f"keyframe interval must be >= 1, got {interval}")
    if num_frames < interval + 1:
        return []
    return list(range(0, num_frames, interval))


def random_keyframes(num_frames: int, rng: np.random.Generator, gaps: tuple[int, int] = RANDOM_GAPS) -> list[int]:
    """Keys from frame 0 with gaps drawn uniformly in ``gaps`` (inclusive), the last one ``<= num_frames - 1`` (the
    clip is cut after it); ``[]`` when not even two keys fit."""
    lo, hi = int(gaps[0]), int(gaps[1])
    if not 1 <= lo <= hi:
        raise ValueError(f"random keyframe gaps must satisfy 1 <= lo <= hi, got {gaps}")
    keys = [0]
    while True:
        nxt = keys[-1] + int(rng.integers(lo, hi + 1))
        if nxt > num_frames - 1:
            break
        keys.append(nxt)
    return keys if len(keys) >= 2 else []


def mean_joint_speed(positions: np.ndarray) -> np.ndarray:
    """``(F, J, 3)`` global positions -> ``(F,)`` mean over joints of the central-difference speed (length units per
    frame; the first and last frame use one-sided differences)."""
    v = np.gradient(np.asarray(positions, np.float64), axis=0)
    return np.linalg.norm(v, axis=-1).mean(axis=1)


def extreme_keyframes(positions: np.ndarray, min_gap: int = EXTREME_MIN_GAP, max_gap: int = EXTREME_MAX_GAP) -> list[int]:
    """Keys at the motion's extremes (module docstring) of a clip with global positions ``(F, J, 3)``: frame 0, the
    last frame, the local minima of :func:`mean_joint_speed` lowest first at least ``min_gap`` frames from every
    chosen key, then every gap longer than ``max_gap`` split into ``ceil(gap / max_gap)`` equal parts.  ``[]``
    for a clip of fewer than 2 frames."""
    f = len(positions)
    if f < 2:
        return []
    speed = mean_joint_speed(positions)
    t = np.arange(1, f - 1)
    eps = 1e-9 * float(speed.max())  # a plateau's rounding noise is no turning point
    minima = t[(speed[t] <= speed[t - 1]) & (speed[t] + eps < speed[t + 1])]
    keys = [0, f - 1]
    for m in minima[np.argsort(speed[minima], kind="stable")]:
        if min(abs(int(m) - k) for k in keys) >= min_gap:
            keys.append(int(m))
    keys.sort()
    out = [keys[0]]
    for b in keys[1:]:
        a = out[-1]
        parts = -(-(b - a) // max_gap)
        out += [a + round(i * (b - a) / parts) for i in range(1, parts)] + [b]
    return out


@dataclass(frozen=True)
class KeyposeSchedule:
    """A named schedule: ``keys(num_frames, rng, positions) -> keys`` (``[]``: the clip is too short for it);
    ``needs_positions``: it reads the clip's global positions ``(F, J, 3)`` (else ``positions`` may be ``None``)."""

    keys: Callable[[int, np.random.Generator, np.ndarray | None], list[int]]
    needs_positions: bool = False


SCHEDULES: dict[str, KeyposeSchedule] = {
    "random": KeyposeSchedule(lambda num_frames, rng, positions: random_keyframes(num_frames, rng)),
    "extremes": KeyposeSchedule(lambda num_frames, rng, positions: extreme_keyframes(positions), needs_positions=True),
}


def partial_interval(schedule) -> int | None:
    """``K`` of a ``partial<K>`` schedule (``K >= 4``: room for a partial key and frames to fill on each side);
    ``None`` for any other schedule."""
    if isinstance(schedule, str) and schedule.startswith(PARTIAL) and schedule[len(PARTIAL):].isdigit():
        k = int(schedule[len(PARTIAL):])
        return k if k >= 4 else None
    return None


def check_schedule(schedule) -> None:
    """ValueError (a message a config check puts its key in front of) unless ``schedule`` is an interval
    ``K >= MIN_INTERVAL``, a name of :data:`SCHEDULES` or ``partial<K>`` (``K >= 4``)."""
    if isinstance(schedule, str) and (schedule in SCHEDULES or partial_interval(schedule)):
        return
    if isinstance(schedule, bool) or not isinstance(schedule, int) or schedule < MIN_INTERVAL:
        raise ValueError(f"intervals must be integers >= {MIN_INTERVAL} (a keyframe every K frames), one of "
                         f"{list(SCHEDULES)} or partial<K> (K >= 4: partial keys), got {schedule!r}")


def needs_positions(schedule) -> bool:
    """Whether ``schedule`` places its keys from the clip's global positions (:func:`schedule_keyframes`)."""
    return isinstance(schedule, str) and schedule in SCHEDULES and SCHEDULES[schedule].needs_positions


def schedule_keyframes(schedule, num_frames: int, rng: np.random.Generator,
                       positions: np.ndarray | None = None) -> list[int]:
    """The keys of one clip of ``num_frames`` frames under ``schedule``: an int ``K`` (:func:`keyframe_indices`) or a
    name of :data:`SCHEDULES` (``positions (F, J, 3)``: the clip's global positions, for those that need them).
    ``[]``: the clip is too short for the schedule."""
    if not isinstance(schedule, str):
        return keyframe_indices(num_frames, int(schedule))
    if schedule not in SCHEDULES:
        raise ValueError(f"unknown keyframe schedule {schedule!r}; choose an interval K >= {MIN_INTERVAL} or one of "
                         f"{list(SCHEDULES)}")
    entry = SCHEDULES[schedule]
    if entry.needs_positions and (positions is None or len(positions) != num_frames):
        raise ValueError(f"the {schedule} schedule needs the clip's global positions (F, J, 3)")
    return entry.keys(num_frames, rng, positions)
