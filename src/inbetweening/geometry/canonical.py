"""Window canonicalisation: centre the root XZ and turn about +Y so the root's forward axis points to +X.

The geometry of a window's canonical frame: :func:`facing_rotation`, :func:`canonical_frame` and
:func:`canonicalise` / :func:`uncanonicalise` (used by the predictor's one centring stage,
:meth:`inbetweening.predictor.predictor.Predictor.canonical_frame`, and by the LAFAN1 protocol's whole-window
normalisation, :func:`inbetweening.data.windows.canonicalise_windows`).  Pure functions; numpy arrays
and torch tensors alike (like :mod:`inbetweening.geometry.quaternion`).
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from inbetweening.geometry.arrays import Array, is_tensor, torch
from inbetweening.geometry.quaternion import qbetween, qinv, qmul, qnormalize, qrot

_is_torch = is_tensor


def _const(values, like: Array) -> Array:
    if _is_torch(like):
        return torch.as_tensor(values, dtype=like.dtype, device=like.device)
    return np.asarray(values, dtype=np.float64)


def masked_mean(x: Array, known: Array | None = None) -> Array:
    """Mean over the time axis ``-2`` (kept), over all frames or only where ``known``.

    ``x (..., T, C), known (..., T) bool | None -> (..., 1, C)``.  Unknown values are never read (NaN is fine);
    with no known frame the mean is 0.
    """
    if known is None:
        if _is_torch(x):
            return x.mean(dim=-2, keepdim=True)
        return x.mean(axis=-2, keepdims=True)
    if _is_torch(x):
        picked = torch.where(known[..., None], x, 0.0)
        return picked.sum(-2, keepdim=True) / known.to(x.dtype).sum(-1, keepdim=True)[..., None].clamp(min=1)
    picked = np.where(np.asarray(known)[..., None], x, 0.0)
    return picked.sum(axis=-2, keepdims=True) / np.maximum(np.asarray(known).sum(-1, keepdims=True)[..., None], 1)


def xz_centre(root: Array, known: Array | None = None) -> Array:
    """The point the window is centred on: mean root XZ (over ``known`` frames if given), Y = 0.

    ``root (..., T, 3), known (..., T) | None -> (..., 1, 3)``.
    """
    xz = masked_mean(root[..., [0, 2]], known)
    zero = xz[..., :1] * 0.0
    if _is_torch(root):
        return torch.cat([xz[..., :1], zero, xz[..., 1:]], dim=-1)
    return np.concatenate([xz[..., :1], zero, xz[..., 1:]], axis=-1)


def facing_rotation(root_q: Array, forward_axis: Sequence[float]) -> Array:
    """Rotation about +Y taking +X to the root's facing direction.  ``(..., 4) -> (..., 4)``.

    The facing direction is ``forward_axis`` (a direction in the root's local frame, LAFAN1: +Y) rotated by
    ``root_q`` and projected onto XZ.  Computed as the LAFAN1 reference does (``qbetween`` of normalised
    vectors), bit for bit; where that is degenerate (facing exactly -X, or straight up/down) the result is a
    half turn about +Y or the identity instead of a zero quaternion.
    """
    axis = _const(forward_axis, root_q)
    mask = _const([1.0, 0.0, 1.0], root_q)
    plusx = _const([1.0, 0.0, 0.0], root_q)
    fwd = mask * qrot(root_q, axis)
    fwd = fwd / ((fwd * fwd).sum(-1)[..., None] ** 0.5 + 1e-8)
    rot = qnormalize(qbetween(plusx, fwd))
    degenerate = ((rot * rot).sum(-1) < 0.5)[..., None]
    fallback_half = fwd[..., :1] < -0.5  # facing -X; otherwise no horizontal facing at all
    half, ident = _const([0.0, 0.0, 1.0, 0.0], root_q), _const([1.0, 0.0, 0.0, 0.0], root_q)
    if _is_torch(root_q):
        return torch.where(degenerate, torch.where(fallback_half, half, ident), rot)
    return np.where(degenerate, np.where(fallback_half, half, ident), rot)


def canonical_frame(root: Array, local_q: Array, forward_axis: Sequence[float], frame, known: Array | None = None,
                    centre_at_frame: bool = False) -> tuple[Array, Array]:
    """``(centre (..., 1, 3), rotation (..., 1, 4))`` of windows ``root (..., T, 3), local_q (..., T, J, 4)``:
    the facing of the root at ``frame`` (a unit quaternion, without the reference's epsilon, so
    :func:`uncanonicalise` inverts :func:`canonicalise` exactly) and the mean root XZ (over ``known (..., T)`` frames
    if given), or with ``centre_at_frame`` the root XZ at ``frame``.  ``frame``: an int, or one frame per window
    (``(B,)`` indices of windows ``root (B, T, 3)``, ``local_q (B, T, J, 4)``)."""
    if isinstance(frame, (int, np.integer)):
        root_q, at = local_q[..., frame : frame + 1, 0, :], root[..., frame : frame + 1, :]
    else:
        rows = torch.arange(len(frame), device=frame.device) if _is_torch(frame) else np.arange(len(frame))
        root_q, at = local_q[rows, frame][:, None, 0, :], root[rows, frame][:, None, :]
    rot = facing_rotation(root_q, forward_axis)
    centre = xz_centre(at) if centre_at_frame else xz_centre(root, known)  # a mean over one frame is its value
    return centre, rot / (rot * rot).sum(-1)[..., None] ** 0.5


def canonicalise(root: Array, local_q: Array, centre: Array, rotation: Array) -> tuple[Array, Array]:
    """Move windows into their canonical frame: ``root' = R^-1 (root - centre)``, root rotation ``R^-1 q_0``.

    ``root (..., T, 3), local_q (..., T, J, 4), centre (..., 1, 3), rotation (..., 1, 4) -> same shapes``;
    the other joints' local rotations are returned unchanged (a yaw of the root leaves them as they are).
    """
    inv = qinv(rotation)
    q = local_q.clone() if _is_torch(local_q) else np.array(local_q, copy=True)
    q[..., 0, :] = qmul(inv, local_q[..., 0, :])
    return qrot(inv, root - centre), q


def uncanonicalise(root: Array, local_q: Array, centre: Array, rotation: Array) -> tuple[Array, Array]:
    """Inverse of :func:`canonicalise` (same arguments and shapes)."""
    q = local_q.clone() if _is_torch(local_q) else np.array(local_q, copy=True)
    q[..., 0, :] = qmul(rotation, local_q[..., 0, :])
    return qrot(rotation, root) + centre, q
