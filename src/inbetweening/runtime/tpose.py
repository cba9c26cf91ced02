"""Reference poses of a humanoid skeleton: the **T-pose** the retargeting (:mod:`.retarget`) measures a motion
against, the up axis of its world and its body frame.

A T-pose is built from a *natural pose* (for a rig: per chain the key nearest the model's natural pose,
:func:`nearest_pose`; for the model: :data:`MODEL_POSE`, its training data's mean): the body chain (hips to head) up,
the legs down, the feet forward, the arms out to the sides, each bone turned from the natural pose by the shortest
rotation, the limbs' hinges (:data:`HINGES`) framed by their bend (a rig's bend axis taken from every key,
:func:`hinge_axes`), a limb without a hand or toes pointed by its end site; the hips and the bone the arms hang from
turned as a whole so the legs and the shoulders lie across (left to +X, up +Y, forward +Z in the model's world).  Up is
the world axis nearest the keys' hips -> head (:func:`world_up`), and both skeletons' body frames come from one rule
(:func:`body_basis`), so two skeletons that differ only in names, channels, units or their world's turn get T-poses
that differ by exactly that.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from inbetweening.geometry.quaternion import qframe, qinv, qmul, qrot, qswing
from inbetweening.geometry.skeleton import Skeleton, fk

__all__ = ["ARM", "BODY", "HINGES", "LEG", "MODEL_POSE", "MODEL_REST", "UP", "Chains", "aims", "basis_quat",
           "body_basis", "chain", "chains", "frame_of", "hinge_axes", "hip_height", "mean_pose", "model_natural_pose",
           "nearest_pose", "rest_pose", "tpose", "world_up"]


BODY = ("Hips", "Spine", "Chest", "Neck", "Head")
ARM = ("Shoulder", "UpperArm", "LowerArm", "Hand")
LEG = ("UpperLeg", "LowerLeg", "Foot", "Toes")
UP, LEFT, FORWARD = np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])


def _side_chains() -> list[tuple[tuple[str, ...], np.ndarray, np.ndarray]]:
    """``(slots, direction of the segments, direction of the last segment)`` of the four limbs."""
    out = []
    for side, sign in (("L", 1.0), ("R", -1.0)):
        out.append((tuple(f"{s}_{side}" for s in ARM), sign * LEFT, sign * LEFT))
        out.append((tuple(f"{s}_{side}" for s in LEG), -UP, FORWARD))
    return out


def chain(parents, top: int, bottom: int) -> list[int]:
    """Joints from ``top`` down to ``bottom`` (both included); ``[]`` when ``bottom`` is not below ``top``."""
    path = [bottom]
    while path[-1] != top:
        p = parents[path[-1]]
        if p < 0:
            return []
        path.append(p)
    return path[::-1]


@dataclass(frozen=True)
class Chains:
    """A skeleton's chains: per joint the chain it belongs to (``body`` or a limb's first slot), the joint it aims at
    along the chain, the direction of that segment in the T-pose, and the chains' joints in order."""

    aim: dict[int, int]
    direction: dict[int, np.ndarray]
    paths: dict[str, list[int]]


def chains(parents, slot_of: dict[str, int]) -> Chains:
    aim, direction, paths = {}, {}, {}
    body = [slot_of[s] for s in BODY if s in slot_of]
    path = chain(parents, body[0], body[-1])
    paths["body"] = path
    for a, b in zip(path, path[1:]):
        aim[a], direction[a] = b, UP
    for slots, seg, last in _side_chains():
        present = [slot_of[s] for s in slots if s in slot_of]
        path = chain(parents, present[0], present[-1]) if len(present) > 1 else present
        paths[slots[0]] = path
        foot = slot_of.get(slots[2]) if slots[1].startswith("LowerLeg") else None
        for a, b in zip(path, path[1:]):
            aim[a] = b  # the leg's bones at or below the ankle point forward, the others along the limb
            direction[a] = last if foot is not None and _below(parents, a, foot) else seg
    return Chains(aim, direction, paths)


def aims(ch: Chains, rest: np.ndarray) -> dict[int, int]:
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
        above = chain(skeleton.parents, 0, slot_of["Hips"])[:-1]
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
HINGE_AGREE = 0.7  # a joint whose bend axes over the keys agree less than this (mean vector / mean length) is no hinge


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


