"""Left/right mirror maps: pairs of joint names ``(left, right)`` for mirror augmentation.

A map is derived from joint-name conventions (:data:`SIDE_MARKERS`: LAFAN1's ``LeftArm``/``RightArm``
prefixes, Bandai-Namco's ``Hand_L``/``Hand_R`` suffixes) and validated against a skeleton: every pair names
two joints of it, the right name is the left one with its side marker swapped, no joint is in two pairs
(so the joint permutation is an involution), and no joint with a side marker whose counterpart exists is
left out.
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

from inbetweening.data.errors import DatasetError

# (left marker, right marker, where the marker sits in the name)
SIDE_MARKERS: tuple[tuple[str, str, str], ...] = (
    ("Left", "Right", "prefix"), ("left", "right", "prefix"), ("L_", "R_", "prefix"),  # LAFAN1, Mixamo, Maya
    ("_L", "_R", "suffix"), ("_l", "_r", "suffix"), (".L", ".R", "suffix"), (".l", ".r", "suffix"),  # BN, UE, Blender
)  # checked after a namespace (``mixamorig:``), which is kept

MirrorMap = tuple[tuple[str, str], ...]

__all__ = ["SIDE_MARKERS", "MirrorMap", "derive_mirror", "fit_mirror_frames", "mirror_motion", "mirror_permutation",
           "reflect_rotation", "side_of",
           "side_pairs", "swap_side",
           "validate_mirror"]


def _namespace(name: str) -> tuple[str, str]:
    """``("mixamorig:", "LeftArm")`` for ``"mixamorig:LeftArm"``; ``("", name)`` without a namespace."""
    i = name.rfind(":")
    return name[: i + 1], name[i + 1 :]


def side_of(name: str) -> str | None:
    """``"left"``, ``"right"`` or ``None`` (no side marker) for a joint name."""
    name = _namespace(name)[1]
    for left, right, where in SIDE_MARKERS:
        has = str.startswith if where == "prefix" else str.endswith
        if has(name, left) and len(name) > len(left):
            return "left"
        if has(name, right) and len(name) > len(right):
            return "right"
    return None


def swap_side(name: str) -> str | None:
    """The name with its side marker swapped (``LeftArm`` -> ``RightArm``, ``Hand_R`` -> ``Hand_L``), or ``None``."""
    ns, name = _namespace(name)
    for left, right, where in SIDE_MARKERS:
        for a, b in ((left, right), (right, left)):
            if where == "prefix" and name.startswith(a) and len(name) > len(a):
                return ns + b + name[len(a):]
            if where == "suffix" and name.endswith(a) and len(name) > len(a):
                return ns + name[: -len(a)] + b
    return None


def side_pairs(left_pattern: str, parts: str | Iterable[str]) -> MirrorMap:
    """Pairs from a left-side name pattern: ``side_pairs("Left{}", "Arm Hand")`` -> ``(("LeftArm", "RightArm"), ...)``."""
    parts = parts.split() if isinstance(parts, str) else list(parts)
    pairs = []
    for part in parts:
        left = left_pattern.format(part)
        right = swap_side(left)
        if side_of(left) != "left" or right is None:
            raise ValueError(f"side_pairs: {left!r} has no left side marker of {SIDE_MARKERS}")
        pairs.append((left, right))
    return tuple(pairs)


def derive_mirror(names: Sequence[str]) -> MirrorMap:
    """Every ``(left, right)`` pair of a skeleton's joint names that the side markers identify, in joint order."""
    present = set(names)
    return tuple((n, swap_side(n)) for n in names if side_of(n) == "left" and swap_side(n) in present)


