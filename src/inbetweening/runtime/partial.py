"""Partial keys: frames the animator keyed on some bones only.

A partial key constrains its bones and nothing else: the gaps are still those between whole keys (:mod:`.plan`), and
a window that holds a partial key sees it as known values of those joints (the model was trained for it:
``data.partial_prob``, :func:`inbetweening.training.tasks.partial_keys`); the other joints of that frame are generated
like any in-between.  What the window shows in place of the unkeyed joints there (their world positions depend on
them), what the do-no-harm blend falls back to and what a long gap's pseudo-keyframes take is the interpolation of
each joint between its own known values (:func:`~inbetweening.geometry.interp.interpolate_known`).  Keyed values come
back exactly as given.
"""
from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .model import InbetweenError
from .plan import check_keys

__all__ = ["check_clip", "check_partial", "known_values"]


def _joints_of(frame: int, joints, names: list[str], skeleton: str) -> np.ndarray:
    """One partial key's joints (a bool mask of ``len(names)``, joint indices or joint names of ``skeleton``) as a
    bool mask."""
    n = len(names)
    arr = np.asarray(joints) if isinstance(joints, np.ndarray) or not isinstance(joints, (list, tuple, set)) else None
    if arr is not None and arr.dtype == bool:
        if arr.shape != (n,):
            raise InbetweenError(f"partial keys: frame {frame}: a joint mask needs {n} values (one per joint of "
                                 f"{skeleton}), got shape {arr.shape}")
        return arr.copy()
    mask = np.zeros(n, dtype=bool)
    if isinstance(joints, str):
        joints = [joints]
        arr = None
    items = list(joints) if arr is None else (list(np.atleast_1d(arr)) if arr.ndim else [arr.item()])
    for j in items:
        if isinstance(j, (str, np.str_)):
            if str(j) not in names:
                raise InbetweenError(f"partial keys: frame {frame}: no joint named {str(j)!r} in {skeleton}")
            mask[names.index(str(j))] = True
        elif isinstance(j, (int, np.integer)) and not isinstance(j, bool) and 0 <= int(j) < n:
            mask[int(j)] = True
        else:
            raise InbetweenError(f"partial keys: frame {frame}: {j!r} is not a joint (an index 0..{n - 1} or a name)")
    return mask


def check_partial(partial, keys: list[int], num_frames: int, names: list[str],
                  skeleton: str = "the model's skeleton") -> tuple[dict[int, np.ndarray], list[int]]:
    """``partial`` (``{frame: joints}``, ``None`` or empty for none; joints: a bool mask, indices or names of
    ``names``, the joints of ``skeleton``, for messages) checked against the whole ``keys``: ``({frame: (J,) bool
    mask}, keys)``.  A frame must lie strictly between the first and the last key and must not be a key; a frame
    keyed on every joint is a whole key (moved into the returned keys); a frame keyed on none is left out.  The one
    check of partial keys: the API's (a file's frames and bones) and the runtime's (:func:`check_clip`)."""
    if not partial:
        return {}, keys
    if not isinstance(partial, Mapping):
        raise InbetweenError(f"partial keys must map frame -> joints, got {type(partial).__name__}")
    out: dict[int, np.ndarray] = {}
    whole = set(keys)
    for frame, joints in partial.items():
        if isinstance(frame, bool) or not isinstance(frame, (int, np.integer)):
            raise InbetweenError(f"partial keys: {frame!r} is not an integer frame index")
        t = int(frame)
        if not 0 <= t < num_frames:
            raise InbetweenError(f"partial keys: frame {t} is out of range for a clip of {num_frames} frames")
        if t in whole:
            raise InbetweenError(f"partial keys: frame {t} is also a whole key (give it once)")
        if not keys[0] < t < keys[-1]:
            raise InbetweenError(f"partial keys: frame {t} lies outside the keys ({keys[0]}..{keys[-1]}); a partial "
                                 "key constrains the frames between two whole keys")
        mask = _joints_of(t, joints, names, skeleton)
        if mask.all():
            whole.add(t)
        elif mask.any():
            out[t] = mask
    return out, sorted(whole)


def known_values(partial: dict[int, np.ndarray], keys: list[int], num_frames: int, num_joints: int) -> np.ndarray:
    """``(F, J)`` bool: the values the caller gave in the filled span and before it (every frame before the first
    key is context), the keys whole and the partial keys on their joints."""
    known = np.zeros((num_frames, num_joints), dtype=bool)
    known[: keys[0]] = True
    known[keys] = True
    for t, mask in partial.items():
        known[t] = mask
    return known


def check_clip(where: str, n: int, keys, partial, names: list[str], joints: list[np.ndarray],
               root: np.ndarray | None = None) -> tuple[list[int], dict[int, np.ndarray]]:
    """The one input check of a fill (:meth:`FillRuntime.fill <inbetweening.runtime.fill.FillRuntime.fill>` on the
    model's skeleton, :func:`~inbetweening.runtime.rig_fill.fill_rig` on a rig's): ``(keys, partial keys)`` checked
    (:func:`~inbetweening.runtime.plan.check_keys`, :func:`check_partial`; ``n`` frames, joints ``names``), and the
    values they keep finite: every key's in each of ``joints`` (arrays ``(F, J, ...)``) and ``root`` (``(F, 3)``), a
    partial key's on its keyed joints (the root where it keys joint 0).  :class:`InbetweenError` naming ``where``."""
    keys = check_keys(keys, n, "keys")
    part, keys = check_partial(partial, keys, n, names, "the rig" if where == "fill_rig" else "the model's skeleton")
    values = list(joints) + ([root] if root is not None else [])
    if not all(np.isfinite(a[keys]).all() for a in values):
        raise InbetweenError(f"{where}: the keys contain NaN or infinite values")
    for t, mask in part.items():
        if not (all(np.isfinite(a[t, mask]).all() for a in joints)
                and (root is None or not mask[0] or np.isfinite(root[t]).all())):
            raise InbetweenError(f"{where}: the partial key at frame {t} contains NaN or infinite values")
    return keys, part