def hinge_axes(skeleton: Skeleton, slot_of: dict[str, int], poses: np.ndarray) -> dict[int, np.ndarray]:
    """Per hinged joint (:data:`HINGES`) its bend axis in its own frame, from every pose of ``poses`` (local rotations
    ``(K, J, 4)``, e.g. the keys): each pose's ``a->b x b->c`` (as long as the sine of its bend) taken into the joint's
    frame and summed, so the poses that bend it most say the most.  Left out (the pose a T-pose starts from says it
    then): a limb straight in every pose (the mean sine under :data:`HINGE_BEND`), and a joint that does not bend as a
    hinge (its axes in its frame disagree: their mean's length under :data:`HINGE_AGREE` of their mean length)."""
    q = np.asarray(poses, dtype=np.float64).reshape(-1, skeleton.num_joints, 4)
    g, pos = fk(q, np.broadcast_to(skeleton.offsets, q.shape[:-1] + (3,)), skeleton.parents)
    out = {}
    for bone, (joints, _) in HINGES.items():
        if bone not in slot_of or not all(j in slot_of for j in joints):
            continue
        a, b, c = (pos[:, slot_of[j]] for j in joints)
        u, v = b - a, c - b
        n = np.cross(u, v) / np.maximum(np.linalg.norm(u, axis=-1) * np.linalg.norm(v, axis=-1), 1e-12)[:, None]
        each = qrot(qinv(g[:, slot_of[bone]]), n)
        local = each.mean(0)
        agree = np.linalg.norm(local) / max(float(np.linalg.norm(each, axis=-1).mean()), 1e-12)
        if np.linalg.norm(local) >= HINGE_BEND and agree >= HINGE_AGREE:
            out[slot_of[bone]] = local / np.linalg.norm(local)
    return out


def _tips(slot_of: dict[str, int], ch: Chains, rq: np.ndarray, pos: np.ndarray,
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
          ends: dict[int, np.ndarray] | None = None, axes: dict[int, np.ndarray] | None = None) -> np.ndarray:
    """Global rotations ``(J, 4)`` of the skeleton in its T-pose (module docstring) in its own world, whose body frame
    is ``basis`` (columns: left, up, forward; default: the model's world, the identity), built from the pose
    :func:`rest_pose` gives (``start``, ``reference``) by turning each bone the shortest way, the hips and the chest
    as a whole, the bent limbs by their hinge (:data:`HINGES`).  ``ends``: end-site offsets per joint (a limb whose
    last slot is missing points its last bone by it)."""
    basis = np.eye(3) if basis is None else basis
    parents = skeleton.parents
    rq, rest = rest_pose(skeleton, slot_of, reference, start)
    ch = chains(parents, slot_of)
    hips = slot_of["Hips"]
    arm_root = parents[ch.paths["Shoulder_L"][0]]
    lateral_hips = rest[slot_of["UpperLeg_L"]] - rest[slot_of["UpperLeg_R"]]
    lateral_arms = rest[ch.paths["Shoulder_L"][0]] - rest[ch.paths["Shoulder_R"][0]]
    full = {hips: lateral_hips, arm_root: lateral_arms}
    aim = aims(ch, rest)
    tips = _tips(slot_of, ch, rq, rest, ends)
    hinged = _hinges(slot_of, rest, {j: tip for j, (tip, _) in tips.items()})
    for j, axis in (axes or {}).items():  # hinge axes known from more poses than the start (:func:`hinge_axes`)
        natural = next(n for bone, (_, n) in HINGES.items() if slot_of.get(bone) == j)
        hinged[j] = (qrot(rq[j], axis), natural)
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


def body_basis(skeleton: Skeleton, slot_of: dict[str, int], up: np.ndarray, reference: np.ndarray | None = None,
                start: np.ndarray | None = None) -> np.ndarray:
    """The skeleton's body frame: columns left, up, forward, with ``up`` its world's (:func:`world_up`) and left the
    thighs across it in the pose :func:`rest_pose` gives; where they lie along it (a degenerate rest), the hips -> head
    across it, else a world axis.  Two skeletons that differ only in their names, their channels or their world's turn
    get bases that differ by that turn, so the retargeting between them is exact."""
    return frame_of(rest_pose(skeleton, slot_of, reference, start)[1], slot_of, up)


