"""Interpolation between known frames: positions linearly, rotations by slerp (numpy and torch).

The one implementation behind the interpolation baseline of the benchmark, the lerp mask of the model input,
the animator tool's pseudo-keyframes and its comparison clip.  Weights are the caller's (the benchmark passes
the reference code's float32 ``linspace``).
"""
from __future__ import annotations

import itertools

import numpy as np

from inbetweening.geometry.arrays import Array, is_tensor
from inbetweening.geometry.quaternion import slerp_np, slerp_torch


def lerp(a: Array, b: Array, w: Array) -> Array:
    """``a + w (b - a)`` (broadcasting)."""
    return a + w * (b - a)


def slerp(q0: Array, q1: Array, w: Array) -> Array:
    """Shortest-arc slerp with the reference's linear fallback.  ``(..., 4), (..., 4), (...) -> (..., 4)``."""
    if is_tensor(q0):
        return slerp_torch(q0, q1, w)
    return slerp_np(q0, q1, w)


def interpolate_pose(root0: Array, q0: Array, root1: Array, q1: Array, w: Array) -> tuple[Array, Array]:
    """Poses between two poses: root lerp, per-joint slerp.

    ``root0/root1 (..., 3), q0/q1 (..., J, 4)`` and weights ``w (...)`` (broadcasting with the batch shape; 0 ->
    the first pose, 1 -> the second) -> ``root (..., 3), q (..., J, 4)``.
    """
    return lerp(root0, root1, w[..., None]), slerp(q0, q1, w[..., None])


def interpolate_keyframes(root, local_q, known_frames) -> tuple[np.ndarray, np.ndarray]:
    """Fill the frames between consecutive known frames by root lerp and per-joint slerp (the baseline).

    ``root (F, 3), local_q (F, J, 4), known_frames`` (sorted) -> new float64 arrays; known frames are copied
    unchanged and unknown frames are never read.
    """
    root = np.array(root, dtype=np.float64)
    q = np.array(local_q, dtype=np.float64)
    for a, b in itertools.pairwise(known_frames):
        if b - a < 2:
            continue
        w = (np.arange(a + 1, b) - a) / (b - a)
        root[a + 1 : b], q[a + 1 : b] = interpolate_pose(root[a], q[a], root[b], q[b], w)
    return root, q


def interpolate_known(root, local_q, known) -> tuple[np.ndarray, np.ndarray]:
    """:func:`interpolate_keyframes` joint by joint: ``known (F, J)`` bool marks the values given (partial keys: a
    frame may be known on some joints only); each joint's rotation is slerped between its own known frames, the root
    position lerped between the frames where joint 0 is known; before a joint's first / after its last known frame it
    holds that value.  Known values are copied unchanged and unknown values are never read; a joint never known keeps
    the input (never read by callers that know it)."""
    root = np.array(root, dtype=np.float64)
    q = np.array(local_q, dtype=np.float64)
    known = np.asarray(known, dtype=bool)
    f = len(root)
    t = np.arange(f)

    def spans(frames):
        nxt = np.clip(np.searchsorted(frames, t, side="left"), 1, len(frames) - 1)
        a, b = frames[nxt - 1], frames[nxt]
        w = np.clip((t - a) / np.maximum(b - a, 1), 0.0, 1.0)
        return a, b, w, ~np.isin(t, frames)

    for j in range(known.shape[1]):
        frames = np.flatnonzero(known[:, j])
        if len(frames) == 0:
            continue
        if len(frames) == 1:
            q[~known[:, j], j] = q[frames[0], j]
        else:
            a, b, w, todo = spans(frames)
            q[todo, j] = slerp_np(q[a[todo], j], q[b[todo], j], w[todo])
        if j == 0:
            if len(frames) == 1:
                root[~known[:, 0]] = root[frames[0]]
            else:
                root[todo] = lerp(root[a[todo]], root[b[todo]], w[todo, None])
    return root, q
