"""Quaternion utilities, numpy and torch side by side.

Convention everywhere: quaternions are ``(w, x, y, z)`` in the last axis, the product is
the Hamilton product, and ``qmul(a, b)`` applied to a vector rotates by ``b`` first, then ``a``.

Every function in the first block accepts either ``numpy.ndarray`` or ``torch.Tensor`` and
returns the same kind (one implementation, dispatched on the input type, so the numpy and torch
paths cannot drift apart). Functions with a ``_np`` / ``_torch`` suffix are the two sides of an
operation that is written differently for each library (the torch side uses ``roma``); the tests
check them against each other.
"""
from __future__ import annotations

import numpy as np

from inbetweening.geometry.arrays import Array, is_tensor, torch

_AXES = {"x": 0, "y": 1, "z": 2}


def _stack(parts: list) -> Array:
    if is_tensor(parts[0]):
        return torch.stack(parts, dim=-1)
    return np.stack(parts, axis=-1)


def _cross(a: Array, b: Array) -> Array:
    """Cross product over the last axis (3), broadcasting.  ``(..., 3) x (..., 3) -> (..., 3)``."""
    ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
    bx, by, bz = b[..., 0], b[..., 1], b[..., 2]
    return _stack([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx])


_is_torch = is_tensor


def _sum_last(x: Array, keepdims: bool = True) -> Array:
    if _is_torch(x):
        return x.sum(dim=-1, keepdim=keepdims)
    return x.sum(axis=-1, keepdims=keepdims)


# --------------------------------------------------------------------------------------------
# Shared (numpy or torch) implementations
# --------------------------------------------------------------------------------------------
def qmul(a: Array, b: Array) -> Array:
    """Hamilton product ``a ⊗ b``.  ``(..., 4), (..., 4) -> (..., 4)`` (broadcasting)."""
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return _stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ]
    )


def quat_to_rot6d(q: Array) -> Array:
    """Continuous 6-D rotation (Zhou et al. 2019): the first two columns of the rotation matrix of unit quaternions
    ``q`` (wxyz), as ``[m00, m10, m20, m01, m11, m21]``.  ``(..., 4) -> (..., 6)``; ``q`` and ``-q`` give the same
    value (no sign ambiguity, unlike the quaternion itself)."""
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return _stack([1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y),
                   2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x)])


def qinv(q: Array) -> Array:
    """Inverse of a unit quaternion (the conjugate).  ``(..., 4) -> (..., 4)``."""
    return _stack([q[..., 0], -q[..., 1], -q[..., 2], -q[..., 3]])


def qrot(q: Array, v: Array) -> Array:
    """Rotate vectors by unit quaternions.  ``(..., 4), (..., 3) -> (..., 3)`` (broadcasting)."""
    u = q[..., 1:]
    t = 2.0 * _cross(u, v)
    return v + q[..., :1] * t + _cross(u, t)


def qnormalize(q: Array, eps: float = 1e-8) -> Array:
    """Scale to unit length.  ``(..., 4) -> (..., 4)``."""
    norm = _sum_last(q * q) ** 0.5
    return q / (norm + eps)


def qbetween(a: Array, b: Array) -> Array:
    """Unnormalised quaternion rotating direction ``a`` onto ``b``.  ``(..., 3), (..., 3) -> (..., 4)``.

    Normalise the result with :func:`qnormalize` (kept separate so the benchmark protocol can
    reproduce the reference implementation bit for bit).
    """
    w = (_sum_last(a * a, False) * _sum_last(b * b, False)) ** 0.5 + _sum_last(a * b, False)
    c = _cross(a, b)
    return _stack([w, c[..., 0], c[..., 1], c[..., 2]])


