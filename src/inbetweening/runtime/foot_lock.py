"""Foot locking: where a foot is planted, hold it still and bend the leg to reach it.

Where the foot is planted, gap by gap between two keys (:func:`gap_contacts`): the model's contact channels where it
has them, else the data's contact rule on the fill itself (the foot low and slow, or as low as it stands at the keys).
The feet and the rule are the model's data's; a model that recorded none (trained before they were) gets them from its
skeleton and the keys (:func:`contact_rule`: the feet by name or as the lowest limbs' ends, the built-in rule scaled to
the keys' body height).

The runtime locks each gap as soon as it is generated, between its two keys, so the next gap's context holds planted
feet and a re-fill of some gaps locks them as a fill of every gap does.  For each leg (a foot joint of the data's
:class:`~inbetweening.data.contacts.FootContact` whose parent and grandparent are the knee and the hip) and each of
its foot joints (the ankle and those below it, e.g. the toes), the frames where that joint's contact is above one half
form *contact runs*.  In a run the joint is held at one position: a keyframe's where the run holds one (so the locked
foot meets the key exactly; between two keys of a run it moves straight from one key's position to the other's), else
the mean of the generated positions; over ``blend`` frames on each side of a run the target is blended from the
generated position to the held one.

* The leg is solved with a two-bone IK (:func:`inbetweening.geometry.ik.two_bone_ik`) so the ankle reaches its target,
  the foot keeping its global rotation.
* Where a toe is held more than its ankle (the heel up), the rest of the ankle's target is where the generated foot,
  moved so its toe sits at the toe's hold, puts the ankle; then, wherever a toe is held, the foot is turned about the
  ankle to point the toe at its hold.  Without this the feet turned on their held toes and slid them 4-5 cm/s on
  Bandai-Namco-2 (RESULTS.md section 5.3).  A toe run is held only where that carried ankle stays within
  ``planted_reach`` leg lengths of the generated hip (beyond, on motions the model never saw, the wrongly held toes
  cost joint error), and only in gaps of ``short_gap`` frames or longer (in shorter ones it cost the standard
  split and the held-out walks joint error).
* Optionally (``move_root``), where a locked ankle is out of the leg's reach from the generated hip, the root of that
  frame is moved by the shortfall (the legs' mean, smoothed over ``blend`` frames either side) before the legs are
  solved.

Keyframes are never changed: only the hip, knee and ankle rotations (and with ``move_root`` the root) of generated
frames.

Short gaps (under ``short_gap`` frames) of a model with contact channels take the contact the keys say
(:func:`gap_contacts`) instead of the prediction: with keys every 5 frames the predicted contact raised the joint
error of the shipped contact model by 3 % (RESULTS.md section 5.3).  In longer gaps the prediction is distrusted where
it is implausible: a predicted contact run whose held foot would be out of the leg's reach from the generated hip
(``planted_reach``) takes the rule's contact instead (a model that does not know the motion plants feet the body
walks away from; the locking then drags the leg, RESULTS.md section 5.3).  A gap the self-check gave back to
interpolation takes the keys' contact alone, for every model (``trusted_share``, RESULTS.md section 5.3).

The numbers named ``like_this`` are :class:`~inbetweening.runtime.settings.FillSettings` fields (``settings``).
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from inbetweening.data.contacts import (
    CONTACT_THRESHOLD,
    FootContact,
    body_height,
    find_feet,
    planted_frames,
    scaled_contact,
)
from inbetweening.data.errors import DatasetError
from inbetweening.geometry.ik import two_bone_ik
from inbetweening.geometry.quaternion import qinv, qmul, qswing
from inbetweening.geometry.skeleton import Skeleton

from .settings import DEFAULT_SETTINGS, FillSettings

__all__ = ["ClipFeet", "clip_feet", "contact_rule", "gap_contacts", "key_contacts", "legs",
           "lock_feet", "lock_gap", "plausible_contacts"]



def _ancestors(parents: Sequence[int], j: int) -> list[int]:
    out = []
    while parents[j] >= 0:
        j = parents[j]
        out.append(j)
    return out


def legs(skeleton: Skeleton, feet: Sequence[int]) -> list[tuple[int, int, int]]:
    """The ``(hip, knee, ankle)`` chains of the foot joints: per leg the foot joint nearest the root (a foot joint
    below another one, e.g. the toes under the ankle, belongs to its leg), with its parent and grandparent; a foot
    whose chain reaches the root is skipped."""
    parents = skeleton.parents
    chains = []
    for f in sorted(feet, key=lambda j: len(_ancestors(parents, j))):
        if any(a in _ancestors(parents, f) for _, _, a in chains):
            continue  # a toe under an ankle already chosen
        knee = parents[f]
        if knee <= 0 or parents[knee] <= 0:
            continue  # the hip must sit below the root (the root is never changed)
        chains.append((parents[knee], knee, f))
    return chains


def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    """``[(start, stop), ...]`` of the True runs of a 1-D bool array (stop exclusive)."""
    edges = np.diff(np.concatenate([[0], flags.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))


def _reach_shift(skeleton: Skeleton, gp: np.ndarray, plans: list, n: int, blend: int) -> np.ndarray:
    """``(F, 3)``: how far to move the root so that each locked ankle is within its leg's reach from the hip."""
    total, count = np.zeros((n, 3)), np.zeros(n)
    for hip, knee, ankle, frames, goal in plans:
        reach = 0.999 * (np.linalg.norm(skeleton.offsets[knee]) + np.linalg.norm(skeleton.offsets[ankle]))
        d = goal - gp[frames, hip]
        length = np.linalg.norm(d, axis=-1)
        out = length > reach
        total[frames[out]] += ((length[out] - reach) / length[out])[:, None] * d[out]
        count[frames[out]] += 1
    shift = total / np.maximum(count, 1)[:, None]
    if not count.any():
        return shift
    size = np.linalg.norm(shift, axis=-1)  # each frame takes the largest shift within `blend` frames, then smoothed
    at = np.clip(np.arange(n)[None] + np.arange(-blend, blend + 1)[:, None], 0, n - 1)  # (2 blend + 1, F)
    wide = shift[at[np.argmax(size[at], axis=0), np.arange(n)]]
    kernel = np.ones(2 * blend + 1) / (2 * blend + 1)
    return np.stack([np.convolve(wide[:, i], kernel, mode="same") for i in range(3)], axis=-1)