def validate_mirror(pairs: Iterable[Sequence[str]], names: Sequence[str], where: str = "mirror map") -> MirrorMap:
    """Check a mirror map against a skeleton's joint names; return it as a tuple of pairs.

    Raises :class:`DatasetError` (message starting with ``where``) naming the first bad pair or missing joint.
    """
    out: list[tuple[str, str]] = []
    present, used = set(names), set()
    for pair in pairs:
        if len(pair) != 2:
            raise DatasetError(f"{where}: {tuple(pair)!r} is not a (left, right) pair of joint names")
        left, right = str(pair[0]), str(pair[1])
        for n in (left, right):
            if n not in present:
                raise DatasetError(f"{where}: joint {n!r} of pair ({left!r}, {right!r}) is not in the skeleton")
            if n in used:
                raise DatasetError(f"{where}: joint {n!r} is in more than one pair")
            used.add(n)
        if side_of(left) != "left" or swap_side(left) != right:
            raise DatasetError(f"{where}: ({left!r}, {right!r}) is not a left joint and its right counterpart")
        out.append((left, right))
    missing = [a for a, _ in derive_mirror(names) if a not in used]
    if missing:
        raise DatasetError(f"{where}: left/right joints {missing} have a counterpart in the skeleton but no pair")
    return tuple(out)


def mirror_permutation(pairs: Iterable[Sequence[str]], names: Sequence[str]) -> np.ndarray:
    """``(J,)`` int64: joint ``j`` of a mirrored pose takes joint ``perm[j]``'s data; ``perm[perm] == arange(J)``."""
    index = {n: j for j, n in enumerate(names)}
    perm = np.arange(len(names))
    for left, right in validate_mirror(pairs, names):
        perm[index[left]], perm[index[right]] = index[right], index[left]
    return perm



# the 24 rotations that permute the coordinate axes up to sign, wxyz (candidate relations between mirrored joint frames)
def _axis_rotations() -> np.ndarray:
    import itertools

    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            m = np.zeros((3, 3))
            m[range(3), perm] = signs
            if np.linalg.det(m) > 0:
                out.append(_quat_from_matrix(m))
    return np.asarray(out)


def _quat_from_matrix(m: np.ndarray) -> np.ndarray:
    w = np.sqrt(max(0.0, 1.0 + m[0, 0] + m[1, 1] + m[2, 2])) / 2
    x = np.sqrt(max(0.0, 1.0 + m[0, 0] - m[1, 1] - m[2, 2])) / 2
    y = np.sqrt(max(0.0, 1.0 - m[0, 0] + m[1, 1] - m[2, 2])) / 2
    z = np.sqrt(max(0.0, 1.0 - m[0, 0] - m[1, 1] + m[2, 2])) / 2
    x = np.copysign(x, m[2, 1] - m[1, 2])
    y = np.copysign(y, m[0, 2] - m[2, 0])
    z = np.copysign(z, m[1, 0] - m[0, 1])
    q = np.array([w, x, y, z])
    return q / np.linalg.norm(q)


def reflect_rotation(q, axis: int = 0):
    """The rotation ``S R S`` of a rotation ``R`` seen in a mirror (``S`` negates coordinate ``axis``): ``w`` and the
    ``axis`` component kept, the other two negated.  ``(..., 4) -> (..., 4)`` wxyz, numpy or torch."""
    sign = [1.0, -1.0, -1.0, -1.0]
    sign[1 + axis] = 1.0
    if hasattr(q, "new_tensor"):
        return q * q.new_tensor(sign)
    return np.asarray(q) * np.asarray(sign)


def mirror_motion(root, local_q, perm, frames, parents, axis: int = 0):
    """Left/right mirror image of a motion across the world plane normal to ``axis`` (numpy, float64).

    ``root (..., 3), local_q (..., J, 4)`` wxyz; ``perm`` from :func:`mirror_permutation`; ``frames (J, 4)`` from
    :func:`fit_mirror_frames` (identity for skeletons whose joint frames are mirror images of each other).  Joint
    ``j`` of the mirror takes joint ``perm[j]``'s rotation: global ``G'_j = refl(G_perm[j]) A_j``, so local
    ``L'_j = A_parent^-1 refl(L_perm[j]) A_j``; the root position's ``axis`` coordinate is negated.  The forward
    kinematics of the result are the mirrored global positions (exactly, for a symmetric skeleton).
    """
    from inbetweening.geometry.quaternion import qinv, qmul

    root = np.array(root, dtype=np.float64, copy=True)
    root[..., axis] *= -1.0
    a = np.asarray(frames, dtype=np.float64)
    par = np.asarray(parents)
    a_parent = np.where((par >= 0)[:, None], a[np.maximum(par, 0)], np.array([1.0, 0.0, 0.0, 0.0]))
    q = reflect_rotation(np.asarray(local_q, dtype=np.float64)[..., np.asarray(perm), :], axis)
    return root, qmul(qmul(qinv(a_parent), q), a)


