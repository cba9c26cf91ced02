"""The keyframes-only protocol: whole test clips, keys placed by a schedule and nothing else.

What an animator gives the tool.  For each schedule (:mod:`inbetweening.evaluation.schedules`: an interval ``K``,
a key every ``K`` frames - default 5, 15, 30, 45 - or a keypose schedule, ``random`` or ``extremes``) and each test
clip long enough for two of its keys, the clip is truncated to its last key (so its last frame is a key).

Every other frame is generated from the keyframes alone (no context frames), by the
fill runtime (:class:`inbetweening.runtime.FillRuntime`, what every front end fills with) for a model, and by root lerp +
per-joint slerp (:func:`inbetweening.geometry.interp.interpolate_keyframes`) for the interpolation baseline.
Unknown frames are NaN when handed to a fill function, so nothing can read the ground truth.

Scores, on the generated (non-key) frames, pooled over all clips, and per clip:

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
* **Per clip** (never only pooled: a pooled mean hides the clips a model makes worse): each clip's own ratio (its
  position error over interpolation's on its generated frames); ``worse_share`` = the share of clips whose ratio is
  above :data:`WORSE` (worse than interpolation by more than 5 %), ``worst`` = the :data:`N_WORST` highest, by name;
  ``clip_ratios`` = every clip's.

Shapes: a clip ``root (F, 3)``, ``local_q (F, J, 4)``; global positions ``(F, J, 3)``.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from inbetweening.data.contacts import FootContact, foot_contacts
from inbetweening.evaluation import partial_keys as PK
from inbetweening.evaluation.schedules import needs_positions, partial_interval, schedule_keyframes
from inbetweening.geometry.interp import interpolate_keyframes
from inbetweening.geometry.skeleton import Skeleton

UP = 1  # Y up
HORIZONTAL = (0, 2)  # X and Z

# fill(root (F, 3), local_q (F, J, 4) with NaN in unknown frames, keyframes[, partial={frame: (J,) bool}])
#   -> (root (F, 3), local_q (F, J, 4)); partial keys: schedule partial<K> (:mod:`.partial_keys`)
Fill = Callable[[np.ndarray, np.ndarray, list[int]], tuple[np.ndarray, np.ndarray]]

# the figures of one interval, in the order they are printed
COLUMNS = ("model_cm", "interp_cm", "ratio", "skate_model", "skate_interp", "skate_gt")
WORSE = 1.05  # a clip's ratio above this: worse than interpolation by more than 5 %
N_WORST = 3  # the worst clips named per schedule


# ------------------------------------------------------------------------------------------
# Pure scoring functions
# ------------------------------------------------------------------------------------------
def generated_frames(num_frames: int, keys: Sequence[int]) -> np.ndarray:
    """``(F,)`` bool: True for the frames that are not keyframes."""
    gen = np.ones(num_frames, dtype=bool)
    gen[list(keys)] = False
    return gen


def keyed_clip(root: np.ndarray, local_q: np.ndarray, keys: Sequence[int]):
    """A clip as the protocol hands it to a fill: truncated to its last key (``keys`` sorted), every other frame NaN so
    nothing can read the ground truth.  Returns ``(truth, given, generated)``: ``(root, local_q)`` of the truncated
    clip (float64), the same with the generated frames NaN, and those frames' mask (:func:`generated_frames`)."""
    n = keys[-1] + 1
    truth = (np.asarray(root[:n], np.float64), np.asarray(local_q[:n], np.float64))
    gen = generated_frames(n, keys)
    given = (truth[0].copy(), truth[1].copy())
    given[0][gen], given[1][gen] = np.nan, np.nan
    return truth, given, gen


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


