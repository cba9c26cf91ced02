"""Retargeting between a humanoid rig (the animator's character) and the model's skeleton: the runtime's stage that
lets a model fill any humanoid whose bones a :class:`~inbetweening.runtime.bone_map.BoneMap` names.

Both skeletons are first put in one reference pose, a **T-pose** built for each from its rest pose: the body chain
(hips to head) up, the legs down, the feet forward, the arms out to the sides, each bone turned from its rest
direction by the shortest rotation (no twist added: a rig's own rest twists are kept), the hips and the bone the arms
hang from turned as a whole so the legs and the shoulders lie across (left to +X, up +Y, forward +Z in the model's
world).  The model's zero pose is degenerate (every bone along its parent's X axis), its T-pose is what its data's
motions are measured against here.  A rig's rest pose may be a T-pose, an A-pose, Z up or Y up, in any unit.

A motion then moves across as **world rotations from the T-pose**: a mapped bone's global rotation ``G`` is
``W T`` with ``T`` its T-pose rotation, and the other skeleton's bone takes the same ``W`` (turned into its world).
Chains of different lengths are distributed: a body bone (spine, neck) that one skeleton has and the other lacks
takes the rotation interpolated between its chain's mapped neighbours by its place along the chain; a bone inside a
limb (a twist segment) moves rigidly with the mapped bone above it; a missing clavicle follows the chest, missing
toes the foot.  The root (the hips) moves by the rig's hip height: ``p_model = s F p_rig``.  Bones without a slot
(fingers, twist leaves, face, props) keep their own local values, which the runtime interpolates between the keys.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from inbetweening.geometry.quaternion import (
    euler_to_quat_np,
    qframe,
    qinv,
    qmul,
    qrot,
    qswing,
    quat_to_euler_np,
    remove_discontinuities,
    slerp_np,
)
from inbetweening.geometry.skeleton import Skeleton, fk

from .model import InbetweenError

if TYPE_CHECKING:
    from .bone_map import BoneMap

__all__ = ["BODY", "Retarget", "rest_pose", "tpose", "world_up"]

BODY = ("Hips", "Spine", "Chest", "Neck", "Head")
ARM = ("Shoulder", "UpperArm", "LowerArm", "Hand")
LEG = ("UpperLeg", "LowerLeg", "Foot", "Toes")
UP, LEFT, FORWARD = np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])
EULER_ORDER = "zxy"  # the rotation channels of the shipped models' training files (Bandai-Namco-2)


def euler_sign(q: np.ndarray, order: str = EULER_ORDER) -> np.ndarray:
    """Quaternions ``(..., 4)`` with the sign a BVH file's Euler angles give them (``order``): the network reads
    quaternions as numbers, and ``q`` and ``-q`` are different inputs to it; a key read from a file of the model's
    skeleton has this sign, a retargeted one gets it here."""
    back = euler_to_quat_np(quat_to_euler_np(q, order), order)
    return np.where(((q * back).sum(-1) < 0)[..., None], -q, q)


def _side_chains() -> list[tuple[tuple[str, ...], np.ndarray, np.ndarray]]:
    """``(slots, direction of the segments, direction of the last segment)`` of the four limbs."""
    out = []
    for side, sign in (("L", 1.0), ("R", -1.0)):
        out.append((tuple(f"{s}_{side}" for s in ARM), sign * LEFT, sign * LEFT))
        out.append((tuple(f"{s}_{side}" for s in LEG), -UP, FORWARD))
    return out


def _path(parents, top: int, bottom: int) -> list[int]:
    """Joints from ``top`` down to ``bottom`` (both included); ``[]`` when ``bottom`` is not below ``top``."""
    path = [bottom]
    while path[-1] != top:
        p = parents[path[-1]]
        if p < 0:
            return []
        path.append(p)
    return path[::-1]


@dataclass(frozen=True)
class _Chains:
    """A skeleton's chains: per joint the chain it belongs to (``body`` or a limb's first slot), the joint it aims at
    along the chain, the direction of that segment in the T-pose, and the chains' joints in order."""

    aim: dict[int, int]
    direction: dict[int, np.ndarray]
    paths: dict[str, list[int]]


