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
SIDE_MARKERS: tuple[tuple[str, str, str], ...] = (("Left", "Right", "prefix"), ("_L", "_R", "suffix"))

MirrorMap = tuple[tuple[str, str], ...]

__all__ = ["SIDE_MARKERS", "MirrorMap", "derive_mirror", "mirror_permutation", "side_of", "side_pairs", "swap_side",
           "validate_mirror"]


def side_of(name: str) -> str | None:
    """``"left"``, ``"right"`` or ``None`` (no side marker) for a joint name."""
    for left, right, where in SIDE_MARKERS:
        has = str.startswith if where == "prefix" else str.endswith
        if has(name, left) and len(name) > len(left):
            return "left"
        if has(name, right) and len(name) > len(right):
            return "right"
    return None


def swap_side(name: str) -> str | None:
    """The name with its side marker swapped (``LeftArm`` -> ``RightArm``, ``Hand_R`` -> ``Hand_L``), or ``None``."""
    for left, right, where in SIDE_MARKERS:
        for a, b in ((left, right), (right, left)):
            if where == "prefix" and name.startswith(a) and len(name) > len(a):
                return b + name[len(a):]
            if where == "suffix" and name.endswith(a) and len(name) > len(a):
                return name[: -len(a)] + b
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
