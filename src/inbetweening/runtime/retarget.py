"""Retargeting between a humanoid rig (the animator's character) and the model's skeleton: the runtime's stage that
lets a model fill any humanoid whose bones a :class:`~inbetweening.runtime.bone_map.BoneMap` names.

Both skeletons are first put in one reference pose, a **T-pose** built for each from a natural pose (:mod:`.tpose`:
the keys' mean for the rig, the training data's mean for the model; up the world axis the keys stand along).  A
skeleton of the model's own shape (its mapped joints, up to names, channels, unit and turn) takes the model's natural
pose, so its retargeting is the identity.  A rig's rest pose may be a T-pose, an A-pose, Z up or Y up, in any unit.

A motion then moves across as **world rotations from the T-pose**: a mapped bone's global rotation ``G`` is
``W T`` with ``T`` its T-pose rotation, and the other skeleton's bone takes the same ``W`` (turned into its world).
Chains of different lengths are distributed: a body bone (spine, neck) that one skeleton has and the other lacks
takes the rotation interpolated between its chain's mapped neighbours by its place along the chain; a bone inside a
limb (a twist segment) moves rigidly with the mapped bone above it; a missing clavicle follows the chest, missing
toes the foot.  The root (the hips) moves by the rig's hip height: ``p_model = s F p_rig``, the keys' lowest ankle put
at the model's (:data:`MODEL_ANKLE`).  Bones without a slot (fingers, twist leaves, face, props) keep their own local
values, which the runtime interpolates between the keys.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from inbetweening.geometry.quaternion import euler_to_quat_np, qinv, qmul, qrot, qswing, quat_to_euler_np, slerp_np
from inbetweening.geometry.skeleton import Skeleton, fk

from .model import InbetweenError
from .tpose import (
    BODY,
    UP,
    aims,
    basis_quat,
    body_basis,
    chain,
    chains,
    hinge_axes,
    hip_height,
    model_natural_pose,
    nearest_pose,
    rest_pose,
    tpose,
    world_up,
)

if TYPE_CHECKING:
    from .bone_map import BoneMap

__all__ = ["EULER_ORDER", "MODEL_ANKLE", "ModelSide", "Retarget", "euler_sign", "rig_plan"]

EULER_ORDER = "zxy"  # the rotation channels of the shipped models' training files (Bandai-Namco-2)


class ModelSide:
    """What a :class:`Retarget` needs of the model's skeleton alone, for one natural pose ``start``: its slots, basis,
    T-pose, hip height, rest positions, FK of ``start`` and chains.  Built once per model and pose (:meth:`of`): every
    fill of every rig builds a ``Retarget``, the model's side never changes."""

    _cache: dict = {}

    def __init__(self, model: Skeleton, start: np.ndarray | None):
        self.slot = {s: model.names.index(s) for s in model.names}
        self.start = start
        self.basis = body_basis(model, self.slot, UP, start=start)  # the project's world: Y up
        self.tpose = tpose(model, self.slot, self.basis, start=start)
        self.height = hip_height(model, self.tpose, self.slot, UP)
        self.rest = rest_pose(model, self.slot)[1]
        self.global_start = None if start is None else fk(np.asarray(start, np.float64), model.offsets, model.parents)[0]
        self.chains = chains(model.parents, self.slot)
        for a in (self.start, self.basis, self.tpose, self.rest, self.global_start):
            if a is not None:
                a.flags.writeable = False

    @classmethod
    def of(cls, model: Skeleton, model_pose: np.ndarray | None) -> ModelSide:
        start = model_pose if model_pose is not None else model_natural_pose(model)
        start = None if start is None else np.array(start, dtype=np.float64)  # its own copy: made read-only below
        key = (tuple(model.names), tuple(model.parents), np.asarray(model.offsets, np.float64).tobytes(),
               None if start is None else start.tobytes())
        side = cls._cache.get(key)
        if side is None:
            if len(cls._cache) > 8:
                cls._cache.clear()
            side = cls._cache[key] = cls(model, start)
        return side