def frame_of(pos: np.ndarray, slot_of: dict[str, int], up: np.ndarray) -> np.ndarray:
    """The body frame (columns left, up, forward) of a pose's joint positions ``pos (J, 3)``: ``up`` and the thighs
    across it; where they lie along it, the hips -> head across it, else a world axis."""
    up = np.asarray(up, dtype=np.float64) / np.linalg.norm(up)
    for v in (pos[slot_of["UpperLeg_L"]] - pos[slot_of["UpperLeg_R"]], pos[slot_of["Head"]] - pos[slot_of["Hips"]],
              np.roll(np.abs(up), 1)):
        across = v - (v @ up) * up
        if np.linalg.norm(across) > 0.1 * np.linalg.norm(v):
            break
    left = across / np.linalg.norm(across)
    return np.stack([left, up, np.cross(left, up)], axis=1)


def nearest_pose(skeleton: Skeleton, slot_of: dict[str, int], poses: np.ndarray, up: np.ndarray,
                 target: Skeleton, target_slot: dict[str, int], target_pose: np.ndarray | None = None) -> np.ndarray:
    """A natural pose of the keys ``poses`` (local rotations ``(K, J, 4)``) for a T-pose that agrees with ``target``'s
    (built from ``target_pose``, local rotations; ``None``: its zero pose): per chain (the body, each limb) the key
    whose chain points most like the target's (the directions between the chain's mapped joints, in each pose's body
    frame, :func:`frame_of`), carried onto the first key's body frame.  Local rotations ``(J, 4)``.

    A T-pose is reached from its natural pose by the shortest turns, and the twist those turns leave depends on the
    road: a limb raised in every key (a wave) reached the T-pose from above while the target's came from below, and
    arrived half a turn twisted.  Starting each chain from the key nearest the target's pose keeps both roads short
    and alike."""
    q = np.asarray(poses, dtype=np.float64).reshape(-1, skeleton.num_joints, 4)
    g, pos = fk(q, np.broadcast_to(skeleton.offsets, q.shape[:-1] + (3,)), skeleton.parents)
    frames = np.stack([frame_of(p, slot_of, up) for p in pos])
    t_local = np.tile([1.0, 0.0, 0.0, 0.0], (target.num_joints, 1)) if target_pose is None else target_pose
    t_pos = fk(np.asarray(t_local, np.float64), target.offsets, target.parents)[1]
    t_frame = frame_of(t_pos, target_slot, np.array([0.0, 1.0, 0.0]))
    name_of = {j: s for s, j in slot_of.items()}
    ch = chains(skeleton.parents, slot_of)
    owner: dict[int, int] = {}
    for path in ch.paths.values():
        mapped = [j for j in path if name_of.get(j) in target_slot]
        pairs = list(zip(mapped, mapped[1:]))
        if not pairs:
            continue
        want = np.stack([t_frame.T @ (t_pos[target_slot[name_of[b]]] - t_pos[target_slot[name_of[a]]])
                         for a, b in pairs])
        have = np.stack([np.einsum("kji,kj->ki", frames, pos[:, b] - pos[:, a]) for a, b in pairs], axis=1)
        cos = (have * want).sum(-1) / np.maximum(np.linalg.norm(have, axis=-1) * np.linalg.norm(want, axis=-1), 1e-12)
        best = int(np.argmin(np.arccos(np.clip(cos, -1.0, 1.0)).sum(-1)))
        for j in path:
            owner[j] = best
    turns = qmul(basis_quat(frames[0])[None], qinv(np.stack([basis_quat(f) for f in frames])))  # key k -> key 0
    out = np.zeros((skeleton.num_joints, 4))
    for j, p in enumerate(skeleton.parents):
        if j not in owner:
            owner[j] = owner.get(p, 0)
        out[j] = qmul(turns[owner[j]], g[owner[j], j])
    par = list(skeleton.parents[1:])
    return np.concatenate([out[:1], qmul(qinv(out[par]), out[1:])], axis=0)


def basis_quat(basis: np.ndarray) -> np.ndarray:
    """The unit quaternion of an orthonormal basis (a rotation matrix)."""
    return qframe(np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0]), basis[:, 1], basis[:, 0])


def hip_height(skeleton: Skeleton, t: np.ndarray, slot_of: dict[str, int], up: np.ndarray) -> float:
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
