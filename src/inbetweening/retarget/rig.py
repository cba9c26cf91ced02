"""The learned retargeter's rig and features (numpy): a **target rig** (a BVH hierarchy of any humanoid topology) driven
by a motion of the source skeleton (the model's, e.g. Bandai-Namco-2's 21 joints).

:class:`TargetRig` holds the target's hierarchy, its bone map (:func:`~inbetweening.runtime.bone_map.detect_bone_map`)
and the analytic :class:`~inbetweening.runtime.retarget.Retarget` between the two; it makes the training pairs
(:meth:`TargetRig.analytic`: the source's motion carried onto the target), the naive baseline
(:meth:`TargetRig.copy_by_slot`: each mapped bone takes the source joint's local rotation as it is), and the network's
features both ways:

- **source** (:meth:`TargetRig.encode_source`), per frame: every joint's local rotation as 6-D (the root's with the
  root's heading, its turn about the vertical, taken out), the root's horizontal velocity in the heading frame, its
  height and the heading's turn to the next frame;
- **target** (:meth:`TargetRig.encode_target` / :meth:`TargetRig.decode`), per frame, in the source's heading frame and
  the source's world and units: the 6-D rotation of every *driven* target bone (the bones the analytic retargeter
  drives; the hips' as its world rotation), the hips' offset from the source's root, and every target joint's
  position relative to the source's root (a position head: it carries the bone-length term; the BVH is built from the
  rotations).  The other bones (fingers, twist leaves, bones above the hips) keep the target rig file's first frame.
"""
from __future__ import annotations

import numpy as np

from inbetweening.data.bvh import BVH
from inbetweening.geometry.quaternion import qframe, qinv, qmul, qrot, quat_to_rot6d, remove_discontinuities
from inbetweening.geometry.skeleton import Skeleton, fk
from inbetweening.runtime.bone_map import BoneMapError, detect_bone_map
from inbetweening.runtime.errors import InbetweenError
from inbetweening.runtime.retarget import Retarget

__all__ = ["FEET", "TargetRig", "heading", "rot6d_to_quat"]

FEET = ("Foot_L", "Toes_L", "Foot_R", "Toes_R")
_X, _Y = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])


def heading(root_q: np.ndarray, forward) -> np.ndarray:
    """The turn about the vertical (Y) of root rotations ``(F, 4)`` whose local ``forward`` axis is the facing:
    ``(F, 4)`` quaternions about +Y."""
    f = qrot(root_q, np.broadcast_to(np.asarray(forward, np.float64), root_q.shape[:-1] + (3,)))
    half = 0.5 * np.arctan2(f[..., 0], f[..., 2])
    zero = np.zeros_like(half)
    return np.stack([np.cos(half), zero, np.sin(half), zero], axis=-1)


def rot6d_to_quat(r: np.ndarray) -> np.ndarray:
    """6-D rotations ``(..., 6)`` (the first two columns of the matrix, :func:`quat_to_rot6d`'s layout; need not be
    orthonormal) -> unit quaternions ``(..., 4)`` wxyz."""
    r = np.asarray(r, np.float64)
    a = np.broadcast_to(_X, r.shape[:-1] + (3,))
    b = np.broadcast_to(_Y, r.shape[:-1] + (3,))
    return qframe(a, b, r[..., :3], r[..., 3:])


def _rep(x: np.ndarray, f: int) -> np.ndarray:
    return np.repeat(np.asarray(x, np.float64)[None], f, axis=0)