def _chains(parents, slot_of: dict[str, int]) -> _Chains:
    aim, direction, paths = {}, {}, {}
    body = [slot_of[s] for s in BODY if s in slot_of]
    path = _path(parents, body[0], body[-1])
    paths["body"] = path
    for a, b in zip(path, path[1:]):
        aim[a], direction[a] = b, UP
    for slots, seg, last in _side_chains():
        present = [slot_of[s] for s in slots if s in slot_of]
        path = _path(parents, present[0], present[-1]) if len(present) > 1 else present
        paths[slots[0]] = path
        foot = slot_of.get(slots[2]) if slots[1].startswith("LowerLeg") else None
        for a, b in zip(path, path[1:]):
            aim[a] = b  # the leg's bones at or below the ankle point forward, the others along the limb
            direction[a] = last if foot is not None and _below(parents, a, foot) else seg
    return _Chains(aim, direction, paths)


def _aims(ch: _Chains, rest: np.ndarray) -> dict[int, int]:
    """Per chain joint the joint it points at: the next joint along its chain that does not sit on it (a zero-length
    bone, such as CMU's ``LowerBack`` on ``Hips``, points nowhere; the bone before it points past it)."""
    scale = max(float(np.ptp(rest, axis=0).max()), 1e-9)
    aim = {}
    for path in ch.paths.values():
        for i, a in enumerate(path[:-1]):
            nxt = next((b for b in path[i + 1 :] if np.linalg.norm(rest[b] - rest[a]) > 1e-6 * scale), None)
            if nxt is not None and a in ch.aim:
                aim[a] = nxt
    return aim


def _below(parents, j: int, top: int) -> bool:
    """Whether ``j`` is ``top`` or below it."""
    while j >= 0:
        if j == top:
            return True
        j = parents[j]
    return False


def rest_pose(skeleton: Skeleton, slot_of: dict[str, int], reference: np.ndarray | None = None):
    """``(global rotations (J, 4), positions (J, 3))`` of the rest pose: every local rotation the identity (BVH's rest),
    except the bones above the hips, which take ``reference`` (local rotations ``(J, 4)``, e.g. a key frame's): a
    static top bone that turns the whole character (an armature's axis change) is part of where the body stands."""
    n = skeleton.num_joints
    local = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    if reference is not None:
        above = _path(skeleton.parents, 0, slot_of["Hips"])[:-1]
        local[above] = np.asarray(reference, dtype=np.float64)[above]
    return fk(local, skeleton.offsets, skeleton.parents)


def tpose(skeleton: Skeleton, slot_of: dict[str, int], basis: np.ndarray | None = None,
          reference: np.ndarray | None = None) -> np.ndarray:
    """Global rotations ``(J, 4)`` of the skeleton in its T-pose (module docstring) in its own world, whose body frame
    is ``basis`` (columns: left, up, forward; default: the model's world, the identity), built from its rest pose
    (:func:`rest_pose`, ``reference`` for the bones above the hips)."""
    basis = np.eye(3) if basis is None else basis
    parents = skeleton.parents
    rq, rest = rest_pose(skeleton, slot_of, reference)
    ch = _chains(parents, slot_of)
    hips = slot_of["Hips"]
    arm_root = parents[ch.paths["Shoulder_L"][0]]
    lateral_hips = rest[slot_of["UpperLeg_L"]] - rest[slot_of["UpperLeg_R"]]
    lateral_arms = rest[ch.paths["Shoulder_L"][0]] - rest[ch.paths["Shoulder_R"][0]]
    full = {hips: lateral_hips, arm_root: lateral_arms}
    aim = _aims(ch, rest)
    t = rq.copy()
    for j in range(len(parents)):
        p = parents[j]
        if p >= 0:
            t[j] = qmul(t[p], qmul(qinv(rq[p]), rq[j]))  # the parent's T-pose turn, the rest's local rotation
        if j in aim:
            d = rest[aim[j]] - rest[j]  # the rest direction (world)
            want = basis @ ch.direction[j]
            if j in full:
                t[j] = qmul(qframe(d, full[j], want, basis @ LEFT), rq[j])
            else:
                # a bone pointing (nearly) opposite its T-pose direction turns about the body's forward axis, not about
                # whichever axis rounding picks (the model's zero pose has such bones: its legs along its spine)
                t[j] = qmul(qswing(qrot(qmul(t[j], qinv(rq[j])), d), want, basis @ FORWARD, 1e-4), t[j])
    return t