def _hold(planted: np.ndarray, pos: np.ndarray, generated: np.ndarray, keys: np.ndarray, go_on: tuple[bool, bool],
          blend: int, keep: Callable[[int, int, np.ndarray], bool] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(target (F, 3), weight (F,))`` of one foot joint planted at ``planted (F,)``, at ``pos (F, 3)``: in each run
    (one with a generated frame, or going on beyond the span, ``go_on``) the keys' positions where it holds keys (held
    before the first and after the last), else the run's mean, weight 1; blended out over ``blend`` frames each side.
    ``keep(start, stop, hold)``: whether to hold a run at ``hold (stop - start, 3)`` (default: every run)."""
    n = len(planted)
    planted = planted.copy()
    holds = []
    for s, e in _runs(planted):
        if not generated[s:e].any() and not ((s == 0 and go_on[0]) or (e == n and go_on[1])):
            continue
        inside = keys[(keys >= s) & (keys < e)]
        if len(inside):
            frames = np.arange(s, e)
            hold = np.stack([np.interp(frames, inside, pos[inside, i]) for i in range(3)], axis=-1)
        else:
            hold = np.broadcast_to(pos[s:e].mean(axis=0), (e - s, 3))
        if keep is None or keep(s, e, hold):
            holds.append((s, e, hold))
        else:
            planted[s:e] = False
    target, weight = np.full((n, 3), np.nan), np.zeros(n)
    for s, e, hold in holds:
        target[s:e], weight[s:e] = hold, 1.0
        for d in range(1, blend + 1):
            w = 1.0 - d / (blend + 1)
            for t, h in ((s - d, hold[0]), (e - 1 + d, hold[-1])):
                if 0 <= t < n and not planted[t] and w > weight[t]:
                    target[t], weight[t] = h, w
    return target, weight


def _planted(contact: np.ndarray, j: int) -> np.ndarray:
    return np.nan_to_num(contact[:, j], nan=0.0) > CONTACT_THRESHOLD


def _carried_within(gp: np.ndarray, hip: int, ankle: int, toe: int, reach: float) -> Callable:
    """``keep`` of :func:`_hold` for a toe: a run is held where the generated foot, carried so that the toe sits at its
    hold, keeps its ankle within ``reach`` of the generated hip (``gp (F, J, 3)``) at every frame."""
    def keep(s: int, e: int, at: np.ndarray) -> bool:
        ankle_at = gp[s:e, ankle] + at - gp[s:e, toe]
        return bool(np.linalg.norm(ankle_at - gp[s:e, hip], axis=-1).max() <= reach)
    return keep


def _pull(pos: np.ndarray, target: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """``weight`` of the way from ``pos (F, 3)`` to ``target (F, 3)`` (``target`` may be NaN where the weight is 0)."""
    return weight[:, None] * (np.nan_to_num(target) - pos)


def lock_feet(skeleton: Skeleton, root: np.ndarray, local_q: np.ndarray, known_frames: Sequence[int],
              contact: np.ndarray, feet: Sequence[int], move_root: bool = False, ends: np.ndarray | None = None,
              toes: bool = True, settings: FillSettings = DEFAULT_SETTINGS) -> tuple[np.ndarray, np.ndarray]:
    """``(root (F, 3), local_q (F, J, 4))`` with the feet locked (module docstring); ``contact (F, J)`` (contact in
    [0, 1]; keyframes: their own), ``feet``: foot joint indices; ``move_root``: move the root where a locked ankle is
    out of reach (off by default: on Bandai-Namco-2 it raised the joint error at every schedule and did not lower the
    skating, RESULTS.md appendix); ``toes``: hold the planted foot joints below the ankles too (off: the ankles
    alone, the foot keeping its global rotation); ``settings``: ``blend_frames``, ``planted_reach``.  Returns new
    arrays; the keyframes' rows are the input's."""
    blend = settings.blend_frames
    q = np.array(local_q, dtype=np.float64)
    root_out = np.array(root, dtype=np.float64)
    n = len(root)
    go_on = np.zeros((2, q.shape[1]), dtype=bool) if ends is None else np.asarray(ends, dtype=bool)
    generated = np.ones(n, dtype=bool)
    generated[list(known_frames)] = False
    keys = np.flatnonzero(~generated)
    gq, gp = skeleton.pose(root_out, q)
    parents = skeleton.parents
    plans, aims = [], []
    for hip, knee, ankle in legs(skeleton, feet):
        reach = settings.planted_reach * (np.linalg.norm(skeleton.offsets[knee]) + np.linalg.norm(skeleton.offsets[ankle]))
        target, weight = _hold(_planted(contact, ankle), gp[:, ankle], generated, keys, go_on[:, ankle], blend)
        shift = _pull(gp[:, ankle], target, weight)
        below = [j for j in feet if ankle in _ancestors(parents, j)] if toes else []
        for toe in below:  # a held toe carries its foot
            t_target, t_weight = _hold(_planted(contact, toe), gp[:, toe], generated, keys, go_on[:, toe], blend,
                                       _carried_within(gp, hip, ankle, toe, reach))
            if not (t_weight[generated] > 0).any():
                continue
            toe_goal = gp[:, toe] + _pull(gp[:, toe], t_target, t_weight)
            shift += (1.0 - weight)[:, None] * (toe_goal - gp[:, toe])
            weight = np.maximum(weight, t_weight)
            frames = np.flatnonzero(generated & (t_weight > 0))
            aims.append((ankle, toe, frames, toe_goal[frames]))
        frames = np.flatnonzero(generated & (weight > 0))
        if len(frames):
            plans.append((hip, knee, ankle, frames, gp[frames, ankle] + shift[frames]))
    shift = _reach_shift(skeleton, gp, plans, n, blend) if move_root else np.zeros((n, 3))
    shift[~generated] = 0.0
    if np.abs(shift).max(initial=0.0) > 0:
        root_out += shift
        gq, gp = skeleton.pose(root_out, q)
    for hip, knee, ankle, frames, goal in plans:
        parent = parents[hip]
        h, k, a = two_bone_ik(gp[frames, hip], gp[frames, knee], gp[frames, ankle], goal, gq[frames, hip],
                              gq[frames, knee], gq[frames, ankle], gq[frames, parent])
        q[frames, hip], q[frames, knee], q[frames, ankle] = h, k, a
    for ankle, toe, frames, goal in aims:  # then each held toe: the foot turned about its ankle to point it there
        gq, gp = skeleton.pose(root_out, q)
        turn = qswing(gp[frames, toe] - gp[frames, ankle], goal - gp[frames, ankle])
        q[frames, ankle] = qmul(qinv(gq[frames, parents[ankle]]), qmul(turn, gq[frames, ankle]))
    q[keys] = local_q[keys]
    root_out[keys] = np.asarray(root)[keys]
    return root_out, q


def _clean_runs(flags: np.ndarray, min_run: int) -> np.ndarray:
    """``flags (F,)`` with holes shorter than ``min_run`` filled, then runs shorter than ``min_run`` dropped."""
    out = flags.copy()
    for s, e in _runs(~out):
        if e - s < min_run and s > 0 and e < len(out):
            out[s:e] = True
    for s, e in _runs(out):
        if e - s < min_run:
            out[s:e] = False
    return out


@dataclass
class ClipFeet:
    """What the keys of one clip say about its feet: the contact ``rule`` (:func:`contact_rule`) and its foot joints
    ``feet``, the keys' own contact ``at_keys (F, J)`` (:func:`key_contacts`), each foot's planted ``levels (J,)``
    (its median height at the keys where it is planted, plus ``planted_margin`` of the contact height; ``-inf``
    where it is planted at no key), ``held {(a, b): (J,) bool}``: per key gap, whether both keys have the foot
    planted within a quarter of the contact height of each other (the keys say it stayed down), ``key_pose {key:
    (root, local_q)}``: the keys as given (a locked foot meets them exactly), and ``ends {(a, b): (2, J) bool}``:
    whether a foot planted at key ``a`` (row 0) or ``b`` (row 1) stays planted beyond it, through the gap before ``a``
    or after ``b`` (:attr:`held` of that gap)."""

    rule: FootContact
    feet: list[int]
    at_keys: np.ndarray
    levels: np.ndarray
    held: dict
    key_pose: dict
    ends: dict


def clip_feet(contact: FootContact, skeleton: Skeleton, fps: float, root: np.ndarray, local_q: np.ndarray,
              known_frames: Sequence[int], settings: FillSettings = DEFAULT_SETTINGS) -> ClipFeet | None:
    """:class:`ClipFeet` from the keys alone, ``None`` when no feet can be found (:func:`contact_rule`)."""
    keys = sorted(known_frames)
    rule = contact_rule(contact, skeleton, root, local_q, keys)
    if not rule.feet:
        return None
    feet = list(rule.indices(skeleton.names, "the model's feet"))
    at_keys = key_contacts(skeleton, rule, fps, root, local_q, keys)
    gp = skeleton.pose(np.asarray(root, np.float64)[keys], np.asarray(local_q, np.float64)[keys])[1]
    levels = np.full(skeleton.num_joints, -np.inf)
    held = {g: np.zeros(skeleton.num_joints, dtype=bool) for g in zip(keys, keys[1:])}
    for j in feet:
        planted = at_keys[keys, j] > 0.5
        if planted.any():
            levels[j] = np.median(gp[planted, j, 1]) + settings.planted_margin * rule.height
        for i, g in enumerate(zip(keys, keys[1:])):
            near = np.linalg.norm(gp[i + 1, j] - gp[i, j]) < 0.25 * rule.height
            held[g][j] = bool(planted[i] and planted[i + 1] and near)
    key_pose = {k: (np.array(root[k], np.float64), np.array(local_q[k], np.float64)) for k in keys}
    gaps, none = list(held), np.zeros(skeleton.num_joints, dtype=bool)
    ends = {g: np.stack([held[gaps[i - 1]] if i > 0 else none, held[gaps[i + 1]] if i + 1 < len(gaps) else none])
            for i, g in enumerate(gaps)}
    return ClipFeet(rule, feet, at_keys, levels, held, key_pose, ends)


def lock_gap(skeleton: Skeleton, feet: ClipFeet, root: np.ndarray, local_q: np.ndarray, contact: np.ndarray, a: int,
             b: int, fixed: Sequence[int] = (), settings: FillSettings = DEFAULT_SETTINGS) -> tuple[np.ndarray, np.ndarray]:
    """Frames ``a + 1 .. b - 1`` of ``root (F, 3)``, ``local_q (F, J, 4)`` with the feet of the gap between keys ``a``
    and ``b`` locked on ``contact (F, J)`` (:func:`lock_feet`, between the keys as given, the toes held in gaps of
    ``settings.short_gap`` frames or longer; ``fixed``: frames inside the gap never moved, e.g. partial keys)."""
    r, q = np.array(root[a : b + 1], np.float64), np.array(local_q[a : b + 1], np.float64)
    (r[0], q[0]), (r[-1], q[-1]) = feet.key_pose[a], feet.key_pose[b]
    r, q = lock_feet(skeleton, r, q, [0, b - a] + [t - a for t in fixed], contact[a : b + 1], feet.feet,
                     ends=feet.ends[(a, b)], toes=b - a - 1 >= settings.short_gap, settings=settings)
    return r[1:-1], q[1:-1]


def gap_contacts(skeleton: Skeleton, feet: ClipFeet, fps: float, root: np.ndarray, local_q: np.ndarray, a: int,
                 b: int, predicted: np.ndarray | None = None, positions: np.ndarray | None = None,
                 share: float = 1.0, settings: FillSettings = DEFAULT_SETTINGS) -> np.ndarray:
    """Foot contact ``(b - a - 1, J)`` of the gap between keys ``a`` and ``b``, judged on frames ``a .. b`` (``positions
    (b - a + 1, J, 3)``: their joints' global positions where the caller has them) and what the
    keys say alone (so a re-fill of some gaps finds in a gap what a fill of every gap finds there): ``predicted``, the
    model's contact channels there, where it has them and the gap is ``short_gap`` frames or longer, but the rule
    below where they are implausible (:func:`plausible_contacts`); else, 1/0 on the feet and 0 elsewhere:

    * a gap whose two keys both have the foot planted within a quarter of the contact height of each other holds it
      planted throughout (the keys say the foot did not leave the ground between them);
    * elsewhere the data's rule on the filled motion itself (:func:`~inbetweening.data.contacts.planted_frames`), runs
      and holes shorter than ``min_run`` frames cleaned;
    * in gaps of ``short_gap`` to ``planted_max_gap`` - 1 frames, also where the filled foot is as low as it
      stands at the keys (below its planted level) and slower than ``planted_speed`` times the contact speed.  A
      fill slides where the real foot is planted, so the speed rule alone misses most of those frames (RESULTS.md
      section 5.3); in shorter gaps it cost joint error, in longer ones it held feet that had left.

    A gap the self-check gave back to interpolation (``share``, the network's share of it, under
    ``trusted_share``) takes only what its keys say (the first rule): its fill is mostly interpolation, whose feet
    are low and slow where the real ones swing, and its predicted contacts are the network's that the check
    distrusted; on motions never seen both planted feet that were moving (RESULTS.md section 5.3).  The numbers
    ``like_this`` are ``settings``' (:class:`~inbetweening.runtime.settings.FillSettings`)."""
    s = settings
    n = b - a - 1
    out = np.zeros((n, skeleton.num_joints))
    if n < 1:
        return out
    if share < s.trusted_share:
        out[:, feet.feet] = feet.held[(a, b)][feet.feet]
        return out
    rule = feet.rule
    gp = positions if positions is not None else skeleton.pose(np.asarray(root[a : b + 1], np.float64),
                                                               np.asarray(local_q[a : b + 1], np.float64))[1]
    for j in feet.feet:
        seg = gp[:, j : j + 1]
        f = planted_frames(seg, fps, rule.height, rule.speed)[:, 0]
        if s.short_gap <= n < s.planted_max_gap:
            loose = planted_frames(seg, fps, rule.height, rule.speed * s.planted_speed)[:, 0]
            f |= loose & (seg[:, 0, 1] < feet.levels[j])
        f = _clean_runs(f, s.min_run)
        if feet.held[(a, b)][j]:
            f[:] = True
        out[:, j] = f[1:-1]
    if predicted is not None and n >= s.short_gap:
        return plausible_contacts(skeleton, feet.feet, gp[1:-1], predicted, out, s)
    return out


def plausible_contacts(skeleton: Skeleton, feet: Sequence[int], positions: np.ndarray, predicted: np.ndarray,
                       fallback: np.ndarray, settings: FillSettings = DEFAULT_SETTINGS) -> np.ndarray:
    """``predicted (F, J)`` contact, but each run of a leg's ankle above :data:`~inbetweening.data.contacts.
    CONTACT_THRESHOLD` whose held position (the run's mean ankle position in ``positions (F, J, 3)``) is farther
    from the hip than ``settings.planted_reach`` times the leg's length at some frame of the run: there the leg's
    joints (the ankle and the foot joints below it) take ``fallback (F, J)`` instead."""
    out = np.array(predicted, np.float64)
    parents = skeleton.parents
    for hip, knee, ankle in legs(skeleton, feet):
        reach = np.linalg.norm(skeleton.offsets[knee]) + np.linalg.norm(skeleton.offsets[ankle])
        below = [j for j in feet if j == ankle or ankle in _ancestors(parents, j)]
        for s, e in _runs(out[:, ankle] > CONTACT_THRESHOLD):
            hold = positions[s:e, ankle].mean(axis=0)
            if np.linalg.norm(positions[s:e, hip] - hold, axis=-1).max() > settings.planted_reach * reach:
                out[s:e, below] = fallback[s:e, below]
    return out


def key_contacts(skeleton: Skeleton, contact: FootContact, fps: float, root: np.ndarray, local_q: np.ndarray,
                 known_frames: Sequence[int]) -> np.ndarray:
    """The keys' own foot contact ``(F, J)``: the data's rule (:func:`~inbetweening.data.contacts.planted_frames`) on
    the keyframes alone (a key's speed from its neighbouring key frame where there is one, else its height alone),
    1/0 on the feet, 0 on the other joints, NaN on the frames that are not keys."""
    keys = np.asarray(list(known_frames))
    root_k = np.full(np.shape(root), np.nan)
    q_k = np.full(np.shape(local_q), np.nan)
    root_k[keys], q_k[keys] = np.asarray(root)[keys], np.asarray(local_q)[keys]
    gp = skeleton.pose(root_k, q_k)[1]
    out = np.zeros(gp.shape[:-1])
    feet = list(contact.indices(skeleton.names, "the model's feet"))
    if feet:
        out[:, feet] = planted_frames(gp[:, feet], fps, contact.height, contact.speed)
    out[np.isnan(gp[..., 0])] = np.nan
    return out


def contact_rule(contact: FootContact, skeleton: Skeleton, root: np.ndarray, local_q: np.ndarray,
                 known_frames: Sequence[int]) -> FootContact:
    """``contact`` when it names feet; else the feet found on ``skeleton`` (:func:`~inbetweening.data.contacts.
    find_feet`, on the keys' median joint heights) with the built-in rule scaled to the keys' body height
    (:func:`~inbetweening.data.contacts.scaled_contact`); no feet (an empty rule) when none can be found."""
    if contact.feet:
        return contact
    keys = list(known_frames)
    gp = skeleton.pose(np.asarray(root, np.float64)[keys], np.asarray(local_q, np.float64)[keys])[1]
    try:
        feet, _ = find_feet(skeleton.names, skeleton.parents, np.median(gp[..., 1], axis=0))
    except DatasetError:
        return contact
    height = body_height([gp])
    return scaled_contact(feet, height) if feet and height > 0 else contact
