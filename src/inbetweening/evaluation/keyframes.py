"""The keyframes-only protocol: whole test clips, a keyframe every ``K`` frames and nothing else.

What an animator gives the tool.  For each interval ``K`` (default 5, 15, 30, 45) and each test clip of at least
``K + 1`` frames, the keyframes are frames ``0, K, 2K, ..., mK`` (the clip is truncated to the last keyframe, so
its last frame is a key).  Animators do not key on a grid, so two keypose schedules are scored the same way
(:func:`schedule_keyframes`):

* ``random``: gaps drawn uniformly in ``3..45`` frames from frame 0 (seeded per clip by the run's seed and the
  clip's position), the clip truncated to the last key;
* ``extremes``: keys at the motion's extremes - frame 0, the last frame, and the local minima of the mean joint
  speed (the poses where the motion turns), taken lowest speed first at least 8 frames from every key already
  chosen; a gap longer than 45 frames is then split into equal parts (breakdown keys).

Every other frame is generated from the keyframes alone (no context frames), by the
animator path (:meth:`inbetweening.tools.inbetweener.Inbetweener.fill_arrays`) for a model, and by root lerp +
per-joint slerp (:func:`inbetweening.geometry.interp.interpolate_keyframes`) for the interpolation baseline.
Unknown frames are NaN when handed to a fill function, so nothing can read the ground truth.

Scores, on the generated (non-key) frames, pooled over all clips:

* **Position error**: mean over generated frames and joints of the Euclidean distance between predicted and
  true global joint positions (FK by :meth:`~inbetweening.geometry.skeleton.Skeleton.pose`), in the dataset's
  length unit (cm for LAFAN1, Bandai-Namco and the synthetic data); ``ratio`` = model / interpolation.
* **Foot skating**: for each consecutive frame pair ``(t, t+1)`` touching a generated frame and each foot joint
  (the dataset's :class:`~inbetweening.data.contacts.FootContact`), the joint is *in contact* when, in the ground
  truth, its height (Y up, the pair's mean)
  is below ``contact_height`` AND its speed ``|p[t+1] - p[t]| * fps`` is below ``contact_speed``.  A motion's
  skating is the mean horizontal (XZ) speed ``|(p[t+1] - p[t])_xz| * fps`` of its own foot joints over those
  in-contact (pair, joint) entries, in length units per second (cm/s): how fast the generated foot moves where
  the real foot is planted (for the ground truth itself: its residual slide).  No contact at all: 0.
  The contacts are the ground truth's, not each motion's own: with its own contacts a motion whose feet slide
  faster than ``contact_speed`` would have no contact there and score *less* skating (on Bandai-Namco-2 with a key
  every 30 frames, interpolation scored 0.15 cm/s that way against 1.48 cm/s for the ground truth).

Shapes: a clip ``root (F, 3)``, ``local_q (F, J, 4)``; global positions ``(F, J, 3)``.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from inbetweening.data.contacts import FootContact, foot_contacts
from inbetweening.geometry.interp import interpolate_keyframes
from inbetweening.geometry.skeleton import Skeleton

KEYFRAME_INTERVALS = (5, 15, 30, 45)
SCHEDULES = ("random", "extremes")  # keypose schedules scored besides "a key every K" (module docstring)
RANDOM_GAPS = (3, 45)  # random: gaps drawn uniformly in this range (frames)
EXTREME_MIN_GAP, EXTREME_MAX_GAP = 8, 45  # extremes: minima at least this far apart; longer gaps split
UP = 1  # Y up
HORIZONTAL = (0, 2)  # X and Z

# fill(root (F, 3), local_q (F, J, 4) with NaN in unknown frames, keyframes) -> (root (F, 3), local_q (F, J, 4))
Fill = Callable[[np.ndarray, np.ndarray, list[int]], tuple[np.ndarray, np.ndarray]]

# the figures of one interval, in the order they are printed
COLUMNS = ("model_cm", "interp_cm", "ratio", "skate_model", "skate_interp", "skate_gt")


# ------------------------------------------------------------------------------------------
# Pure scoring functions
# ------------------------------------------------------------------------------------------
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


def schedule_keyframes(schedule, num_frames: int, rng: np.random.Generator,
                       positions: np.ndarray | None = None) -> list[int]:
    """The keys of one clip of ``num_frames`` frames under ``schedule``: an int ``K`` (:func:`keyframe_indices`),
    ``"random"`` (:func:`random_keyframes`) or ``"extremes"`` (:func:`extreme_keyframes` of the clip's global
    ``positions (F, J, 3)``).  ``[]``: the clip is too short for the schedule."""
    if schedule == "random":
        return random_keyframes(num_frames, rng)
    if schedule == "extremes":
        if positions is None or len(positions) != num_frames:
            raise ValueError("the extremes schedule needs the clip's global positions (F, J, 3)")
        return extreme_keyframes(positions)
    if isinstance(schedule, str):
        raise ValueError(f"unknown keyframe schedule {schedule!r}; choose an interval K >= 2 or one of {list(SCHEDULES)}")
    return keyframe_indices(num_frames, int(schedule))


def generated_frames(num_frames: int, keys: Sequence[int]) -> np.ndarray:
    """``(F,)`` bool: True for the frames that are not keyframes."""
    gen = np.ones(num_frames, dtype=bool)
    gen[list(keys)] = False
    return gen


def position_error(pred_gp: np.ndarray, gt_gp: np.ndarray, frames: np.ndarray) -> tuple[float, int]:
    """Sum and count of per-joint position errors over the selected frames.

    ``pred_gp, gt_gp (F, J, 3)`` global positions, ``frames (F,)`` bool -> ``(sum of |pred - gt| over selected
    frames and all joints, number of (frame, joint) entries)``; the mean is ``sum / count``.
    """
    d = np.linalg.norm(pred_gp[frames] - gt_gp[frames], axis=-1)
    return float(d.sum()), int(d.size)


def horizontal_speed(feet_gp: np.ndarray, fps: float) -> np.ndarray:
    """Horizontal (XZ) speed per frame pair.  ``(F, K, 3) -> (F-1, K)``, length units per second."""
    step = np.diff(feet_gp, axis=0)[..., list(HORIZONTAL)]
    return np.linalg.norm(step, axis=-1) * fps


def foot_skate(feet_gp: np.ndarray, contact: np.ndarray, fps: float) -> tuple[float, int]:
    """Sum and count of the horizontal speeds of foot joints over the in-contact entries.

    ``feet_gp (F, K, 3)`` global positions of the foot joints, ``contact (F-1, K)`` bool (the ground truth's
    :func:`foot_contacts`, restricted to the scored pairs) -> ``(sum of horizontal speeds over the contact
    entries, their number)``; the mean skate is ``sum / count``.
    """
    return float(horizontal_speed(feet_gp, fps)[contact].sum()), int(contact.sum())


def scored_pairs(generated: np.ndarray) -> np.ndarray:
    """``(F,)`` bool generated frames -> ``(F-1,)`` bool: the frame pairs ``(t, t+1)`` touching a generated frame."""
    return generated[:-1] | generated[1:]


# ------------------------------------------------------------------------------------------
# Accumulation over clips
# ------------------------------------------------------------------------------------------
@dataclass
class FootSpec:
    """The foot joints (indices into the skeleton) and the contact thresholds of a dataset."""

    joints: tuple[int, ...]
    contact_height: float
    contact_speed: float


def foot_spec(skeleton: Skeleton, contact: FootContact) -> FootSpec | None:
    """The :class:`FootSpec` of a dataset's feet and contact rule (``MotionData.contact``) on ``skeleton``; ``None``
    when it names no feet.  ``DatasetError`` when a foot joint is not in the skeleton."""
    if not contact.feet:
        return None
    return FootSpec(contact.indices(skeleton.names, "foot contact"), contact.height, contact.speed)


def hold_keyframes(root: np.ndarray, local_q: np.ndarray, keys: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """The zero-velocity baseline on keyframes: every frame repeats the keyframe before it.
    ``root (F, 3), local_q (F, J, 4)`` (unknown frames never read) -> new float64 arrays."""
    idx = np.asarray(keys)[np.searchsorted(keys, np.arange(len(root)), side="right") - 1]
    return np.array(root, np.float64)[idx], np.array(local_q, np.float64)[idx]


@dataclass
class _Totals:
    """Running sums of one interval (means are ``sum / count``)."""

    err: dict
    skate: dict
    clips: int = 0
    frames: int = 0

    @classmethod
    def empty(cls) -> _Totals:
        return cls({k: [0.0, 0] for k in ("model", "interp")}, {k: [0.0, 0] for k in ("model", "interp", "gt")})

    def add(self, table: dict, key: str, value: tuple[float, int]) -> None:
        table[key][0] += value[0]
        table[key][1] += value[1]

    gaps: int = 0  # number of gaps between consecutive keys

    def summary(self, with_skate: bool) -> dict:
        """The interval's figures (:data:`COLUMNS`, skating only ``with_skate``) plus ``n_clips``/``n_frames`` and
        ``mean_gap`` (frames from one key to the next, on average)."""
        model, interp = (self.err[k][0] / max(self.err[k][1], 1) for k in ("model", "interp"))
        out = {"model_cm": model, "interp_cm": interp, "ratio": model / interp if interp > 0 else float("nan")}
        if with_skate:  # no contact at all: nothing to skate on
            out.update({f"skate_{k}": (s / c if c else 0.0) for k, (s, c) in self.skate.items()})
        mean_gap = (self.frames + self.gaps) / self.gaps if self.gaps else 0.0
        return {**out, "n_clips": self.clips, "n_frames": self.frames, "mean_gap": mean_gap}


def score_clip(totals: _Totals, skeleton: Skeleton, gt: tuple, pred: tuple, interp: tuple, keys: Sequence[int],
               fps: float, feet: FootSpec | None) -> None:
    """Add one filled clip to ``totals``.  ``gt``, ``pred``, ``interp``: ``(root (F, 3), local_q (F, J, 4))``."""
    gen = generated_frames(len(gt[0]), keys)
    pos = {k: skeleton.pose(np.asarray(r, np.float64), np.asarray(q, np.float64))[1]
           for k, (r, q) in (("gt", gt), ("model", pred), ("interp", interp))}
    for k in ("model", "interp"):
        totals.add(totals.err, k, position_error(pos[k], pos["gt"], gen))
    if feet is not None:
        j = list(feet.joints)
        contact = foot_contacts(pos["gt"][:, j], fps, feet.contact_height, feet.contact_speed)
        contact &= scored_pairs(gen)[:, None]
        for k, gp in pos.items():
            totals.add(totals.skate, k, foot_skate(gp[:, j], contact, fps))
    totals.clips += 1
    totals.frames += int(gen.sum())
    totals.gaps += len(keys) - 1


def evaluate_clips(clips: Sequence, skeleton: Skeleton, fill: Fill | None, intervals: Sequence, fps: float,
                   feet: FootSpec | None = None, progress: Callable[[str], None] | None = None,
                   seed: int = 0) -> dict[str, dict]:
    """Run the protocol (module docstring) over ``clips`` (objects with ``root_pos (F, 3)``, ``local_q (F, J, 4)``).

    ``intervals``: schedules, each an interval ``K`` or one of :data:`SCHEDULES` (:func:`schedule_keyframes`;
    ``random`` draws from a generator seeded by ``seed`` and the clip's position).  ``fill`` generates the unknown
    frames (:data:`Fill`; ``None``: the model is the interpolation itself).  Returns ``{str(K): {"model_cm",
    "interp_cm", "ratio", "skate_model", "skate_interp", "skate_gt", "n_clips", "n_frames", "mean_gap"}}`` (no
    ``skate_*`` when ``feet`` is ``None``); schedules no clip is long enough for are left out.
    """
    out: dict[str, dict] = {}
    for k in intervals:
        totals = _Totals.empty()
        for i, clip in enumerate(clips):
            positions = None
            if k == "extremes":  # the ground truth's own motion decides where its extremes are
                positions = skeleton.pose(np.asarray(clip.root_pos, np.float64), np.asarray(clip.local_q, np.float64))[1]
            keys = schedule_keyframes(k, len(clip.root_pos), np.random.default_rng([int(seed), i]), positions)
            if not keys:
                continue
            n = keys[-1] + 1
            gt = (np.asarray(clip.root_pos[:n], np.float64), np.asarray(clip.local_q[:n], np.float64))
            gen = generated_frames(n, keys)
            root_in, q_in = gt[0].copy(), gt[1].copy()
            root_in[gen], q_in[gen] = np.nan, np.nan  # a fill that reads unknown frames fails loudly
            interp = interpolate_keyframes(root_in, q_in, keys)
            pred = interp if fill is None else fill(root_in, q_in, keys)
            if not (np.isfinite(pred[0]).all() and np.isfinite(pred[1]).all()):
                raise ValueError(f"keyframes protocol: the fill returned non-finite values (interval {k}, "
                                 f"clip {getattr(clip, 'name', '?')})")
            score_clip(totals, skeleton, gt, pred, interp, keys, fps, feet)
        if totals.clips:
            out[str(k)] = totals.summary(feet is not None)
        if progress is not None:
            progress(f"keyframes every {k}: {totals.clips} clips")
    return out


def format_table(results: dict[str, dict], unit: str = "cm") -> str:
    """Markdown table of :func:`evaluate_clips`'s results: one row per keyframe interval."""
    head = (f"| keyframe every | model ({unit}) | interpolation ({unit}) | ratio | skate model ({unit}/s) "
            f"| skate interpolation ({unit}/s) | skate ground truth ({unit}/s) | clips | generated frames |")
    lines = [head, "|---:|" + "---:|" * 8]
    for k, r in results.items():
        cells = [("" if r.get(c) is None else f"{r[c]:.3f}" if c == "ratio" else f"{r[c]:.2f}") for c in COLUMNS]
        lines.append(f"| {k} | " + " | ".join(cells) + f" | {r['n_clips']} | {r['n_frames']} |")
    return "\n".join(lines)