def world_up(skeleton: Skeleton, slot_of: dict[str, int], poses: np.ndarray | None = None) -> np.ndarray:
    """The up axis of the skeleton's world: the coordinate axis (+-X, +-Y or +-Z) nearest the mean hips -> head
    direction of ``poses`` (local rotations ``(J, 4)`` or ``(K, J, 4)``, e.g. the keys'; default: the rest pose).  How
    the character stands in its motion, not its rest pose, says where up is: a rest pose need not stand (the model's
    own zero pose lies along X)."""
    local = np.tile([1.0, 0.0, 0.0, 0.0], (1, skeleton.num_joints, 1)) if poses is None else \
        np.asarray(poses, dtype=np.float64).reshape(-1, skeleton.num_joints, 4)
    pos = fk(local, np.broadcast_to(skeleton.offsets, local.shape[:-1] + (3,)), skeleton.parents)[1]
    d = pos[:, slot_of["Head"]] - pos[:, slot_of["Hips"]]
    d = (d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-12)).mean(0)
    axis = int(np.argmax(np.abs(d)))
    up = np.zeros(3)
    up[axis] = 1.0 if d[axis] >= 0 else -1.0
    return up


def _body_basis(skeleton: Skeleton, slot_of: dict[str, int], up: np.ndarray,
                reference: np.ndarray | None = None) -> np.ndarray:
    """The skeleton's body frame: columns left, up, forward, with ``up`` its world's (:func:`world_up`) and left the
    rest pose's thighs (``reference`` for the bones above the hips) across it; where they lie along it (a degenerate
    rest), the rest's hips -> head across it, else a world axis.  Two skeletons that differ only in their names, their
    channels or their world's turn get bases that differ by that turn, so the retargeting between them is exact."""
    rest = rest_pose(skeleton, slot_of, reference)[1]
    up = np.asarray(up, dtype=np.float64) / np.linalg.norm(up)
    for v in (rest[slot_of["UpperLeg_L"]] - rest[slot_of["UpperLeg_R"]], rest[slot_of["Head"]] - rest[slot_of["Hips"]],
              np.roll(np.abs(up), 1)):
        across = v - (v @ up) * up
        if np.linalg.norm(across) > 0.1 * np.linalg.norm(v):
            break
    left = across / np.linalg.norm(across)
    return np.stack([left, up, np.cross(left, up)], axis=1)


def _quat_of(basis: np.ndarray) -> np.ndarray:
    """The unit quaternion of an orthonormal basis (a rotation matrix)."""
    return qframe(np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0]), basis[:, 1], basis[:, 0])


def _hip_height(skeleton: Skeleton, t: np.ndarray, slot_of: dict[str, int], up: np.ndarray) -> float:
    """The hips' height above the ankles in the T-pose ``t`` (global rotations), along ``up``."""
    parents = skeleton.parents
    local = np.array([t[0]] + [qmul(qinv(t[parents[j]]), t[j]) for j in range(1, len(parents))])
    pos = fk(local, skeleton.offsets, parents)[1]
    feet = 0.5 * (pos[slot_of["Foot_L"]] + pos[slot_of["Foot_R"]])
    return float((pos[slot_of["Hips"]] - feet) @ up)