def qswing(a: np.ndarray, b: np.ndarray, axis: np.ndarray | None = None, opposite: float = 1e-9) -> np.ndarray:
    """Unit quaternion of the shortest rotation taking direction ``a`` onto ``b`` (numpy).  Where they are (nearly)
    opposite (``1 + cos`` below ``opposite``) the shortest arc is undecided: a half turn about ``axis`` (made
    perpendicular to ``a``; default: any perpendicular axis).  ``(..., 3), (..., 3) -> (..., 4)``."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    a = a / np.maximum(np.linalg.norm(a, axis=-1, keepdims=True), 1e-12)
    b = b / np.maximum(np.linalg.norm(b, axis=-1, keepdims=True), 1e-12)
    q = qbetween(a, b)
    flip = q[..., 0] < opposite  # w = 1 + cos(angle) for unit vectors
    if np.any(flip):
        helper = np.where((np.abs(a[..., :1]) < 0.9), np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))
        perp = _cross(a, helper)
        if axis is not None:
            given = np.asarray(axis, dtype=np.float64) - (np.asarray(axis, dtype=np.float64) * a).sum(-1, keepdims=True) * a
            ok = np.linalg.norm(given, axis=-1, keepdims=True) > 1e-6
            perp = np.where(ok, given, perp)
        perp = perp / np.linalg.norm(perp, axis=-1, keepdims=True)
        half = np.concatenate([np.zeros(perp.shape[:-1] + (1,)), perp], axis=-1)
        q = np.where(flip[..., None], half, q)
    return qnormalize(q, 0.0)


def qframe(a1: np.ndarray, a2: np.ndarray, b1: np.ndarray, b2: np.ndarray) -> np.ndarray:
    """Unit quaternion of the rotation taking direction ``a1`` onto ``b1`` exactly and the plane of ``(a1, a2)`` onto
    that of ``(b1, b2)`` (``a2`` turned about ``b1`` as close to ``b2`` as it goes): a frame given by a primary and a
    secondary direction (numpy).  ``(..., 3) x 4 -> (..., 4)``."""
    r1 = qswing(a1, b1)
    b1 = np.asarray(b1, dtype=np.float64)
    b1 = b1 / np.linalg.norm(b1, axis=-1, keepdims=True)
    a2r = qrot(r1, np.asarray(a2, dtype=np.float64))
    pa = a2r - (a2r * b1).sum(-1, keepdims=True) * b1
    pb = np.asarray(b2, dtype=np.float64) - (np.asarray(b2, dtype=np.float64) * b1).sum(-1, keepdims=True) * b1
    half = 0.5 * np.arctan2((_cross(pa, pb) * b1).sum(-1), (pa * pb).sum(-1))  # the turn about b1
    twist = np.concatenate([np.cos(half)[..., None], np.sin(half)[..., None] * b1], axis=-1)
    return qnormalize(qmul(twist, r1), 0.0)


def remove_discontinuities(q: Array, axis: int = 0) -> Array:
    """Flip signs along time so consecutive quaternions have a non-negative dot product.

    ``q_t -> -q_t`` whenever that is closer to the (already fixed) ``q_{t-1}``; vectorised as a
    cumulative product of the per-step sign changes.  ``(T, ..., 4) -> (T, ..., 4)`` along ``axis``.
    """
    if _is_torch(q):
        qm = torch.movedim(q, axis, 0)
        dots = (qm[1:] * qm[:-1]).sum(-1)
        step = torch.where(dots < 0, -1.0, 1.0).to(q.dtype)
        sign = torch.cat([torch.ones_like(qm[:1, ..., 0]), torch.cumprod(step, 0)], 0)  # (a single frame too)
        return torch.movedim(qm * sign[..., None], 0, axis)
    qm = np.moveaxis(q, axis, 0)
    dots = (qm[1:] * qm[:-1]).sum(-1)
    step = np.where(dots < 0, -1.0, 1.0)
    sign = np.concatenate([np.ones_like(qm[:1, ..., 0]), np.cumprod(step, 0)], 0)  # (a single frame too)
    return np.moveaxis(qm * sign[..., None], 0, axis)


def qangle(a: Array, b: Array) -> Array:
    """Geodesic angle (radians) between rotations, sign invariant.  ``(..., 4), (..., 4) -> (...)``.

    ``2 atan2(|xyz|, |w|)`` of ``a* ⊗ b``: exact near 0, where ``2 acos(|a·b|)`` loses half the digits.
    """
    d = qmul(qinv(a), b)
    s = _sum_last(d[..., 1:] * d[..., 1:], False) ** 0.5
    if _is_torch(d):
        return 2.0 * torch.atan2(s, d[..., 0].abs())
    return 2.0 * np.arctan2(s, np.abs(d[..., 0]))


# --------------------------------------------------------------------------------------------
# numpy / torch pairs
# --------------------------------------------------------------------------------------------
def euler_to_quat_np(angles: np.ndarray, order: str, degrees: bool = True) -> np.ndarray:
    """Euler angles to quaternions, BVH style.  ``(..., 3) -> (..., 4)``.

    ``order`` names the axis of each of the three angles, e.g. ``"zxy"`` for channels
    ``Zrotation Xrotation Yrotation``; the result is ``q_A ⊗ q_B ⊗ q_C`` (intrinsic rotations).
    """
    order = order.lower()
    angles = np.asarray(angles, dtype=np.float64)
    if degrees:
        angles = np.radians(angles)
    out = None
    for i, ax in enumerate(order):
        half = angles[..., i] / 2.0
        q = np.zeros(angles.shape[:-1] + (4,), dtype=np.float64)
        q[..., 0] = np.cos(half)
        q[..., 1 + _AXES[ax]] = np.sin(half)
        out = q if out is None else qmul(out, q)
    return out


def euler_to_quat_torch(angles: torch.Tensor, order: str, degrees: bool = True) -> torch.Tensor:
    """Torch twin of :func:`euler_to_quat_np`, through ``roma`` (intrinsic convention = uppercase)."""
    import roma  # imported where used: it imports torch._dynamo (seconds of start-up)

    xyzw = roma.euler_to_unitquat(order.upper(), angles, degrees=degrees)
    return xyzw_to_wxyz(xyzw)


def quat_to_matrix_np(q: np.ndarray) -> np.ndarray:
    """Unit quaternions to rotation matrices.  ``(..., 4) -> (..., 3, 3)``."""
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    m = np.empty(q.shape[:-1] + (3, 3), dtype=np.float64)
    m[..., 0, 0] = 1 - 2 * (y * y + z * z)
    m[..., 0, 1] = 2 * (x * y - w * z)
    m[..., 0, 2] = 2 * (x * z + w * y)
    m[..., 1, 0] = 2 * (x * y + w * z)
    m[..., 1, 1] = 1 - 2 * (x * x + z * z)
    m[..., 1, 2] = 2 * (y * z - w * x)
    m[..., 2, 0] = 2 * (x * z - w * y)
    m[..., 2, 1] = 2 * (y * z + w * x)
    m[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return m


def quat_to_euler_np(q: np.ndarray, order: str, degrees: bool = True) -> np.ndarray:
    """Inverse of :func:`euler_to_quat_np` for any of the six Tait-Bryan orders.  ``(..., 4) -> (..., 3)``.

    For intrinsic order A B C the rotation matrix is R = R_A R_B R_C; the middle angle is
    recovered from element ``R[a, c]`` and the others from the remaining row/column.
    """
    order = order.lower()
    a, b, c = (_AXES[ch] for ch in order)
    if len({a, b, c}) != 3:
        raise ValueError(f"quat_to_euler_np: order {order!r} must name three different axes")
    q = np.asarray(q, dtype=np.float64)
    if q.ndim == 1:  # one quaternion: the gimbal-lock branch below assigns into arrays
        return quat_to_euler_np(q[None], order, degrees)[0]
    m = quat_to_matrix_np(qnormalize(q))
    # parity of the permutation (a, b, c): +1 for cyclic (xyz, yzx, zxy), -1 otherwise
    sign = 1.0 if (b - a) % 3 == 1 else -1.0
    cos_mid = np.hypot(m[..., a, a], m[..., a, b])
    mid = np.arctan2(sign * m[..., a, c], cos_mid)
    first = np.arctan2(-sign * m[..., b, c], m[..., c, c])
    last = np.arctan2(-sign * m[..., a, b], m[..., a, a])
    # gimbal lock: cos(mid) ~ 0 -> last angle := 0 and the first from R · R_b(mid)^T = R_a(first)
    lock = cos_mid < 1e-6
    if np.any(lock):
        half = mid[lock] / 2.0
        qb = np.zeros(half.shape + (4,))
        qb[..., 0], qb[..., 1 + b] = np.cos(half), np.sin(half)
        ra = m[lock] @ np.swapaxes(quat_to_matrix_np(qb), -1, -2)
        u, v = (a + 1) % 3, (a + 2) % 3
        first[lock] = np.arctan2(ra[..., v, u], ra[..., u, u])
        last[lock] = 0.0
    out = np.stack([first, mid, last], axis=-1)
    return np.degrees(out) if degrees else out


def slerp_np(q0: np.ndarray, q1: np.ndarray, t: np.ndarray | float, linear_eps: float = 0.01) -> np.ndarray:
    """Spherical interpolation along the shorter arc.  ``(..., 4), (..., 4), (...) -> (..., 4)``.

    Falls back to linear interpolation where ``1 - |dot| < linear_eps`` (as the LAFAN1 reference
    code does); the result is normalised.
    """
    q0 = qnormalize(np.asarray(q0, dtype=np.float64))
    q1 = qnormalize(np.asarray(q1, dtype=np.float64))
    dot = np.sum(q0 * q1, axis=-1)
    q1 = np.where((dot < 0)[..., None], -q1, q1)
    dot = np.abs(dot)
    t = np.zeros_like(dot) + t
    linear = (1.0 - dot) < linear_eps
    omega = np.arccos(np.clip(dot, -1.0, 1.0))
    sin_omega = np.where(linear, 1.0, np.sin(omega))
    w0 = np.where(linear, 1.0 - t, np.sin((1.0 - t) * omega) / sin_omega)
    w1 = np.where(linear, t, np.sin(t * omega) / sin_omega)
    return qnormalize(w0[..., None] * q0 + w1[..., None] * q1)


def slerp_torch(q0: torch.Tensor, q1: torch.Tensor, t: torch.Tensor | float, linear_eps: float = 0.01) -> torch.Tensor:
    """Torch twin of :func:`slerp_np` (same shortest-arc rule and linear fallback), differentiable.

    ``(..., 4), (..., 4), (...) -> (..., 4)``; ``t`` broadcasts against the batch shape.
    """
    q0, q1 = qnormalize(q0), qnormalize(q1)
    dot = (q0 * q1).sum(-1)
    q1 = torch.where((dot < 0)[..., None], -q1, q1)
    dot = dot.abs()
    t = torch.as_tensor(t, dtype=q0.dtype, device=q0.device)
    linear = (1.0 - dot) < linear_eps
    omega = torch.acos(dot.clamp(max=1.0 - 1e-7))
    sin_omega = torch.where(linear, torch.ones_like(omega), torch.sin(omega))
    w0 = torch.where(linear, 1.0 - t, torch.sin((1.0 - t) * omega) / sin_omega)
    w1 = torch.where(linear, t + 0 * omega, torch.sin(t * omega) / sin_omega)
    return qnormalize(w0[..., None] * q0 + w1[..., None] * q1)


def slerp_roma(q0: torch.Tensor, q1: torch.Tensor, steps: torch.Tensor) -> torch.Tensor:
    """Slerp through ``roma.unitquat_slerp`` (wxyz in and out): ``(N, 4), (N, 4), (S,) -> (S, N, 4)``.

    Used by the tests as an independent implementation to check :func:`slerp_torch` against.
    """
    import roma

    out = roma.unitquat_slerp(wxyz_to_xyzw(qnormalize(q0)), wxyz_to_xyzw(qnormalize(q1)), steps, shortest_arc=True)
    return xyzw_to_wxyz(out)


def wxyz_to_xyzw(q: Array) -> Array:
    """``(..., 4)`` wxyz -> xyzw (roma's order)."""
    return _stack([q[..., 1], q[..., 2], q[..., 3], q[..., 0]])


def xyzw_to_wxyz(q: Array) -> Array:
    """``(..., 4)`` xyzw (roma's order) -> wxyz."""
    return _stack([q[..., 3], q[..., 0], q[..., 1], q[..., 2]])