def fit_mirror_frames(offsets, parents, perm, sample_q, axis: int = 0, tol: float = 0.05) -> tuple[np.ndarray, float]:
    """How each mirrored joint's frame relates to its counterpart's: ``(A (J, 4) wxyz, asymmetry)``.

    Skeletons exported from DCC tools give left and right joints frames that are not plain mirror images (Bandai-Namco:
    every bone along its local +X or -X).  For each joint ``A_j`` is one of the 24 axis-permuting rotations: those that
    map its children's offsets onto the mirrored offsets of its counterpart's children (``A_j o_c = S o_perm[c]``, which
    makes the mirrored positions exact) are candidates, and among them the one whose mirrored local rotations lie
    closest to the joint's own rotations in ``sample_q (N, J, 4)`` (training frames) wins; joints are settled parents
    first, a right joint with its left one (``A_R = refl(A_L^-1)``, so that mirroring twice is the identity).
    ``asymmetry``: the largest offset mismatch of the chosen frames relative to the longest offset (0 for an
    exactly symmetric skeleton).  ``ValueError`` when no frame fits within ``tol`` (the skeleton is not symmetric).
    """
    from inbetweening.geometry.quaternion import qinv, qmul

    off = np.asarray(offsets, dtype=np.float64)
    par, perm = list(parents), np.asarray(perm)
    j_count = len(par)
    scale = max(float(np.linalg.norm(off, axis=-1).max()), 1e-12)
    cands = _axis_rotations()
    s = np.ones(3)
    s[axis] = -1.0
    sample = np.asarray(sample_q, dtype=np.float64)
    refl = reflect_rotation(sample[:, perm], axis)
    frames = np.tile(np.array([1.0, 0.0, 0.0, 0.0]), (j_count, 1))
    worst = 0.0
    from inbetweening.geometry.quaternion import qrot

    for j in range(j_count):  # parents come before children
        if perm[j] < j:  # settled with its counterpart
            continue
        kids = [c for c in range(j_count) if par[c] == j]
        if kids:
            err = np.array([max(float(np.abs(qrot(np.broadcast_to(c4, (1, 4)), off[c][None])[0] - s * off[perm[c]]).max())
                                for c in kids) for c4 in cands]) / scale
        else:
            err = np.zeros(len(cands))
        ok = err <= err.min() + 1e-6 + tol * 0.1
        if perm[j] == j:  # a middle joint mirrors onto itself: mirroring twice must give its rotation back
            twice = np.abs(qmul(reflect_rotation(cands, axis), cands)[:, 0])
            ok &= twice > 1 - 1e-9
        if err.min() > tol:
            raise ValueError(f"joint {j}: the skeleton is not left/right symmetric (offset mismatch {err.min():.1%})")
        a_p = frames[par[j]] if par[j] >= 0 else np.array([1.0, 0.0, 0.0, 0.0])
        # how close each candidate's mirrored rotations come to the joint's own (principal direction of its quats)
        own = sample[:, j]
        mean = np.linalg.eigh(own.T @ own)[1][:, -1]
        scores = []
        for c4 in cands:
            mq = qmul(qmul(qinv(a_p)[None], refl[:, j]), c4[None])
            scores.append(float(np.abs(mq @ mean).mean()))
        scores = np.where(ok, np.asarray(scores), -np.inf)
        best = int(np.argmax(scores))
        frames[j] = cands[best]
        frames[perm[j]] = reflect_rotation(qinv(cands[best]), axis)  # so that mirroring twice is the identity
        worst = max(worst, float(err[best]))
    return frames, worst