class Retarget:
    """Motion between ``rig`` (a humanoid skeleton, its rest offsets) and ``model`` (the model's skeleton, whose joint
    names are the slots) through ``bone_map`` (slot -> rig bone).  :meth:`to_model` and :meth:`to_rig` (module
    docstring); ``reference``: the rig's local rotations ``(J, 4)`` at a key (its bones above the hips stand as there
    in the reference pose); ``poses``: the rig's local rotations ``(K, J, 4)`` at the keys, which say where its world's
    up is (:func:`world_up`; default: the reference); ``up``: that direction when the caller knows it (a host whose
    armature is turned as an object); ``scale``: model lengths per rig length (hip heights);
    ``world``: the rotation from the rig's world to the model's (wxyz).  The model's own skeleton under other names is
    the identity case: ``world`` a turn about the up axis at most, the same T-pose, the same motion."""

    def __init__(self, rig: Skeleton, model: Skeleton, bone_map: BoneMap, reference: np.ndarray | None = None,
                 where: str = "rig", poses: np.ndarray | None = None, up: np.ndarray | None = None):
        self.rig, self.model, self.map = rig, model, bone_map
        self.rig_slot = {s: rig.names.index(b) for s, b in bone_map.slots.items()}
        self.model_slot = {s: model.names.index(s) for s in model.names}
        rest = rest_pose(rig, self.rig_slot, reference)[1]
        slot = self.rig_slot
        size = float(np.ptp(rest, axis=0).max())
        tall = np.linalg.norm(rest[slot["Head"]] - rest[slot["Hips"]])
        across = np.linalg.norm(rest[slot["UpperLeg_L"]] - rest[slot["UpperLeg_R"]])
        if not (np.isfinite(size) and size > 0 and tall > 1e-3 * size and across > 1e-3 * size):
            raise InbetweenError(f"{where}: its scale and up direction cannot be found from its rest pose (the head "
                                 f"{tall:.3g} from the hips, the thighs {across:.3g} apart, the rig {size:.3g} across)")
        if up is None:
            up = world_up(rig, self.rig_slot, reference if poses is None else poses)
        elif not (np.shape(up) == (3,) and np.isfinite(up).all() and np.linalg.norm(up) > 0):
            raise InbetweenError(f"{where}: up must be a direction (x, y, z), got {up!r}")
        basis = _body_basis(rig, self.rig_slot, up, reference)
        m_basis = _body_basis(model, self.model_slot, UP)  # the model's world is the project's: Y up
        self.world = qmul(_quat_of(m_basis), qinv(_quat_of(basis)))  # rig world -> model world
        self.t_rig = tpose(rig, self.rig_slot, basis, reference)
        self.t_model = tpose(model, self.model_slot, m_basis)
        rig_height = _hip_height(rig, self.t_rig, self.rig_slot, basis[:, 1])
        if not rig_height > 1e-3 * size:
            raise InbetweenError(f"{where}: its scale cannot be found: in its T-pose the hips are not above the ankles "
                                 f"(hip height {rig_height:.3g}, the rig {size:.3g} across)")
        self.scale = _hip_height(model, self.t_model, self.model_slot, UP) / rig_height
        self._plan_model()
        self._plan_rig()
        self._plan_aims(reference)

    # ------------------------------------------------------------------ where each joint's rotation comes from
    def _fractions(self, skeleton: Skeleton, path: list[int]) -> np.ndarray:
        rest = fk(np.tile([1.0, 0, 0, 0], (skeleton.num_joints, 1)), skeleton.offsets, skeleton.parents)[1]
        seg = np.linalg.norm(np.diff(rest[path], axis=0), axis=-1)
        return np.concatenate([[0.0], np.cumsum(seg)])

    def _plan_model(self) -> None:
        """Per model joint ``(a, b, f)``: its world rotation is ``slerp(W[a], W[b], f)`` of rig bones ``a``, ``b``."""
        m, slots = self.model, self.rig_slot
        src = {}
        for j, name in enumerate(m.names):
            if name in slots:
                src[j] = (slots[name], slots[name], 0.0)
        body = [self.model_slot[s] for s in BODY]
        pos = self._fractions(m, body)
        for i, j in enumerate(body):
            if j in src:
                continue
            lo = max(k for k in range(i) if body[k] in src)
            hi = min(k for k in range(i + 1, len(body)) if body[k] in src)
            f = (pos[i] - pos[lo]) / (pos[hi] - pos[lo]) if pos[hi] > pos[lo] else 0.0
            src[j] = (src[body[lo]][0], src[body[hi]][0], float(f))
        for j in range(m.num_joints):  # a missing clavicle follows the chest, missing toes the foot
            if j not in src:
                src[j] = src[m.parents[j]]
        self.model_source = [src[j] for j in range(m.num_joints)]

    def _plan_rig(self) -> None:
        """Per rig bone: ``("slot", model joint)``; inside a chain between mapped bones ``("body" | "limb", model joint,
        rig bone)``: rigid with the mapped bone below it (the model's segment there is one bone); or ``("free",)``
        (keeps its local values)."""
        r = self.rig
        mapped = {b: self.model_slot[s] for s, b in self.rig_slot.items()}
        plan: list[tuple] = [("free",)] * r.num_joints
        for b, j in mapped.items():
            plan[b] = ("slot", j)
        ch = _chains(r.parents, self.rig_slot)
        body = ch.paths["body"]
        for i, b in enumerate(body):
            if b not in mapped:
                lo = max(k for k in range(i) if body[k] in mapped)
                plan[b] = ("body", mapped[body[lo]], body[lo])
        for key, path in ch.paths.items():
            if key == "body":
                continue
            last = None
            for b in path:
                if b in mapped:
                    last = b
                elif last is not None:
                    plan[b] = ("limb", mapped[last], last)
        self.rig_plan = plan

    def _plan_aims(self, reference) -> None:
        """The bones whose direction is matched: per mapped model joint with a chain child mapped too, the pair of rig
        joints it spans (``model_aims``: ``(model joint, model child, rig joint, rig joint)``); per mapped rig bone, the
        next mapped joint along its chain (``rig_aims``: ``(rig bone, rig joint, model joint, model joint, the
        direction to that joint in the bone's T-pose frame)``: the bones in between move with it, as in the T-pose)."""
        m, r = self.model, self.rig
        m_ch = _chains(m.parents, self.model_slot)
        m_rest = rest_pose(m, self.model_slot)[1]
        rq, rest = rest_pose(r, self.rig_slot, reference)
        tiny = 1e-6 * max(float(np.ptp(rest, axis=0).max()), 1e-9)
        model_aims = []
        for j, c in _aims(m_ch, m_rest).items():
            if m.parents[c] == j and m.names[j] in self.rig_slot and m.names[c] in self.rig_slot:
                rj, rc = self.rig_slot[m.names[j]], self.rig_slot[m.names[c]]
                if np.linalg.norm(rest[rc] - rest[rj]) > tiny:  # (CMU's Spine and Chest slots sit on other joints)
                    model_aims.append((j, c, rj, rc))
        self.model_aims = model_aims
        mapped = {b: self.model_slot[s] for s, b in self.rig_slot.items()}
        r_ch = _chains(r.parents, self.rig_slot)
        t = self.t_rig
        t_local = np.array([t[0]] + [qmul(qinv(t[r.parents[j]]), t[j]) for j in range(1, r.num_joints)])
        t_pos = fk(t_local, r.offsets, r.parents)[1]  # the T-pose: a chain's bones between mapped ones are straight there
        rig_aims = []
        for path in r_ch.paths.values():
            for i, b in enumerate(path[:-1]):
                nxt = next((c for c in path[i + 1 :] if c in mapped), None)
                if b in mapped and nxt is not None and np.linalg.norm(rest[nxt] - rest[b]) > tiny:
                    rig_aims.append((b, nxt, mapped[b], mapped[nxt], qrot(qinv(self.t_rig[b]), t_pos[nxt] - t_pos[b])))
        self.rig_aims = rig_aims

    # ------------------------------------------------------------------ the two directions
    def _to_model_world(self, w: np.ndarray) -> np.ndarray:
        return qmul(qmul(self.world, w), qinv(self.world))

    def _to_rig_world(self, w: np.ndarray) -> np.ndarray:
        return qmul(qmul(qinv(self.world), w), self.world)

    def to_model(self, local_q: np.ndarray, local_p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The rig's motion ``local_q (F, J, 4), local_p (F, J, 3)`` (every joint's local translation: its offset or
        its position channels; frames in time order) -> the model's ``root (F, 3), local_q (F, Jm, 4)``."""
        gq, gp = fk(np.asarray(local_q, np.float64), np.asarray(local_p, np.float64), self.rig.parents)
        w_rig = qmul(gq, qinv(self.t_rig)[None])  # (F, J, 4) world rotation from the T-pose
        a = np.array([s[0] for s in self.model_source])
        b = np.array([s[1] for s in self.model_source])
        f = np.array([s[2] for s in self.model_source])
        w = np.where((f > 0)[None, :, None], slerp_np(w_rig[:, a], w_rig[:, b], f[None, :]), w_rig[:, a])
        g = qmul(self._to_model_world(w), self.t_model[None])
        turn = np.broadcast_to(self.world, gp.shape[:-1] + (4,))
        for j, c, rj, rc in self.model_aims:  # each bone points where the rig's does (bones between them included)
            want = qrot(turn[:, 0], gp[:, rc] - gp[:, rj])
            g[:, j] = qmul(qswing(qrot(g[:, j], np.broadcast_to(self.model.offsets[c], want.shape)), want), g[:, j])
        par = list(self.model.parents[1:])
        lq = np.concatenate([g[:, :1], qmul(qinv(g[:, par]), g[:, 1:])], axis=1)
        lq[:1] = euler_sign(lq[:1])  # as a file's frames are: the first frame's Euler sign, then continuous in time
        lq = remove_discontinuities(lq, axis=0)
        root = self.scale * qrot(np.broadcast_to(self.world, gp[:, 0].shape[:-1] + (4,)), gp[:, self.rig_slot["Hips"]])
        return root, lq

    def to_rig(self, root: np.ndarray, local_q: np.ndarray, free_q: np.ndarray, free_p: np.ndarray,
               movers: list[int] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The model's ``root (F, 3), local_q (F, Jm, 4)`` -> the rig's ``local_q (F, J, 4), local_p (F, J, 3)``;
        ``free_q``/``free_p`` give the local values of the bones without a slot (and every local translation but the
        one that carries the hips).  ``movers``: rig joints with position channels (the hips' translation goes to the
        nearest of them at or above the hips; default: the rig's root)."""
        gm, pm = fk(np.asarray(local_q, np.float64), np.repeat(self.model.offsets[None], len(root), 0),
                    self.model.parents)
        w = self._to_rig_world(qmul(gm, qinv(self.t_model)[None]))  # (F, Jm, 4) in the rig's world
        back = np.broadcast_to(qinv(self.world), pm.shape[:-1] + (4,))
        turn = {}  # per mapped rig bone: the swing that points it (and the bones it carries) where the model's points
        for b, _, j, k, rest_dir in self.rig_aims:
            want = qrot(back[:, 0], pm[:, k] - pm[:, j])
            have = qrot(qmul(w[:, j], self.t_rig[b]), np.broadcast_to(rest_dir, want.shape))
            turn[b] = qswing(have, want)
        r = self.rig
        f = len(root)
        gq = np.zeros((f, r.num_joints, 4))
        lq = np.array(free_q, dtype=np.float64, copy=True)
        for b, plan in enumerate(self.rig_plan):
            p = r.parents[b]
            kind = plan[0]
            if kind == "slot":
                gq[:, b] = qmul(w[:, plan[1]], self.t_rig[b])
                if b in turn:
                    gq[:, b] = qmul(turn[b], gq[:, b])
            elif kind in ("body", "limb"):  # inside a chain: rigid with the mapped bone below it
                gq[:, b] = qmul(w[:, plan[1]], self.t_rig[b])
                if plan[-1] in turn:
                    gq[:, b] = qmul(turn[plan[-1]], gq[:, b])
            else:
                gq[:, b] = lq[:, b] if p < 0 else qmul(gq[:, p], lq[:, b])
            if kind != "free":
                lq[:, b] = gq[:, b] if p < 0 else qmul(qinv(gq[:, p]), gq[:, b])
        lp = np.array(free_p, dtype=np.float64, copy=True)
        hips = self.rig_slot["Hips"]
        chain = [j for j in _path(r.parents, 0, hips)]
        carriers = [j for j in chain if j in set(movers if movers is not None else [0])]
        if carriers:
            mover = carriers[-1]
            target = qrot(np.broadcast_to(qinv(self.world), root.shape[:-1] + (4,)), np.asarray(root, np.float64)) \
                / self.scale
            gp = fk(lq, lp, r.parents)[1]
            shift = target - gp[:, hips]  # move the mover by what the hips lack
            pm = r.parents[mover]
            lp[:, mover] += shift if pm < 0 else qrot(qinv(fk(lq, lp, r.parents)[0][:, pm]), shift)
        return lq, lp
