"""Checks of the inputs of a skeleton picture (:mod:`inbetweening.rendering.skeleton_plot`): sequences, parents,
up axis, keyframe highlight, feet, contacts, frames and view; each returns the checked value or raises ValueError
naming the argument."""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

DEFAULT_N_FRAMES = 8  # frames shown by draw_sequences when ``frames`` is None

__all__ = ["DEFAULT_N_FRAMES", "check_contacts", "check_feet", "check_highlight", "check_parents", "check_sequences",
           "check_up_axis", "check_frames", "check_view"]



def _to_numpy(x) -> np.ndarray:
    """numpy array or torch tensor (any device, with or without grad) -> ``np.ndarray``."""
    if hasattr(x, "detach"):
        x = x.detach().cpu()
    return np.asarray(x)


def check_parents(parents) -> np.ndarray:
    """``parents`` -> ``(J,)`` int array; ``-1`` for roots, otherwise an index in ``[0, J)`` other than itself."""
    par = _to_numpy(parents)
    if par.ndim != 1 or par.size == 0:
        raise ValueError(f"parents must be a non-empty 1-D sequence of ints, got shape {par.shape}")
    if not np.issubdtype(par.dtype, np.integer) and not (
        np.issubdtype(par.dtype, np.floating) and np.all(np.equal(np.mod(par, 1), 0))
    ):
        raise ValueError(f"parents must hold integers, got {par.tolist()}")
    par = par.astype(np.int64)
    n = par.size
    bad = [j for j, p in enumerate(par) if p < -1 or p >= n or p == j]
    if bad:
        raise ValueError(f"invalid parents at joints {bad}: each entry must be -1 (root) or another joint in [0, {n})")
    return par


def check_sequences(sequences: Mapping, n_joints: int) -> dict[str, np.ndarray]:
    """Validate ``label -> (T, J, 3)`` and convert to float64 numpy arrays."""
    if not isinstance(sequences, Mapping):
        raise TypeError(f"sequences must be a dict label -> (T, J, 3) array, got {type(sequences).__name__}")
    if len(sequences) == 0:
        raise ValueError("sequences is empty: pass at least one label -> (T, J, 3) array")
    out: dict[str, np.ndarray] = {}
    for label, seq in sequences.items():
        arr = _to_numpy(seq)
        if arr.ndim != 3 or arr.shape[-1] != 3:
            raise ValueError(f"sequence {label!r} must have shape (T, J, 3) (global joint positions), got {arr.shape}")
        if arr.shape[0] == 0:
            raise ValueError(f"sequence {label!r} has no frames (T == 0)")
        if arr.shape[1] != n_joints:
            raise ValueError(f"sequence {label!r} has J={arr.shape[1]} joints but parents describes {n_joints} joints")
        arr = arr.astype(np.float64)
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"sequence {label!r} contains NaN or infinite values")
        out[str(label)] = arr
    return out


def check_up_axis(up_axis: int) -> int:
    if up_axis not in (0, 1, 2):
        raise ValueError(f"up_axis must be 0, 1 or 2 (the data axis that points up), got {up_axis!r}")
    return int(up_axis)


def check_highlight(highlight, n_frames: int) -> np.ndarray:
    """``highlight`` -> ``(T,)`` bool array (all False when None); ``T`` is the longest sequence's length."""
    if highlight is None:
        return np.zeros(n_frames, dtype=bool)
    hl = _to_numpy(highlight)
    if hl.ndim != 1 or hl.shape[0] != n_frames:
        raise ValueError(
            f"highlight must be a (T,) bool mask with T={n_frames} (the longest sequence), got shape {hl.shape}"
        )
    return hl.astype(bool)


def check_feet(feet, n_joints: int) -> list[int]:
    """Foot joint indices (``None`` or empty: no trails) -> distinct ints in ``[0, J)``, in the order given."""
    idx = [] if feet is None else [int(f) for f in _to_numpy(feet).reshape(-1)]
    bad = [f for f in idx if not 0 <= f < n_joints]
    if bad:
        raise ValueError(f"feet {bad} are not joint indices in [0, {n_joints})")
    if len(set(idx)) != len(idx):
        raise ValueError(f"feet lists a joint twice: {idx}")
    return idx


def check_contacts(contacts, seqs: Mapping[str, np.ndarray], feet: Sequence[int]) -> dict[str, np.ndarray]:
    """Planted flags -> ``label -> (T_label, K)`` bool, one column per foot of ``feet``.

    ``contacts``: one array for every label, or ``label -> array`` (labels left out get no contact marks); an array
    is ``(T_label, J)`` (every joint; the feet's columns are read) or ``(T_label, K)`` (the feet, in ``feet``'s order),
    of bools (or 0/1)."""
    if contacts is None:
        return {}
    if not feet:
        raise ValueError("contacts given without feet: pass feet=[joint indices] to say which joints they flag")
    given = contacts if isinstance(contacts, Mapping) else dict.fromkeys(seqs, contacts)
    unknown = [label for label in given if label not in seqs]
    if unknown:
        raise ValueError(f"contacts for {unknown}, which are not labels of sequences ({list(seqs)})")
    n_joints = next(iter(seqs.values())).shape[1]
    out = {}
    for label, flags in given.items():
        if flags is None:
            continue
        arr = _to_numpy(flags)
        t = seqs[label].shape[0]
        if arr.ndim != 2 or arr.shape[0] != t or arr.shape[1] not in (n_joints, len(feet)):
            raise ValueError(f"contacts of {label!r} must have shape ({t}, {n_joints}) (every joint) or ({t}, "
                             f"{len(feet)}) (the feet), got {arr.shape}")
        if arr.shape[1] == n_joints and n_joints != len(feet):
            arr = arr[:, list(feet)]
        if arr.dtype != bool:
            if not np.isin(arr, (0, 1)).all():
                raise ValueError(f"contacts of {label!r} must be planted flags (bool or 0/1); threshold a predicted "
                                 f"contact first (inbetweening.data.contacts.CONTACT_THRESHOLD)")
            arr = arr.astype(bool)
        out[label] = arr
    return out


def check_frames(frames, n_frames: int) -> list[int]:
    """Frame indices to show; default: up to :data:`DEFAULT_N_FRAMES` evenly spaced, first and last included."""
    if frames is None:
        k = min(n_frames, DEFAULT_N_FRAMES)
        return sorted({round(float(f)) for f in np.linspace(0, n_frames - 1, k)})
    idx = [int(f) for f in _to_numpy(frames).reshape(-1)]
    if not idx:
        raise ValueError("frames is empty: pass at least one frame index (or None for the default selection)")
    bad = [f for f in idx if not 0 <= f < n_frames]
    if bad:
        raise ValueError(f"frames {bad} out of range [0, {n_frames}) (T of the longest sequence)")
    return idx


def check_view(view) -> tuple[float, float] | None:
    if view is None:
        return None
    v = tuple(float(x) for x in view)
    if len(v) != 2 or not all(math.isfinite(x) for x in v):
        raise ValueError(f"view must be (elevation, azimuth) in degrees or None (automatic), got {view!r}")
    return v
