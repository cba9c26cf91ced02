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


def rest_pose(skeleton: Skeleton, slot_of: dict[str, int], reference: np.ndarray | None = None,
              start: np.ndarray | None = None):
    """``(global rotations (J, 4), positions (J, 3))`` of the pose a T-pose is built from: ``start`` (local rotations
    ``(J, 4)``: a natural pose, :func:`mean_pose`) or BVH's rest (every local rotation the identity); the bones above
    the hips take ``reference`` (local rotations ``(J, 4)``, e.g. a key frame's): a static top bone that turns the
    whole character (an armature's axis change) is part of where the body stands."""
    n = skeleton.num_joints
    local = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)) if start is None else np.array(start, dtype=np.float64)
    if reference is not None:
        above = _path(skeleton.parents, 0, slot_of["Hips"])[:-1]
        local[above] = np.asarray(reference, dtype=np.float64)[above]
    return fk(local, skeleton.offsets, skeleton.parents)


def mean_pose(local_q: np.ndarray) -> np.ndarray:
    """The mean of poses ``local_q (F, J, 4)`` joint by joint (quaternions made one-signed, averaged, normalised): a
    natural pose of a motion whose twists are its own.  The top joint's: the identity (a heading is no pose)."""
    q = np.asarray(local_q, dtype=np.float64)
    q = q * np.where((q * q[:1]).sum(-1, keepdims=True) < 0, -1.0, 1.0)
    m = q.mean(0)
    m = m / np.maximum(np.linalg.norm(m, axis=-1, keepdims=True), 1e-12)
    m[0] = [1.0, 0.0, 0.0, 0.0]
    return m


# The limbs' hinges: per bone, the three joints of the bend it turns with (the knee for the thigh and the shin, the ankle
# for the foot, the elbow for the upper arm and the forearm) and that bend's axis ``a->b x b->c`` in a natural T-pose
# (x left, y up, z forward; palms down): the knees bend back, the feet up, the elbows towards the palms.  A T-pose built
# by the shortest turns alone depends on the pose it starts from (an arm raised from hanging or from held forward ends
# twisted differently); the bend fixes the twist where the starting pose bends it (:data:`HINGE_BEND`).
HINGES = {f"{bone}_{s}": (tuple(f"{j}_{s}" for j in joints), np.array(axis))
          for s, sign in (("L", 1.0), ("R", -1.0))
          for bone, joints, axis in (("UpperLeg", ("UpperLeg", "LowerLeg", "Foot"), (1.0, 0.0, 0.0)),
                                     ("LowerLeg", ("UpperLeg", "LowerLeg", "Foot"), (1.0, 0.0, 0.0)),
                                     ("Foot", ("LowerLeg", "Foot", "Toes"), (-1.0, 0.0, 0.0)),
                                     ("UpperArm", ("UpperArm", "LowerArm", "Hand"), (0.0, 0.0, -sign)),
                                     ("LowerArm", ("UpperArm", "LowerArm", "Hand"), (0.0, 0.0, -sign)))}
HINGE_BEND = 0.17  # sin 10 degrees: a hinge bent less than this in the starting pose does not say its axis