class TargetRig:
    """A target rig (``bvh``: its hierarchy; its first frame is the reference pose) for motions of ``source``
    (``forward``: the source root's local facing axis).  ``where`` names the rig in messages.  Raises
    :class:`~inbetweening.runtime.model.InbetweenError` (one line) for a rig that is not a mappable humanoid."""

    def __init__(self, bvh: BVH, source: Skeleton, forward=(0.0, 0.0, 1.0), where: str = "target_rig"):
        self.bvh, self.source, self.forward = bvh, source, np.asarray(forward, np.float64)
        sk = self.skeleton = bvh.skeleton()
        try:
            bone_map = detect_bone_map(sk.names, sk.parents, sk.offsets, where=where)
        except BoneMapError as e:
            raise InbetweenError(str(e).splitlines()[0]) from None
        self.ref_q, self.ref_p = bvh.local_rotations()[0], bvh.local_positions()[0]
        self.ret = Retarget(sk, source, bone_map, reference=self.ref_q, where=where)
        self.movers = [j for j, ch in enumerate(bvh.channels) if any(c.endswith("position") for c in ch)] or [0]
        self.hips = self.ret.rig_slot["Hips"]
        self.driven = [j for j, plan in enumerate(self.ret.rig_plan) if plan[0] != "free"]
        chain = [j for j in range(sk.num_joints) if self._above(self.hips, j)]
        self.mover = max((j for j in chain if j in self.movers), default=self.hips)
        self.feet = [self.ret.rig_slot[s] for s in FEET if s in self.ret.rig_slot]
        self.source_feet = [source.names.index(s) for s in FEET if s in self.ret.rig_slot and s in source.names]
        self.slots = {s: b for s, b in self.ret.rig_slot.items() if s in source.names}
        self.bones = np.array([j for j in range(1, sk.num_joints) if j != self.mover and not self._above(self.mover, j)])
        self.bone_parents = np.array([sk.parents[j] for j in self.bones], dtype=np.int64)
        self.bone_lengths = self.ret.scale * np.linalg.norm(self.ref_p[self.bones], axis=-1)

    def _above(self, j: int, top: int) -> bool:
        """Whether ``top`` is ``j`` or one of its ancestors."""
        while j >= 0:
            if j == top:
                return True
            j = self.skeleton.parents[j]
        return False

    @property
    def name_parents(self) -> tuple[tuple[str, ...], tuple[int, ...]]:
        return self.skeleton.names, self.skeleton.parents

    # ------------------------------------------------------------------ whole motions
    def analytic(self, root: np.ndarray, local_q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The source's ``root (F, 3), local_q (F, Js, 4)`` carried onto the target by the analytic retargeter ->
        the target's ``local_q (F, J, 4), local_p (F, J, 3)``."""
        f = len(root)
        return self.ret.to_rig(root, local_q, _rep(self.ref_q, f), _rep(self.ref_p, f), self.movers)

    def copy_by_slot(self, root: np.ndarray, local_q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The naive baseline: each mapped target bone takes the source joint's local rotation unchanged (no rest-pose
        or world alignment), the other bones the reference frame; the hips are placed where the analytic retargeter
        puts them."""
        f = len(root)
        lq = _rep(self.ref_q, f)
        for slot, b in self.slots.items():
            lq[:, b] = local_q[:, self.source.names.index(slot)]
        target = qrot(np.broadcast_to(qinv(self.ret.world), root.shape[:-1] + (4,)), root) / self.ret.scale
        return lq, self._place_hips(lq, _rep(self.ref_p, f), target)

    def _place_hips(self, lq: np.ndarray, lp: np.ndarray, target: np.ndarray) -> np.ndarray:
        """``lp`` with the mover's translation set so that the hips stand at ``target`` (rig world, rig units)."""
        gq, gp = fk(lq, lp, self.skeleton.parents)
        shift = target - gp[:, self.hips]
        p = self.skeleton.parents[self.mover]
        lp = lp.copy()
        lp[:, self.mover] += shift if p < 0 else qrot(qinv(gq[:, p]), shift)
        return lp

    def positions(self, local_q: np.ndarray, local_p: np.ndarray) -> np.ndarray:
        """Global joint positions ``(F, J, 3)`` of a target motion in the source's world and units."""
        gp = fk(local_q, local_p, self.skeleton.parents)[1]
        return self.ret.scale * qrot(np.broadcast_to(self.ret.world, gp.shape[:-1] + (4,)), gp)

    # ------------------------------------------------------------------ features
    def source_dim(self) -> int:
        return self.source.num_joints * 6 + 4

    def target_dim(self) -> int:
        return len(self.driven) * 6 + 3 + self.skeleton.num_joints * 3

    def _frame(self, root: np.ndarray, local_q: np.ndarray) -> np.ndarray:
        return qinv(heading(local_q[:, 0], self.forward))

    def encode_source(self, root: np.ndarray, local_q: np.ndarray) -> np.ndarray:
        """``root (F, 3), local_q (F, Js, 4) -> (F, Js*6 + 4)`` float32 (module docstring)."""
        iy = self._frame(root, local_q)
        q = local_q.copy()
        q[:, 0] = qmul(iy, q[:, 0])
        step = np.diff(root, axis=0, append=root[-1:] + (root[-1:] - root[-2:-1] if len(root) > 1 else 0.0))
        vel = qrot(iy, step)[:, [0, 2]]
        turn = qmul(iy[1:], qinv(iy[:-1])) if len(root) > 1 else np.zeros((0, 4))
        yaw_rate = -2.0 * np.arctan2(turn[:, 2], turn[:, 0])
        yaw_rate = np.concatenate([yaw_rate, yaw_rate[-1:] if len(yaw_rate) else [0.0]])
        return np.concatenate([quat_to_rot6d(q).reshape(len(root), -1), vel, root[:, 1:2], yaw_rate[:, None]],
                              axis=1).astype(np.float32)

    def encode_target(self, local_q: np.ndarray, local_p: np.ndarray, root: np.ndarray,
                      source_q: np.ndarray) -> np.ndarray:
        """The target's ``local_q (F, J, 4), local_p (F, J, 3)`` in the frame of the source's ``root, source_q`` ->
        ``(F, len(driven)*6 + 3 + J*3)`` float32 (module docstring)."""
        f = len(root)
        iy = self._frame(root, source_q)
        gq = fk(local_q, local_p, self.skeleton.parents)[0]
        q = local_q[:, self.driven].copy()
        world = np.broadcast_to(self.ret.world, (f, 4))
        q[:, self.driven.index(self.hips)] = qmul(iy, qmul(world, gq[:, self.hips]))
        pos = qrot(iy[:, None], self.positions(local_q, local_p) - root[:, None])
        return np.concatenate([quat_to_rot6d(q).reshape(f, -1), pos[:, self.hips], pos.reshape(f, -1)],
                              axis=1).astype(np.float32)

    def decode(self, y: np.ndarray, root: np.ndarray, source_q: np.ndarray):
        """Features ``y (F, target_dim)`` in the frame of the source's motion -> the target's ``local_q (F, J, 4)``,
        ``local_p (F, J, 3)`` and the position head's joint positions ``(F, J, 3)`` (source world and units)."""
        f, nd = len(root), len(self.driven)
        yaw = qinv(self._frame(root, source_q))
        y = np.asarray(y, np.float64)
        q = rot6d_to_quat(y[:, : nd * 6].reshape(f, nd, 6))
        hips_world = qmul(qinv(np.broadcast_to(self.ret.world, (f, 4))), qmul(yaw, q[:, self.driven.index(self.hips)]))
        lq = _rep(self.ref_q, f)
        lq[:, self.driven] = q
        p = self.skeleton.parents[self.hips]
        if p >= 0:  # the bones above the hips stand as in the reference frame
            top = fk(lq[:1], self.ref_p[None], self.skeleton.parents)[0][0, p]
            hips_world = qmul(np.broadcast_to(qinv(top), (f, 4)), hips_world)
        lq[:, self.hips] = hips_world
        lq = remove_discontinuities(lq, axis=0)
        hips_pos = root + qrot(yaw, y[:, nd * 6 : nd * 6 + 3])
        target = qrot(np.broadcast_to(qinv(self.ret.world), (f, 4)), hips_pos) / self.ret.scale
        lp = self._place_hips(lq, _rep(self.ref_p, f), target)
        head = root[:, None] + qrot(yaw[:, None], y[:, nd * 6 + 3 :].reshape(f, -1, 3))
        return lq, lp, head
