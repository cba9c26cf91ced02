"""Two-bone inverse kinematics (numpy): move the end of a hip-knee-ankle chain to a target, analytically.

The chain keeps its root joint (the hip) in place and its bending plane where it can; the knee angle is set so the
hip-ankle distance equals the hip-target distance (clamped to what the bones reach), then the chain swings about
the hip to point at the target.  The end joint keeps its global rotation.  Everything is in global space; the caller
turns the new global rotations into local ones (:func:`two_bone_ik` returns both).
"""
from __future__ import annotations

import numpy as np

from inbetweening.geometry.quaternion import qinv, qmul

__all__ = ["axis_angle", "two_bone_ik"]

EPS = 1e-8


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), EPS)


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.arccos(np.clip((_unit(a) * _unit(b)).sum(-1), -1.0, 1.0))


def axis_angle(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Quaternions (wxyz) of rotations by ``angle (...)`` radians about unit ``axis (..., 3)``."""
    half = 0.5 * np.asarray(angle)[..., None]
    return np.concatenate([np.cos(half), np.sin(half) * axis], axis=-1)


def _fill_degenerate(axis: np.ndarray, ok: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """Axes of frames where the leg is straight (``~ok``): the nearest bent frame's, else ``fallback``."""
    if ok.all():
        return axis
    if not ok.any():
        return np.broadcast_to(fallback, axis.shape).copy()
    idx = np.arange(len(ok))
    good = idx[ok]
    nearest = good[np.abs(idx[:, None] - good[None, :]).argmin(axis=1)]
    return axis[nearest]


def two_bone_ik(hip_p, knee_p, ankle_p, target, hip_gq, knee_gq, ankle_gq, parent_gq):
    """Solve the chain for ``F`` frames.

    Args:
        hip_p, knee_p, ankle_p, target: global positions ``(F, 3)``.
        hip_gq, knee_gq, ankle_gq: global rotations ``(F, 4)`` (wxyz) of the three joints; ``parent_gq`` of the hip's
            parent.
    Returns:
        ``(hip_local, knee_local, ankle_local)`` ``(F, 4)`` each: local rotations that put the ankle at the target
        (or as close as the bones reach), the hip where it was and the ankle's global rotation unchanged.
    """
    a, b, c, t = (np.asarray(v, dtype=np.float64) for v in (hip_p, knee_p, ankle_p, target))
    lab = np.linalg.norm(b - a, axis=-1)
    lcb = np.linalg.norm(c - b, axis=-1)
    lat = np.clip(np.linalg.norm(t - a, axis=-1), 1e-6 + np.abs(lab - lcb), lab + lcb - 1e-6)
    ac_ab_0, ba_bc_0 = _angle(c - a, b - a), _angle(a - b, c - b)
    ac_ab_1 = np.arccos(np.clip((lcb**2 - lab**2 - lat**2) / (-2 * lab * lat), -1.0, 1.0))
    ba_bc_1 = np.arccos(np.clip((lat**2 - lab**2 - lcb**2) / (-2 * lab * lcb), -1.0, 1.0))
    bend = np.cross(c - a, b - a)
    ok = np.linalg.norm(bend, axis=-1) > 1e-6 * np.maximum(lab * lcb, EPS)
    bend = _fill_degenerate(_unit(bend), ok, np.array([1.0, 0.0, 0.0]))
    swing = np.cross(c - a, t - a)
    swing_ok = np.linalg.norm(swing, axis=-1) > EPS
    swing = np.where(swing_ok[:, None], _unit(swing), bend)
    r0 = axis_angle(bend, ac_ab_1 - ac_ab_0)
    r1 = axis_angle(bend, ba_bc_1 - ba_bc_0)
    r2 = axis_angle(swing, np.where(swing_ok, _angle(c - a, t - a), 0.0))
    hip_new = qmul(r2, qmul(r0, hip_gq))
    knee_new = qmul(r2, qmul(r1, qmul(r0, knee_gq)))
    return qmul(qinv(parent_gq), hip_new), qmul(qinv(hip_new), knee_new), qmul(qinv(knee_new), ankle_gq)