def euler_sign(q: np.ndarray, order: str = EULER_ORDER) -> np.ndarray:
    """Quaternions ``(..., 4)`` with the sign a BVH file's Euler angles give them (``order``): the network reads
    quaternions as numbers, and ``q`` and ``-q`` are different inputs to it; a key read from a file of the model's
    skeleton has this sign, a retargeted one gets it here."""
    back = euler_to_quat_np(quat_to_euler_np(q, order), order)
    return np.where(((q * back).sum(-1) < 0)[..., None], -q, q)


MODEL_ANKLE = 11.739  # cm: the lowest ankle of a training clip over the floor, median over the clips (the same script)


def _shape(skeleton: Skeleton, joints: list[int], start: np.ndarray | None = None) -> np.ndarray:
    """The distances between ``joints`` in the rest pose (or ``start``), over the largest: the same for two skeletons
    that differ by names, channels, units, their world's turn or bones between these joints."""
    pos = rest_pose(skeleton, {"Hips": 0}, None, start)[1][joints]
    d = np.linalg.norm(pos[:, None] - pos[None], axis=-1)
    return d / max(float(d.max()), 1e-12)


def rig_plan(rig: Skeleton, model: Skeleton, bone_map: BoneMap) -> list[tuple]:
    """Per bone of ``rig`` (mapped to the slots, ``model``'s joint names, by ``bone_map``), where the retargeting takes
    its rotation from: ``("slot", model joint)`` (a mapped bone); inside a chain between mapped bones
    ``("body" | "limb", model joint, rig bone)``: rigid with the mapped bone below it (the model's segment there is one
    bone); or ``("free",)`` (keeps its local values).  It depends on the skeletons and the map only: a front end knows
    the bones a fill writes before it reads a pose."""
    rig_slot = {s: rig.names.index(b) for s, b in bone_map.slots.items()}
    mapped = {b: model.names.index(s) for s, b in rig_slot.items()}
    plan: list[tuple] = [("free",)] * rig.num_joints
    for b, j in mapped.items():
        plan[b] = ("slot", j)
    ch = chains(rig.parents, rig_slot)
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
    return plan


