"""Foot locking: where the model says a foot is planted, hold it still and bend the leg to reach it.

For each leg (a foot joint of the data's :class:`~inbetweening.data.contacts.FootContact` whose parent and
grandparent are the knee and the hip; the other foot joints of the leg, e.g. the toes, follow it), the frames where
the predicted contact of that joint is above one half form *contact runs*.  In a run the ankle is held at one
position: a keyframe's where the run holds one (so the locked foot meets the key exactly; between two keys of a run
it moves straight from one key's position to the other's), else the mean of the generated positions.  The leg is
solved with a two-bone IK (:func:`inbetweening.geometry.ik.two_bone_ik`) so the
ankle reaches it, the foot keeping its global rotation; over ``blend`` frames on each side of a run the target is
blended from the generated position to the locked one.  Keyframes and the root are never changed: only the hip,
knee and ankle rotations of generated frames.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from inbetweening.data.contacts import CONTACT_THRESHOLD, FootContact, planted_frames
from inbetweening.geometry.ik import two_bone_ik
from inbetweening.geometry.skeleton import Skeleton

__all__ = ["BLEND_FRAMES", "key_contacts", "legs", "lock_feet"]

BLEND_FRAMES = 4  # frames over which a lock is blended in and out


def legs(skeleton: Skeleton, feet: Sequence[int]) -> list[tuple[int, int, int]]:
    """The ``(hip, knee, ankle)`` chains of the foot joints: per leg the foot joint nearest the root (a foot joint
    below another one, e.g. the toes under the ankle, belongs to its leg), with its parent and grandparent; a foot
    whose chain reaches the root is skipped."""
    parents = skeleton.parents

    def ancestors(j):
        out = []
        while parents[j] >= 0:
            j = parents[j]
            out.append(j)
        return out

    chains = []
    for f in sorted(feet, key=lambda j: len(ancestors(j))):
        if any(a in ancestors(f) for _, _, a in chains):
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


def lock_feet(skeleton: Skeleton, root: np.ndarray, local_q: np.ndarray, known_frames: Sequence[int],
              contact: np.ndarray, feet: Sequence[int], blend: int = BLEND_FRAMES) -> np.ndarray:
    """``local_q (F, J, 4)`` with the feet locked (module docstring); ``root (F, 3)``, ``contact (F, J)`` (predicted
    contact in [0, 1]; keyframes: their own), ``feet``: foot joint indices.  Returns a new array; the keyframes' rows
    are the input's."""
    q = np.array(local_q, dtype=np.float64)
    n = len(root)
    generated = np.ones(n, dtype=bool)
    generated[list(known_frames)] = False
    keys = np.flatnonzero(~generated)
    for hip, knee, ankle in legs(skeleton, feet):
        planted = np.nan_to_num(contact[:, ankle], nan=0.0) > CONTACT_THRESHOLD
        gq, gp = skeleton.pose(root, q)
        target = np.full((n, 3), np.nan)
        weight = np.zeros(n)
        for s, e in _runs(planted):
            if not generated[s:e].any():
                continue
            inside = keys[(keys >= s) & (keys < e)]
            if len(inside):  # through the keys' own positions (held before the first and after the last)
                frames = np.arange(s, e)
                hold = np.stack([np.interp(frames, inside, gp[inside, ankle, i]) for i in range(3)], axis=-1)
            else:
                hold = np.broadcast_to(gp[s:e, ankle].mean(axis=0), (e - s, 3))
            target[s:e], weight[s:e] = hold, 1.0
            for d in range(1, blend + 1):
                w = 1.0 - d / (blend + 1)
                for t, h in ((s - d, hold[0]), (e - 1 + d, hold[-1])):
                    if 0 <= t < n and not planted[t] and w > weight[t]:
                        target[t], weight[t] = h, w
        frames = np.flatnonzero(generated & (weight > 0))
        if len(frames) == 0:
            continue
        goal = gp[frames, ankle] + weight[frames, None] * (target[frames] - gp[frames, ankle])
        parent = skeleton.parents[hip]
        h, k, a = two_bone_ik(gp[frames, hip], gp[frames, knee], gp[frames, ankle], goal, gq[frames, hip],
                              gq[frames, knee], gq[frames, ankle], gq[frames, parent])
        q[frames, hip], q[frames, knee], q[frames, ankle] = h, k, a
    q[keys] = local_q[keys]
    return q


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