def hold_keyframes(root: np.ndarray, local_q: np.ndarray, keys: Sequence[int],
                   partial: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The zero-velocity baseline on keyframes: every frame repeats the keyframe before it (a partial key's joints
    their own value there).  ``root (F, 3), local_q (F, J, 4)`` (unknown frames never read) -> new float64 arrays."""
    idx = np.asarray(keys)[np.searchsorted(keys, np.arange(len(root)), side="right") - 1]
    r, q = np.array(root, np.float64)[idx], np.array(local_q, np.float64)[idx]
    for t, mask in (partial or {}).items():
        q[t, mask] = local_q[t, mask]
        if mask[0]:
            r[t] = root[t]
    return r, q


@dataclass
class _Totals:
    """Running sums of one interval (means are ``sum / count``)."""

    err: dict
    skate: dict
    clips: int = 0
    frames: int = 0
    per_clip: dict = None  # clip name -> its ratio

    @classmethod
    def empty(cls) -> _Totals:
        return cls({k: [0.0, 0] for k in ("model", "interp")}, {k: [0.0, 0] for k in ("model", "interp", "gt")},
                   per_clip={})

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
        ratios = self.per_clip
        worst = sorted(ratios.items(), key=lambda kv: -kv[1])[:N_WORST]
        out.update(worse_share=(sum(r > WORSE for r in ratios.values()) / len(ratios)) if ratios else 0.0,
                   worst=", ".join(f"{n} {r:.2f}" for n, r in worst))
        return {**out, "n_clips": self.clips, "n_frames": self.frames, "mean_gap": mean_gap, "clip_ratios": ratios}


def score_clip(totals: _Totals, skeleton: Skeleton, gt: tuple, pred: tuple, interp: tuple, keys: Sequence[int],
               fps: float, feet: FootSpec | None, name: str = "") -> None:
    """Add one filled clip (called ``name``) to ``totals``.  ``gt``, ``pred``, ``interp``: ``(root (F, 3), local_q
    (F, J, 4))``."""
    gen = generated_frames(len(gt[0]), keys)
    pos = {k: skeleton.pose(np.asarray(r, np.float64), np.asarray(q, np.float64))[1]
           for k, (r, q) in (("gt", gt), ("model", pred), ("interp", interp))}
    errs = {k: position_error(pos[k], pos["gt"], gen) for k in ("model", "interp")}
    for k, e in errs.items():
        totals.add(totals.err, k, e)
    if errs["interp"][0] > 0:
        totals.per_clip[name or f"clip{totals.clips}"] = errs["model"][0] / errs["interp"][0]
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

    ``intervals``: schedules, each an interval ``K`` or a name of :data:`~inbetweening.evaluation.schedules.
    SCHEDULES` (:func:`~inbetweening.evaluation.schedules.schedule_keyframes`; ``random`` draws from a generator
    seeded by ``seed`` and the clip's position).  ``fill`` generates the unknown frames (:data:`Fill`; ``None``: the
    model is the interpolation itself).  Returns ``{str(K): {"model_cm", "interp_cm", "ratio", "skate_model",
    "skate_interp", "skate_gt", "n_clips", "n_frames", "mean_gap"}}`` (no ``skate_*`` when ``feet`` is ``None``);
    schedules no clip is long enough for are left out.
    """
    out: dict[str, dict] = {}
    for k in intervals:
        if partial_interval(k):
            row = evaluate_partial(clips, skeleton, fill, partial_interval(k))
            if row:
                out[str(k)] = row
            if progress is not None:
                progress(f"keyframes {k}: {row.get('n_clips', 0)} clips")
            continue
        totals = _Totals.empty()
        for i, clip in enumerate(clips):
            positions = None
            if needs_positions(k):  # the ground truth's own motion decides where the keys go (extremes)
                positions = skeleton.pose(np.asarray(clip.root_pos, np.float64), np.asarray(clip.local_q, np.float64))[1]
            keys = schedule_keyframes(k, len(clip.root_pos), np.random.default_rng([int(seed), i]), positions)
            if not keys:
                continue
            gt, (root_in, q_in), gen = keyed_clip(clip.root_pos, clip.local_q, keys)  # unknown frames NaN
            interp = interpolate_keyframes(root_in, q_in, keys)
            pred = interp if fill is None else fill(root_in, q_in, keys)
            if not (np.isfinite(pred[0]).all() and np.isfinite(pred[1]).all()):
                raise ValueError(f"keyframes protocol: the fill returned non-finite values (interval {k}, "
                                 f"clip {getattr(clip, 'name', '?')})")
            score_clip(totals, skeleton, gt, pred, interp, keys, fps, feet, getattr(clip, "name", f"clip{i}"))
        if totals.clips:
            out[str(k)] = totals.summary(feet is not None)
        if progress is not None:
            progress(f"keyframes every {k}: {totals.clips} clips")
    return out


def evaluate_partial(clips: Sequence, skeleton: Skeleton, fill: Fill | None, interval: int) -> dict:
    """The ``partial<K>`` schedule (:mod:`.partial_keys`) over ``clips``: ``{model_cm, interp_cm, ratio, frozen_cm,
    ratio_frozen, free_model_cm, free_interp_cm, free_frozen_cm, worse_share, worst, clip_ratios, n_clips,
    n_frames}`` (``{}`` when no clip is long enough)."""
    parts = PK.body_parts(skeleton)
    sums = {m: np.zeros(4) for m in ("model", "interp", "frozen")}
    ratios, frames = {}, 0
    for i, clip in enumerate(clips):
        keys, partial = PK.partial_schedule(len(clip.root_pos), interval, parts)
        if not keys:
            continue
        n = keys[-1] + 1
        gt = (np.asarray(clip.root_pos[:n], np.float64), np.asarray(clip.local_q[:n], np.float64))
        res = PK.score_partial_clip(skeleton, gt, keys, partial, fill)
        for m, v in res.items():
            sums[m] += v
        if res["interp"][0] > 0:
            ratios[getattr(clip, "name", f"clip{i}")] = res["model"][0] / res["interp"][0]
        frames += n - len(keys)
    if not ratios:
        return {}
    mean = {m: (v[0] / max(v[1], 1), v[2] / max(v[3], 1)) for m, v in sums.items()}
    worst = sorted(ratios.items(), key=lambda kv: -kv[1])[:N_WORST]
    return {"model_cm": mean["model"][0], "interp_cm": mean["interp"][0], "ratio": mean["model"][0] / mean["interp"][0],
            "frozen_cm": mean["frozen"][0], "ratio_frozen": mean["model"][0] / mean["frozen"][0],
            "free_model_cm": mean["model"][1], "free_interp_cm": mean["interp"][1],
            "free_frozen_cm": mean["frozen"][1],
            "worse_share": sum(r > WORSE for r in ratios.values()) / len(ratios),
            "worst": ", ".join(f"{n} {r:.2f}" for n, r in worst), "n_clips": len(ratios), "n_frames": frames,
            "clip_ratios": ratios}


def format_table(results: dict[str, dict], unit: str = "cm") -> str:
    """Markdown table of :func:`evaluate_clips`'s results: one row per keyframe interval."""
    head = (f"| keyframe every | model ({unit}) | interpolation ({unit}) | ratio | skate model ({unit}/s) "
            f"| skate interpolation ({unit}/s) | skate ground truth ({unit}/s) | clips | generated frames "
            f"| clips worse than interpolation by > 5 % | worst clips (ratio) |")
    lines = [head, "|---:|" + "---:|" * 10]
    partial = {k: r for k, r in results.items() if "frozen_cm" in r}
    for k, r in results.items():
        if k in partial:
            continue
        cells = [("" if r.get(c) is None else f"{r[c]:.3f}" if c == "ratio" else f"{r[c]:.2f}") for c in COLUMNS]
        lines.append(f"| {k} | " + " | ".join(cells) + f" | {r['n_clips']} | {r['n_frames']} "
                     f"| {100 * r.get('worse_share', 0.0):.1f} % | {r.get('worst', '')} |")
    if partial:
        lines += ["", f"| partial keys | model ({unit}) | interpolation ({unit}) | ratio | frozen ({unit}) | ratio to "
                  f"frozen | unkeyed joints: model / interpolation / frozen ({unit}) | clips | clips worse than "
                  "interpolation by > 5 % | worst clips (ratio) |", "|---:|" + "---:|" * 9]
        for k, r in partial.items():
            lines.append(f"| {k} | {r['model_cm']:.2f} | {r['interp_cm']:.2f} | {r['ratio']:.3f} | {r['frozen_cm']:.2f} "
                         f"| {r['ratio_frozen']:.3f} | {r['free_model_cm']:.2f} / {r['free_interp_cm']:.2f} / "
                         f"{r['free_frozen_cm']:.2f} | {r['n_clips']} | {100 * r['worse_share']:.1f} % | {r['worst']} |")
    return "\n".join(lines)
