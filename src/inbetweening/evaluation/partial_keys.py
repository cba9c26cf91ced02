"""Partial keys in the keyframes-only protocol (schedule ``partial<K>``, :mod:`.schedules`).

Whole keys every ``K`` frames (:func:`~.schedules.keyframe_indices`) and, halfway between each two, a key of one body
part only (:func:`body_parts`, taken in turn gap after gap): the animator keyed an arm, a leg, the upper body.  Three
fills of the same keys are scored on every frame that is not a whole key (the partial key's unkeyed joints included),
by global position error as in :mod:`.keyframes`:

* ``model``: the fill with the partial keys as partial constraints (``fill(root, q, keys, partial)``);
* ``interp``: each joint interpolated between its own keys (:func:`~inbetweening.geometry.interp.interpolate_known`:
  the unkeyed joints between the whole keys, the keyed ones through the partial key);
* ``frozen``: what treating a partial key as a whole key gives: the frame's unkeyed joints frozen at their curve's
  value there (the interpolation between the whole keys), then the model fills with every key whole.

``free_*``: the same errors on the partial keys' unkeyed joints at those frames only (what the constraint leaves to
the fill).  ``ratio`` = model / interp, ``ratio_frozen`` = model / frozen; per clip as in :mod:`.keyframes`.
"""
from __future__ import annotations

import numpy as np

from inbetweening.geometry.interp import interpolate_keyframes, interpolate_known
from inbetweening.geometry.skeleton import Skeleton

from .schedules import keyframe_indices

__all__ = ["body_parts", "partial_schedule", "score_partial_clip"]


def body_parts(skeleton: Skeleton) -> list[tuple[str, np.ndarray]]:
    """The body parts a partial key holds: for each joint whose parent branches (has two or more children: the hips
    into spine and legs, the chest into neck and arms), ``(its name, (J,) bool)`` marking it and every joint below."""
    parents = list(skeleton.parents)
    j = len(parents)
    children = [sum(1 for p in parents if p == i) for i in range(j)]
    below = np.eye(j, dtype=bool)
    for c in range(j - 1, 0, -1):
        if parents[c] >= 0:
            below[parents[c]] |= below[c]
    return [(skeleton.names[i], below[i]) for i in range(1, j) if parents[i] >= 0 and children[parents[i]] >= 2]


def partial_schedule(num_frames: int, interval: int, parts) -> tuple[list[int], dict[int, np.ndarray]]:
    """Whole keys every ``interval`` frames and ``{frame: joints}``: a partial key halfway between each two, the body
    part of gap ``g`` being ``parts[g % len(parts)]`` (the masks of :func:`body_parts`); ``([], {})`` for a clip too
    short for two whole keys."""
    keys = keyframe_indices(num_frames, interval)
    partial = {a + interval // 2: parts[g % len(parts)][1] for g, a in enumerate(keys[:-1])}
    return keys, partial


def frozen_keys(root: np.ndarray, q: np.ndarray, keys: list[int], partial: dict) -> tuple[np.ndarray, np.ndarray]:
    """The clip with every partial key made whole: its unkeyed joints (and the root, unless joint 0 is keyed) at the
    interpolation between the whole keys."""
    ir, iq = interpolate_keyframes(root, q, keys)
    r, qq = root.copy(), q.copy()
    for t, mask in partial.items():
        qq[t, ~mask] = iq[t, ~mask]
        if not mask[0]:
            r[t] = ir[t]
    return r, qq


def score_partial_clip(skeleton: Skeleton, gt: tuple, keys: list[int], partial: dict, fill) -> dict:
    """One clip's sums: ``{method: (error sum, count, free error sum, free count)}`` for ``model``, ``interp`` and
    ``frozen`` (module docstring).  ``gt``: ``(root (F, 3), local_q (F, J, 4))``; ``fill(root, q, keys, partial=)``
    (``None``: the interpolation is the model); unknown values reach the fills as NaN."""
    f = len(gt[0])
    known = np.zeros(gt[1].shape[:2], dtype=bool)
    known[keys] = True
    for t, mask in partial.items():
        known[t] = mask
    root_in, q_in = gt[0].copy(), gt[1].copy()
    q_in[~known] = np.nan
    root_in[~known[:, 0]] = np.nan
    interp = interpolate_known(root_in, q_in, known)
    if fill is None:
        model = frozen = interp
    else:
        model = fill(root_in, q_in, keys, partial=partial)
        fr, fq = frozen_keys(root_in, q_in, keys, partial)
        frozen = fill(fr, fq, sorted(keys + list(partial)))
    gen = np.ones(f, dtype=bool)
    gen[keys] = False
    free = np.zeros(known.shape, dtype=bool)
    for t, mask in partial.items():
        free[t] = ~mask
    gp = skeleton.pose(*gt)[1]
    out = {}
    for name, (r, q) in (("model", model), ("interp", interp), ("frozen", frozen)):
        if not (np.isfinite(r).all() and np.isfinite(q).all()):
            raise ValueError(f"partial keys: the {name} fill returned non-finite values")
        d = np.linalg.norm(skeleton.pose(np.asarray(r, np.float64), np.asarray(q, np.float64))[1] - gp, axis=-1)
        out[name] = (float(d[gen].sum()), int(d[gen].size), float(d[free].sum()), int(free.sum()))
    return out