class Retarget:
    """Motion between ``rig`` (a humanoid skeleton, its rest offsets) and ``model`` (the model's skeleton, whose joint
    names are the slots) through ``bone_map`` (slot -> rig bone).  :meth:`to_model` and :meth:`to_rig` (module
    docstring); ``reference``: the rig's local rotations ``(J, 4)`` at a key (its bones above the hips stand as there
    in the reference pose); ``poses``: the rig's local rotations ``(K, J, 4)`` at the keys: where its world's up is
    (:func:`world_up`), its natural pose and its hinges' axes (:meth:`_rig_start`; default: the reference); ``up``:
    that direction when the caller knows it (a host whose armature is turned as an object); ``model_pose``: the
    model's natural pose (default :data:`MODEL_POSE` where the model has the skeleton it was read on); ``ends``: the
    rig's end-site offsets per joint (a forearm without a hand, a foot without toes is pointed by its end site);
    ``translations``: the rig's local translations at the keys (as ``poses``): its floor, the lowest ankle there, goes
    where the model's data has it (:data:`MODEL_ANKLE`; the model sees heights).  ``scale``: model lengths per rig
    length (hip heights); ``world``: the rotation from the rig's world to the model's (wxyz); ``lift``: model lengths
    the rig's motion is raised by in the model's world.

    Each skeleton's T-pose is built from its natural pose, so that their bones' twists correspond as their motions'
    do, whatever their rest poses (the model's zero pose lies along X; a rig's may be an A-pose, or its bones' axes
    rolled).  The model's own skeleton under other names, channels, units, axes or with bones added is the identity
    case: the rig's natural pose is then the model's, ``world`` a turn about the up axis, the motion the same."""

    def __init__(self, rig: Skeleton, model: Skeleton, bone_map: BoneMap, reference: np.ndarray | None = None,
                 where: str = "rig", poses: np.ndarray | None = None, up: np.ndarray | None = None,
                 model_pose: np.ndarray | None = None, ends: dict[int, np.ndarray] | None = None,
                 translations: np.ndarray | None = None):
        self.rig, self.model, self.map = rig, model, bone_map
        self.rig_slot = {s: rig.names.index(b) for s, b in bone_map.slots.items()}
        self._m = m_side = ModelSide.of(model, model_pose)
        self.model_slot = m_side.slot
        rest = rest_pose(rig, self.rig_slot, reference)[1]
        slot = self.rig_slot
        size = float(np.ptp(rest, axis=0).max())
        tall = np.linalg.norm(rest[slot["Head"]] - rest[slot["Hips"]])
        across = np.linalg.norm(rest[slot["UpperLeg_L"]] - rest[slot["UpperLeg_R"]])
        if not (np.isfinite(size) and size > 0 and tall > 1e-3 * size and across > 1e-3 * size):
            raise InbetweenError(f"{where}: its scale and up direction cannot be found from its rest pose (the head "
                                 f"{tall:.3g} from the hips, the thighs {across:.3g} apart, the rig {size:.3g} across)")
        keyed = reference if poses is None else poses
        if up is None:
            up = world_up(rig, self.rig_slot, keyed)
        elif not (np.shape(up) == (3,) and np.isfinite(up).all() and np.linalg.norm(up) > 0):
            raise InbetweenError(f"{where}: up must be a direction (x, y, z), got {up!r}")
        m_start = m_side.start
        self.m_basis = m_basis = m_side.basis
        self.t_model = m_side.tpose
        start = self._rig_start(keyed, m_start, reference, up)
        self.basis = basis = body_basis(rig, self.rig_slot, up, reference, start)
        self.world = qmul(basis_quat(m_basis), qinv(basis_quat(basis)))  # rig world -> model world
        axes = hinge_axes(rig, self.rig_slot, keyed) if keyed is not None and not self.same else None
        self.t_rig = tpose(rig, self.rig_slot, basis, reference, start, ends, axes)
        rig_height = hip_height(rig, self.t_rig, self.rig_slot, basis[:, 1])
        if not rig_height > 1e-3 * size:
            raise InbetweenError(f"{where}: its scale cannot be found: in its T-pose the hips are not above the ankles "
                                 f"(hip height {rig_height:.3g}, the rig {size:.3g} across)")
        self.scale = m_side.height / rig_height
        self.lift = 0.0  # model lengths the rig's motion is raised by on the model's side: its floor onto the model's
        if translations is not None and not self.same and model_natural_pose(model) is not None:
            q = np.asarray(keyed, dtype=np.float64).reshape(-1, rig.num_joints, 4)
            gp = fk(q, np.asarray(translations, dtype=np.float64).reshape(q.shape[:-1] + (3,)), rig.parents)[1]
            ankles = gp[:, [slot["Foot_L"], slot["Foot_R"]]] @ basis[:, 1]
            self.lift = MODEL_ANKLE - self.scale * float(ankles.min())
        self._plan_model()
        self._plan_rig()
        self._plan_aims(reference)

    def _rig_start(self, keyed, m_start, reference, up) -> np.ndarray | None:
        """The rig's natural pose: the model's carried over where the rig is the model's skeleton (the same shape of
        the mapped joints at rest, up to the unit and a turn), else per chain the key nearest the model's natural
        pose (:func:`~.tpose.nearest_pose`), else its rest (``None``).  Its hinges then take their axes from every key
        (:func:`~.tpose.hinge_axes`), not from that one pose."""
        slots = [s for s in self.rig_slot if s in self.model_slot]
        mine, theirs = [self.rig_slot[s] for s in slots], [self.model_slot[s] for s in slots]
        self.same = same = bool(np.abs(_shape(self.rig, mine) - _shape(self.model, theirs)).max() < 1e-4)
        if same and m_start is not None:
            rq, rest = rest_pose(self.rig, self.rig_slot, reference)
            a = rest[mine] - rest[self.rig_slot["Hips"]]
            m_rest = self._m.rest
            b = m_rest[theirs] - m_rest[self.model_slot["Hips"]]
            u, _, vt = np.linalg.svd(a.T @ b)  # the turn taking the rig's rest onto the model's (Kabsch)
            turn = basis_quat(vt.T @ np.diag([1.0, 1.0, np.sign(np.linalg.det(vt.T @ u.T))]) @ u.T)
            g_model = self._m.global_start
            source = {b_: self.model_slot[s] for s, b_ in self.rig_slot.items()}
            g = np.zeros((self.rig.num_joints, 4))
            for j, p in enumerate(self.rig.parents):
                if j in source:
                    g[j] = qmul(qmul(qinv(turn), qmul(g_model[source[j]], turn)), rq[j])
                else:
                    g[j] = g[p] if p >= 0 else rq[j]
            par = list(self.rig.parents[1:])
            return np.concatenate([g[:1], qmul(qinv(g[par]), g[1:])], axis=0)
        if keyed is None or same:
            return None
        return nearest_pose(self.rig, self.rig_slot, keyed, up, self.model, self.model_slot, m_start)

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
        """Per rig bone, where its rotation comes from (:func:`rig_plan`)."""
        self.rig_plan = rig_plan(self.rig, self.model, self.map)

    def _plan_aims(self, reference) -> None:
        """The bones whose direction is matched: per mapped model joint with a chain child mapped too, the pair of rig
        joints it spans (``model_aims``: ``(model joint, model child, rig joint, rig joint)``); per mapped rig bone, the
        next mapped joint along its chain (``rig_aims``: ``(rig bone, rig joint, model joint, model joint, the
        direction to that joint in the bone's T-pose frame)``: the bones in between move with it, as in the T-pose)."""
        m, r = self.model, self.rig
        m_ch, m_rest = self._m.chains, self._m.rest
        rq, rest = rest_pose(r, self.rig_slot, reference)
        tiny = 1e-6 * max(float(np.ptp(rest, axis=0).max()), 1e-9)
        model_aims = []
        for j, c in aims(m_ch, m_rest).items():
            if m.parents[c] == j and m.names[j] in self.rig_slot and m.names[c] in self.rig_slot:
                rj, rc = self.rig_slot[m.names[j]], self.rig_slot[m.names[c]]
                if np.linalg.norm(rest[rc] - rest[rj]) > tiny:  # (CMU's Spine and Chest slots sit on other joints)
                    model_aims.append((j, c, rj, rc))
        self.model_aims = model_aims
        mapped = {b: self.model_slot[s] for s, b in self.rig_slot.items()}
        r_ch = chains(r.parents, self.rig_slot)
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
        lq = euler_sign(lq)  # each frame's sign as the model's files give it (the network reads q and -q apart)
        root = self.scale * qrot(np.broadcast_to(self.world, gp[:, 0].shape[:-1] + (4,)), gp[:, self.rig_slot["Hips"]]) \
            + self.lift * UP
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
        above = chain(r.parents, 0, hips)
        carriers = [j for j in above if j in set(movers if movers is not None else [0])]
        if carriers:
            mover = carriers[-1]
            target = qrot(np.broadcast_to(qinv(self.world), root.shape[:-1] + (4,)),
                          np.asarray(root, np.float64) - self.lift * UP) / self.scale
            gq, gp = fk(lq, lp, r.parents)
            shift = target - gp[:, hips]  # move the mover by what the hips lack
            pm = r.parents[mover]
            lp[:, mover] += shift if pm < 0 else qrot(qinv(gq[:, pm]), shift)
        return lq, lp