def _hinges(slot_of: dict[str, int], pos: np.ndarray, tips: dict[int, np.ndarray] | None = None
            ) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Per hinged joint bent enough in the pose ``pos (J, 3)``: ``(its bend axis there, the natural one)``; a missing
    last joint (no hand, no toes) is the tip of the one before it (``tips``: joint -> its end site's position)."""
    out, tips = {}, tips or {}
    for bone, (joints, natural) in HINGES.items():
        if bone not in slot_of or not all(j in slot_of for j in joints[:2]):
            continue
        a, b = pos[slot_of[joints[0]]], pos[slot_of[joints[1]]]
        c = pos[slot_of[joints[2]]] if joints[2] in slot_of else tips.get(slot_of[joints[1]])
        if c is None:
            continue
        u, v = b - a, c - b
        n = np.cross(u, v) / max(np.linalg.norm(u) * np.linalg.norm(v), 1e-12)
        if np.linalg.norm(n) >= HINGE_BEND:
            out[slot_of[bone]] = (n, natural)
    return out


def _tips(slot_of: dict[str, int], ch: _Chains, rq: np.ndarray, pos: np.ndarray,
          ends: dict[int, np.ndarray] | None) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """The limbs whose last slot is missing (a forearm without a hand, a foot without toes): per the limb's last joint,
    ``(where its end site is in the pose, its T-pose direction in the body frame)`` (``rq``: global rotations, ``pos``:
    positions of the pose)."""
    out = {}
    for key, path in ch.paths.items():
        if key == "body" or not path or path[-1] not in (ends or {}):
            continue
        arm = key.startswith("Shoulder")
        if ("Hand" if arm else "Toes") + key[-2:] not in slot_of:
            j = path[-1]
            direction = (1.0 if key.endswith("L") else -1.0) * LEFT if arm else FORWARD
            out[j] = (pos[j] + qrot(rq[j], np.asarray(ends[j], dtype=np.float64)), direction)
    return out


def tpose(skeleton: Skeleton, slot_of: dict[str, int], basis: np.ndarray | None = None,
          reference: np.ndarray | None = None, start: np.ndarray | None = None,
          ends: dict[int, np.ndarray] | None = None) -> np.ndarray:
    """Global rotations ``(J, 4)`` of the skeleton in its T-pose (module docstring) in its own world, whose body frame
    is ``basis`` (columns: left, up, forward; default: the model's world, the identity), built from the pose
    :func:`rest_pose` gives (``start``, ``reference``) by turning each bone the shortest way, the hips and the chest
    as a whole, the bent limbs by their hinge (:data:`HINGES`).  ``ends``: end-site offsets per joint (a limb whose
    last slot is missing points its last bone by it)."""
    basis = np.eye(3) if basis is None else basis
    parents = skeleton.parents
    rq, rest = rest_pose(skeleton, slot_of, reference, start)
    ch = _chains(parents, slot_of)
    hips = slot_of["Hips"]
    arm_root = parents[ch.paths["Shoulder_L"][0]]
    lateral_hips = rest[slot_of["UpperLeg_L"]] - rest[slot_of["UpperLeg_R"]]
    lateral_arms = rest[ch.paths["Shoulder_L"][0]] - rest[ch.paths["Shoulder_R"][0]]
    full = {hips: lateral_hips, arm_root: lateral_arms}
    aim = _aims(ch, rest)
    tips = _tips(slot_of, ch, rq, rest, ends)
    hinged = _hinges(slot_of, rest, {j: tip for j, (tip, _) in tips.items()})
    t = rq.copy()
    for j in range(len(parents)):
        p = parents[j]
        if p >= 0:
            t[j] = qmul(t[p], qmul(qinv(rq[p]), rq[j]))  # the parent's T-pose turn, the start's local rotation
        if j in aim:  # the start's direction (world) and the T-pose's
            d, want = rest[aim[j]] - rest[j], basis @ ch.direction[j]
        elif j in tips:  # the last bone of a limb without its hand or toes: along its end site
            d, want = tips[j][0] - rest[j], basis @ tips[j][1]
        else:
            continue
        if j in full:
            t[j] = qmul(qframe(d, full[j], want, basis @ LEFT), rq[j])
        elif j in hinged:  # a limb bent at its hinge: the bend's axis turned to the natural one (:data:`HINGES`)
            t[j] = qmul(qframe(d, hinged[j][0], want, basis @ hinged[j][1]), rq[j])
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


def _body_basis(skeleton: Skeleton, slot_of: dict[str, int], up: np.ndarray, reference: np.ndarray | None = None,
                start: np.ndarray | None = None) -> np.ndarray:
    """The skeleton's body frame: columns left, up, forward, with ``up`` its world's (:func:`world_up`) and left the
    thighs across it in the pose :func:`rest_pose` gives; where they lie along it (a degenerate rest), the hips -> head
    across it, else a world axis.  Two skeletons that differ only in their names, their channels or their world's turn
    get bases that differ by that turn, so the retargeting between them is exact."""
    rest = rest_pose(skeleton, slot_of, reference, start)[1]
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


# The model's skeleton's natural pose: per joint the mean local rotation of its training data (``python
# benchmarks/model_pose.py``: Bandai-Namco-2's standard training split, 300 clips, every 5th frame), for the model whose
# offsets point as :data:`MODEL_REST` (the shipped models).  Its T-pose is built from this pose, not from its zero pose
# (every bone along its parent's X, the spine's and the limbs' twists none of the data's).
MODEL_POSE: dict[str, tuple[float, float, float, float]] = {
    "Hips": (1.00000, 0.00000, 0.00000, 0.00000),
    "Spine": (0.70924, 0.70298, -0.03380, 0.04068),
    "Chest": (0.99921, -0.00887, 0.00975, 0.03758),
    "Neck": (0.99675, -0.01862, 0.01709, 0.07653),
    "Head": (0.99978, -0.01239, 0.01572, 0.00606),
    "Shoulder_L": (0.58696, -0.41605, -0.40323, -0.56549),
    "UpperArm_L": (0.82973, -0.27256, -0.29929, -0.38429),
    "LowerArm_L": (0.81040, 0.16323, -0.54426, 0.14277),
    "Hand_L": (0.98556, 0.04404, 0.00587, 0.16337),
    "Shoulder_R": (0.57171, 0.43126, -0.41894, 0.55826),
    "UpperArm_R": (0.84638, -0.24207, -0.32784, -0.34288),
    "LowerArm_R": (0.82774, 0.06111, -0.55405, 0.06433),
    "Hand_R": (0.97723, 0.05918, -0.03184, 0.20125),
    "UpperLeg_L": (0.06020, -0.02780, 0.09237, -0.99351),
    "LowerLeg_L": (0.97122, 0.00115, 0.23818, -0.00031),
    "Foot_L": (0.82362, 0.03123, -0.56544, -0.03081),
    "Toes_L": (0.99105, 0.00025, -0.13348, -0.00003),
    "UpperLeg_R": (-0.15941, -0.98700, 0.01969, 0.00525),
    "LowerLeg_R": (0.97716, 0.00068, 0.21248, -0.00020),
    "Foot_R": (0.82491, 0.08221, -0.55877, -0.02322),
    "Toes_R": (0.99050, -0.00009, -0.13751, -0.00017),
}
MODEL_ANKLE = 11.739  # cm: the lowest ankle of a training clip over the floor, median over the clips (the same script)
MODEL_REST: dict[str, tuple[float, float, float]] = {  # its offsets' directions
    "Spine": (1.0000, 0.0000, 0.0000),
    "Chest": (0.9990, -0.0452, 0.0000),
    "Neck": (1.0000, 0.0000, 0.0000),
    "Head": (1.0000, 0.0000, 0.0000),
    "Shoulder_L": (0.9336, -0.0174, 0.3578),
    "UpperArm_L": (1.0000, 0.0000, 0.0000),
    "LowerArm_L": (1.0000, 0.0000, 0.0000),
    "Hand_L": (1.0000, 0.0000, 0.0000),
    "Shoulder_R": (0.9336, -0.0174, -0.3578),
    "UpperArm_R": (-1.0000, 0.0000, 0.0000),
    "LowerArm_R": (-1.0000, 0.0000, 0.0000),
    "Hand_R": (-1.0000, -0.0000, 0.0000),
    "UpperLeg_L": (-0.3210, -0.9471, 0.0000),
    "LowerLeg_L": (1.0000, 0.0000, -0.0000),
    "Foot_L": (1.0000, 0.0000, -0.0000),
    "Toes_L": (1.0000, 0.0000, 0.0000),
    "UpperLeg_R": (-0.3210, 0.9471, 0.0000),
    "LowerLeg_R": (-1.0000, -0.0001, -0.0010),
    "Foot_R": (-1.0000, 0.0000, 0.0000),
    "Toes_R": (-1.0000, 0.0000, 0.0000),
}


def model_natural_pose(model: Skeleton) -> np.ndarray | None:
    """:data:`MODEL_POSE` as local rotations ``(J, 4)`` where ``model`` has the skeleton it was read on (its offsets'
    directions, :data:`MODEL_REST`), else ``None`` (its zero pose stands in)."""
    if tuple(model.names) != tuple(MODEL_POSE) or not all(
            np.abs(np.asarray(o) / max(np.linalg.norm(o), 1e-12) - MODEL_REST[n]).max() < 1e-3
            for n, o in zip(model.names[1:], model.offsets[1:])):
        return None
    pose = np.array([MODEL_POSE[n] for n in model.names])
    return pose / np.linalg.norm(pose, axis=-1, keepdims=True)  # (the table's five decimals: unit again)


def _shape(skeleton: Skeleton, joints: list[int], start: np.ndarray | None = None) -> np.ndarray:
    """The distances between ``joints`` in the rest pose (or ``start``), over the largest: the same for two skeletons
    that differ by names, channels, units, their world's turn or bones between these joints."""
    pos = rest_pose(skeleton, {"Hips": 0}, None, start)[1][joints]
    d = np.linalg.norm(pos[:, None] - pos[None], axis=-1)
    return d / max(float(d.max()), 1e-12)


class Retarget:
    """Motion between ``rig`` (a humanoid skeleton, its rest offsets) and ``model`` (the model's skeleton, whose joint
    names are the slots) through ``bone_map`` (slot -> rig bone).  :meth:`to_model` and :meth:`to_rig` (module
    docstring); ``reference``: the rig's local rotations ``(J, 4)`` at a key (its bones above the hips stand as there
    in the reference pose); ``poses``: the rig's local rotations ``(K, J, 4)`` at the keys: where its world's up is
    (:func:`world_up`) and its natural pose (:func:`mean_pose`; default: the reference); ``up``: that direction when
    the caller knows it (a host whose armature is turned as an object); ``model_pose``: the model's natural pose
    (default :data:`MODEL_POSE` where the model has the skeleton it was read on); ``ends``: the rig's end-site offsets
    per joint (a forearm without a hand, a foot without toes is pointed by its end site); ``translations``: the rig's
    local translations at the keys (as ``poses``): its floor, the lowest ankle there, goes where the model's data has
    it (:data:`MODEL_ANKLE`; the model sees heights).  ``scale``: model lengths per rig
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
        self.model_slot = {s: model.names.index(s) for s in model.names}
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
        m_start = model_pose if model_pose is not None else model_natural_pose(model)
        self.m_basis = m_basis = _body_basis(model, self.model_slot, UP, start=m_start)  # the project's world: Y up
        self.t_model = tpose(model, self.model_slot, m_basis, start=m_start)
        start = self._rig_start(keyed, m_start, reference)
        self.basis = basis = _body_basis(rig, self.rig_slot, up, reference, start)
        self.world = qmul(_quat_of(m_basis), qinv(_quat_of(basis)))  # rig world -> model world
        self.t_rig = tpose(rig, self.rig_slot, basis, reference, start, ends)
        rig_height = _hip_height(rig, self.t_rig, self.rig_slot, basis[:, 1])
        if not rig_height > 1e-3 * size:
            raise InbetweenError(f"{where}: its scale cannot be found: in its T-pose the hips are not above the ankles "
                                 f"(hip height {rig_height:.3g}, the rig {size:.3g} across)")
        self.scale = _hip_height(model, self.t_model, self.model_slot, UP) / rig_height
        self.lift = 0.0  # model lengths the rig's motion is raised by on the model's side: its floor onto the model's
        if translations is not None and not self.same and model_natural_pose(model) is not None:
            q = np.asarray(keyed, dtype=np.float64).reshape(-1, rig.num_joints, 4)
            gp = fk(q, np.asarray(translations, dtype=np.float64).reshape(q.shape[:-1] + (3,)), rig.parents)[1]
            ankles = gp[:, [slot["Foot_L"], slot["Foot_R"]]] @ basis[:, 1]
            self.lift = MODEL_ANKLE - self.scale * float(ankles.min())
        self._plan_model()
        self._plan_rig()
        self._plan_aims(reference)

    def _rig_start(self, keyed, m_start, reference) -> np.ndarray | None:
        """The rig's natural pose: the model's carried over where the rig is the model's skeleton (the same shape of
        the mapped joints at rest, up to the unit and a turn), else the mean of its keys (:func:`mean_pose`), else its
        rest (``None``)."""
        slots = [s for s in self.rig_slot if s in self.model_slot]
        mine, theirs = [self.rig_slot[s] for s in slots], [self.model_slot[s] for s in slots]
        self.same = same = bool(np.abs(_shape(self.rig, mine) - _shape(self.model, theirs)).max() < 1e-4)
        if same and m_start is not None:
            rq, rest = rest_pose(self.rig, self.rig_slot, reference)
            a = rest[mine] - rest[self.rig_slot["Hips"]]
            m_rest = rest_pose(self.model, self.model_slot)[1]
            b = m_rest[theirs] - m_rest[self.model_slot["Hips"]]
            u, _, vt = np.linalg.svd(a.T @ b)  # the turn taking the rig's rest onto the model's (Kabsch)
            turn = _quat_of(vt.T @ np.diag([1.0, 1.0, np.sign(np.linalg.det(vt.T @ u.T))]) @ u.T)
            g_model = fk(np.asarray(m_start, np.float64), self.model.offsets, self.model.parents)[0]
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
        return mean_pose(np.asarray(keyed, dtype=np.float64).reshape(-1, self.rig.num_joints, 4))

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
        chain = [j for j in _path(r.parents, 0, hips)]
        carriers = [j for j in chain if j in set(movers if movers is not None else [0])]
        if carriers:
            mover = carriers[-1]
            target = qrot(np.broadcast_to(qinv(self.world), root.shape[:-1] + (4,)),
                          np.asarray(root, np.float64) - self.lift * UP) / self.scale
            gp = fk(lq, lp, r.parents)[1]
            shift = target - gp[:, hips]  # move the mover by what the hips lack
            pm = r.parents[mover]
            lp[:, mover] += shift if pm < 0 else qrot(qinv(fk(lq, lp, r.parents)[0][:, pm]), shift)
        return lq, lp
