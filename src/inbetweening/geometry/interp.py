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
