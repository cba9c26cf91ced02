"""Skeleton description and forward / inverse kinematics (numpy and torch).

A skeleton is a tree of ``J`` joints listed so that every parent comes before its children
(``parents[0] == -1`` is the root).  Local data per frame: rotations ``(..., J, 4)`` wxyz and
positions ``(..., J, 3)`` (the root's is its global position; the others are normally the bone
offsets).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from inbetweening.geometry.arrays import Array, is_tensor, torch
from inbetweening.geometry.quaternion import qinv, qmul, qrot


def _cat_joints(parts: list) -> Array:
    if is_tensor(parts[0]):
        return torch.cat(parts, dim=-2)
    return np.concatenate(parts, axis=-2)


@lru_cache(maxsize=64)
def _levels(parents: tuple[int, ...]) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
    """The joints below the root by depth: ``((joints, their parents), ...)`` for depth 1, 2, ..."""
    depth = [0] * len(parents)
    for j in range(1, len(parents)):
        depth[j] = depth[parents[j]] + 1
    return tuple((np.array(js), np.array([parents[j] for j in js]))
                 for js in ([j for j in range(len(parents)) if depth[j] == d] for d in range(1, max(depth, default=0) + 1)))


def fk(local_q: Array, local_p: Array, parents) -> tuple[Array, Array]:
    """Forward kinematics.  ``(..., J, 4), (..., J, 3) -> global (..., J, 4), (..., J, 3)``.

    Works for numpy arrays and torch tensors alike (autograd flows through the torch path).  Both go level by level:
    every joint of one depth in one product, the same arithmetic per joint, bit for bit, as joint by joint, with a
    handful of operations per level instead of per joint (in an exported ONNX graph, a few hundred nodes fewer).
    """
    if not is_tensor(local_q) and not is_tensor(local_p):
        local_q, local_p = np.asarray(local_q), np.asarray(local_p)
        shape = np.broadcast_shapes(local_q.shape[:-1], local_p.shape[:-1])
        lq, lp = np.broadcast_to(local_q, shape + (4,)), np.broadcast_to(local_p, shape + (3,))
        gq = np.empty(shape + (4,), np.result_type(lq, np.float16))  # the dtypes the products give, as joint by joint
        gp = np.empty(shape + (3,), np.result_type(lq, lp, np.float16))
        gq[..., 0, :], gp[..., 0, :] = lq[..., 0, :], lp[..., 0, :]
        for js, ps in _levels(tuple(int(p) for p in parents)):
            pq = gq[..., ps, :]
            gp[..., js, :] = qrot(pq, lp[..., js, :]) + gp[..., ps, :]
            gq[..., js, :] = qmul(pq, lq[..., js, :])
        return gq, gp
    levels = _levels(tuple(int(p) for p in parents))
    gq, gp = [local_q[..., :1, :]], [local_p[..., :1, :]]  # per level: the joints of that depth
    at = {0: 0}  # joint -> its place in its level
    for js, ps in levels:
        up, js = [at[int(p)] for p in ps], js.tolist()  # the parents, all one level up
        pq, pp = gq[-1][..., up, :], gp[-1][..., up, :]
        gp.append(qrot(pq, local_p[..., js, :]) + pp)
        gq.append(qmul(pq, local_q[..., js, :]))
        at.update({j: i for i, j in enumerate(js)})
    order = [0] + [int(j) for js, _ in levels for j in js]
    gq, gp = _cat_joints(gq), _cat_joints(gp)
    if order != sorted(order):  # back to the joints' order
        back = np.argsort(order).tolist()
        gq, gp = gq[..., back, :], gp[..., back, :]
    return gq, gp


def ik(global_q: Array, global_p: Array, parents) -> tuple[Array, Array]:
    """Inverse of :func:`fk`.  ``(..., J, 4), (..., J, 3) -> local (..., J, 4), (..., J, 3)``."""
    par = list(parents[1:])
    inv_parent = qinv(global_q[..., par, :])
    local_q = _cat_joints([global_q[..., :1, :], qmul(inv_parent, global_q[..., 1:, :])])
    local_p = _cat_joints([global_p[..., :1, :], qrot(inv_parent, global_p[..., 1:, :] - global_p[..., par, :])])
    return local_q, local_p


@dataclass(frozen=True)
class Skeleton:
    """Joint names, parent indices (root = -1, parents before children) and bone offsets ``(J, 3)``."""

    names: tuple[str, ...]
    parents: tuple[int, ...]
    offsets: np.ndarray = field(repr=False)

    def __post_init__(self):
        object.__setattr__(self, "names", tuple(self.names))
        object.__setattr__(self, "parents", tuple(int(p) for p in self.parents))
        object.__setattr__(self, "offsets", np.asarray(self.offsets, dtype=np.float64).reshape(-1, 3))
        n = len(self.names)
        if len(self.parents) != n or self.offsets.shape[0] != n:
            raise ValueError(f"Skeleton: {n} names, {len(self.parents)} parents, {self.offsets.shape[0]} offsets")
        if n == 0 or self.parents[0] != -1:
            raise ValueError("Skeleton: joint 0 must be the root (parent -1)")
        for j, p in enumerate(self.parents[1:], start=1):
            if not 0 <= p < j:
                raise ValueError(f"Skeleton: joint {self.names[j]!r} has parent {p}; parents must come first")

    @property
    def num_joints(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        return self.names.index(name)

    def children(self, j: int) -> list[int]:
        return [c for c, p in enumerate(self.parents) if p == j]

    def adjacency(self, hops: int = 1, self_loops: bool = True) -> np.ndarray:
        """Joint relation matrix ``(J, J)``: 1 where joints are within ``hops`` bones of each other.

        With ``hops=1`` this is the parent/child relation matrix M of the method (plus the
        diagonal when ``self_loops``).
        """
        n = self.num_joints
        a = np.eye(n, dtype=np.float32)
        for j, p in enumerate(self.parents):
            if p >= 0:
                a[j, p] = a[p, j] = 1.0
        reach = np.eye(n, dtype=np.float32)
        for _ in range(max(int(hops), 0)):
            reach = np.minimum(reach @ a, 1.0)
        if not self_loops:
            np.fill_diagonal(reach, 0.0)
        return reach

    def bone_pairs(self) -> np.ndarray:
        """``(J-1, 2)`` (child, parent) index pairs."""
        return np.array([(j, p) for j, p in enumerate(self.parents) if p >= 0], dtype=np.int64).reshape(-1, 2)

    def local_positions(self, root_pos: Array) -> Array:
        """Root positions ``(..., 3)`` -> local positions ``(..., J, 3)`` with the offsets for non-root joints."""
        if is_tensor(root_pos):
            off = torch.as_tensor(self.offsets, dtype=root_pos.dtype, device=root_pos.device)
            off = off.expand(root_pos.shape[:-1] + off.shape).clone()
            off[..., 0, :] = root_pos
            return off
        off = np.broadcast_to(self.offsets, root_pos.shape[:-1] + self.offsets.shape).copy()
        off[..., 0, :] = root_pos
        return off

    def fk(self, local_q: Array, local_p: Array) -> tuple[Array, Array]:
        return fk(local_q, local_p, self.parents)

    def pose(self, root: Array, local_q: Array) -> tuple[Array, Array]:
        """Global rotations and positions of a pose given by its root positions and local rotations (the bone
        offsets for the other joints).  ``root (..., 3), local_q (..., J, 4) -> (..., J, 4), (..., J, 3)``."""
        return fk(local_q, self.local_positions(root), self.parents)

    def ik(self, global_q: Array, global_p: Array) -> tuple[Array, Array]:
        return ik(global_q, global_p, self.parents)

    def to_dict(self) -> dict:
        """Plain-value form (lists of str/int/float) for checkpoints and JSON."""
        return {"names": list(self.names), "parents": list(self.parents), "offsets": self.offsets.tolist()}

    @classmethod
    def from_dict(cls, d: dict) -> Skeleton:
        return cls(tuple(d["names"]), tuple(d["parents"]), np.asarray(d["offsets"], dtype=np.float64))

    def same_topology(self, other: Skeleton) -> bool:
        return self.names == other.names and self.parents == other.parents

    def __eq__(self, other) -> bool:  # offsets are an array: compare explicitly
        return isinstance(other, Skeleton) and self.same_topology(other) and np.allclose(self.offsets, other.offsets)

    def __hash__(self) -> int:
        return hash((self.names, self.parents))
