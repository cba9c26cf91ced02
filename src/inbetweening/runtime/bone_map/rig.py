"""The rig the map is found on (:class:`_Rig`: names, hierarchy, rest positions, canonical names) and the checks of
a set of slots against its hierarchy, shared by the name pass, the structural fallback and the detection."""
from __future__ import annotations

import numpy as np

from .names import canonical
from .slots import SLOT_PARENTS, SLOTS


# --------------------------------------------------------------------------------------------
# The rig
# --------------------------------------------------------------------------------------------
class _Rig:
    def __init__(self, names, parents, offsets):
        self.names = [str(n) for n in names]
        self.parents = [int(p) for p in np.asarray(parents).reshape(-1)]
        J = len(self.names)
        off = np.asarray(offsets, dtype=np.float64).reshape(-1, 3) if J else np.zeros((0, 3))
        if len(self.parents) != J or off.shape[0] != J:
            raise ValueError(f"bone map: {J} names, {len(self.parents)} parents, {off.shape[0]} offsets")
        if J and (self.parents[0] != -1 or any(not (-1 <= p < j) for j, p in enumerate(self.parents))):
            raise ValueError("bone map: parents must be -1 for a root and point to earlier joints otherwise")
        self.J = J
        self.children: list[list[int]] = [[] for _ in range(J)]
        self.depth = [0] * J
        self.pos = np.zeros((J, 3))
        for j, p in enumerate(self.parents):
            if p >= 0:
                self.children[p].append(j)
                self.depth[j] = self.depth[p] + 1
                self.pos[j] = self.pos[p] + off[j]
            else:
                self.pos[j] = off[j]
        self.canon = [canonical(n) for n in self.names]
        self.index = {}
        for j, n in enumerate(self.names):
            self.index.setdefault(n, j)

    def is_below(self, a: int, b: int) -> bool:
        """Whether joint ``a`` is a strict descendant of joint ``b``."""
        a = self.parents[a]
        while a >= 0:
            if a == b:
                return True
            a = self.parents[a]
        return False

    def subtree(self, j: int) -> list[int]:
        out, todo = [], [j]
        while todo:
            k = todo.pop()
            out.append(k)
            todo += self.children[k]
        return out

    def lca(self, a: int, b: int) -> int:
        up = set()
        while a >= 0:
            up.add(a)
            a = self.parents[a]
        while b >= 0 and b not in up:
            b = self.parents[b]
        return b


def _consistent(rig: _Rig, slots: dict[str, int]) -> dict[str, int]:
    """``slots`` less every slot whose bone is not below the bone of its nearest mapped slot ancestor, or repeats."""
    out: dict[str, int] = {}
    for s in SLOTS:
        if s not in slots or slots[s] in out.values():
            continue
        up = SLOT_PARENTS[s]
        while up is not None and up not in out:
            up = SLOT_PARENTS[up]
        if up is None or rig.is_below(slots[s], out[up]):
            out[s] = slots[s]
    return out


def _violations(rig: _Rig, slots: dict[str, int]) -> list[str]:
    out, seen = [], {}
    for s in SLOTS:
        if s not in slots:
            continue
        j = slots[s]
        if j in seen:
            out.append(f"bone '{rig.names[j]}' is in two slots, {seen[j]} and {s}")
            continue
        seen[j] = s
        up = SLOT_PARENTS[s]
        while up is not None and up not in slots:
            up = SLOT_PARENTS[up]
        if up is not None and not rig.is_below(j, slots[up]):
            out.append(f"{s} '{rig.names[j]}' is not below {up} '{rig.names[slots[up]]}'")
    return out
