"""Characters generated for the retargeting tests: the model's motion played by another humanoid.

:func:`character` turns a motion of the model's skeleton (``root (F, 3)``, ``local_q (F, J, 4)``, Y up, cm) into a BVH
of a rig with other bone names, other proportions (a factor per bone), a rest pose that is a T-pose or an A-pose
(the model's T-pose, arms lowered by ``a_pose`` degrees; the legs take ``scale["legs"]``, the other bones their own
factor), extra bones (a second spine bone inside the spine, twist
bones under the arms, fingers under the hands, a motionless ``root`` bone above the hips), in metres and Z up.  The rig
moves as the model does: each mapped bone turns in world space by what the model's joint turns from its T-pose.
"""
from __future__ import annotations

import numpy as np

from inbetweening.data.bvh import BVH
from inbetweening.geometry.quaternion import qinv, qmul, qrot, remove_discontinuities
from inbetweening.geometry.skeleton import Skeleton, fk
from inbetweening.runtime.retarget import euler_sign
from inbetweening.runtime.tpose import tpose

UE = {"Hips": "pelvis", "Spine": "spine_01", "Chest": "spine_03", "Neck": "neck_01", "Head": "head",
      "Shoulder_L": "clavicle_l", "UpperArm_L": "upperarm_l", "LowerArm_L": "lowerarm_l", "Hand_L": "hand_l",
      "Shoulder_R": "clavicle_r", "UpperArm_R": "upperarm_r", "LowerArm_R": "lowerarm_r", "Hand_R": "hand_r",
      "UpperLeg_L": "thigh_l", "LowerLeg_L": "calf_l", "Foot_L": "foot_l", "Toes_L": "ball_l",
      "UpperLeg_R": "thigh_r", "LowerLeg_R": "calf_r", "Foot_R": "foot_r", "Toes_R": "ball_r"}
Z_UP = np.array([np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0])  # +90 degrees about X: Y up -> Z up


def _rotation_about(axis, degrees):
    half = np.radians(degrees) / 2
    return np.concatenate([[np.cos(half)], np.sin(half) * np.asarray(axis, dtype=float)])


def character(model: Skeleton, root: np.ndarray, local_q: np.ndarray, names: dict[str, str] = UE,
              scale: dict[str, float] | None = None, a_pose: float = 0.0, extras: bool = True, unit: float = 0.01,
              z_up: bool = True, seed: int = 0) -> tuple[BVH, dict[str, str]]:
    """``(the rig's BVH, its bone map slot -> bone)``."""
    rng = np.random.default_rng(seed)
    slot = {n: i for i, n in enumerate(model.names)}
    t = tpose(model, slot)  # the model's T-pose (global rotations)
    rest = t.copy()  # the rig's rest pose, as global rotations of the model's joints
    for side, sign in (("L", 1.0), ("R", -1.0)):
        down = _rotation_about([0.0, 0.0, 1.0], -sign * a_pose)  # arms lowered about the forward axis
        for s in ("UpperArm", "LowerArm", "Hand"):
            rest[slot[f"{s}_{side}"]] = qmul(down, t[slot[f"{s}_{side}"]])
    up = Z_UP if z_up else np.array([1.0, 0, 0, 0])
    scale = scale or {}
    # the rig's joints: the model's (renamed), with extras inserted; offsets = rest-pose bone vectors (rig world)
    local_rest = np.array([rest[0]] + [qmul(qinv(rest[model.parents[j]]), rest[j]) for j in range(1, model.num_joints)])
    pos = fk(local_rest, model.offsets, model.parents)[1]
    bones, parents, offsets, source = [], [], [], []  # source: the model joint whose world rotation the bone takes
    free = set()  # twist bones and fingers: a motion of their own

    def add(name, parent, offset, src, own=False):
        if own:
            free.add(len(bones))
        bones.append(name)
        parents.append(parent)
        offsets.append(np.asarray(offset, float))
        source.append(src)
        return len(bones) - 1

    index = {}
    top = add("root", -1, [0.0, 0.0, 0.0], None) if extras else None
    for j, n in enumerate(model.names):
        p = model.parents[j]
        k = scale.get("legs", 1.0) if n[:-2] in ("UpperLeg", "LowerLeg", "Foot") else scale.get(n, 1.0)
        vec = (pos[j] - pos[p]) * k if p >= 0 else pos[j]
        parent = index[p] if p >= 0 else (top if top is not None else -1)
        if extras and n == "Chest":  # a second spine bone halfway up the spine's last segment
            mid = add("spine_02", parent, vec / 2, model.parents[j])
            index[j] = add(names[n], mid, vec / 2, j)
        else:
            index[j] = add(names[n], parent, vec if p >= 0 else [0.0, 0.0, 0.0], j)
        if extras and n.startswith(("UpperArm", "LowerArm")):
            add(names[n] + "_twist", index[j], 0.5 * (pos[model.children(j)[0]] - pos[j]) * k, j, own=True)
        if extras and n.startswith("Hand"):
            for f in range(2):
                side = 1 if n.endswith("L") else -1
                knuckle = add(f"{names[n]}_finger{f}_01", index[j], [8.0 * side, 0, 2.0 * f], j, own=True)
                add(f"{names[n]}_finger{f}_02", knuckle, [3.0 * side, 0, 0], j, own=True)
    offsets = np.array(offsets)
    hips = index[0]
    offsets[hips] = pos[0] * scale.get("legs", 1.0)  # the hips' rest height follows the legs
    n_out = len(bones)
    f = len(root)
    g_model = fk(np.asarray(local_q, float), np.repeat(model.offsets[None], f, 0), model.parents)[0]
    g = np.zeros((f, n_out, 4))
    g[..., 0] = 1.0
    wiggle = rng.normal(0, 0.05, (n_out, 3))
    for b in range(n_out):
        if source[b] is None:
            continue
        j = source[b]
        g[:, b] = qmul(g_model[:, j], qinv(rest[j]))
        if b in free:
            angle = 0.3 * np.sin(np.arange(f) / 9.0 + b)
            axis = wiggle[b] / np.linalg.norm(wiggle[b])
            extra = np.concatenate([np.cos(angle / 2)[:, None], np.sin(angle / 2)[:, None] * axis], -1)
            g[:, b] = qmul(g[:, parents[b]], extra)
    lq = np.concatenate([g[:, :1], qmul(qinv(g[:, [max(p, 0) for p in parents[1:]]]), g[:, 1:])], axis=1)
    lq[:, 0] = g[:, 0]
    # rig world = up-axis turn of the model's world; lengths in rig units
    if top is None:  # the rig's world is the model's turned: every rotation conjugated, the offsets turned
        lq = qmul(qmul(up, lq), qinv(up))
    hips_q = lq[:, hips] if top is not None else None
    if top is not None:
        lq[:, top] = up
        lq[:, hips] = hips_q
    offsets = offsets * unit
    offsets = qrot(np.broadcast_to(up, offsets.shape[:-1] + (4,)), offsets) if top is None else offsets
    positions = np.repeat(offsets[None], f, 0)
    hips_pos = np.asarray(root, float) * scale.get("legs", 1.0) * unit
    positions[:, hips] = hips_pos if top is not None else qrot(np.broadcast_to(up, hips_pos.shape[:-1] + (4,)), hips_pos)
    channels = [("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")] * n_out
    leaves = [b for b in range(n_out) if b not in parents]
    empty = BVH(bones, np.array(parents), offsets, channels, {b: np.array([0.0, 0.02, 0.0]) for b in leaves}, 1 / 30,
                np.zeros((1, 6 * n_out)), "character.bvh")
    return empty.with_motion(lq, positions), {s: names[s] for s in model.names}


def model_walk(model: Skeleton, frames: int = 121, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A walk-like motion of the model's skeleton ``(root (F, 3), local_q (F, J, 4))``: from the T-pose (an upright
    body), every joint swinging at its own period (``seed``), the root turning and moving forward, with the signs a
    file's Euler angles give the first frame (the network reads ``q`` and ``-q`` differently)."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames)[:, None, None]
    base = tpose(model, {n: i for i, n in enumerate(model.names)})
    local = np.array([base[0]] + [qmul(qinv(base[model.parents[j]]), base[j]) for j in range(1, model.num_joints)])
    ang = 0.35 * np.sin(2 * np.pi * t / rng.uniform(25, 45, (1, model.num_joints, 1))
                        + rng.uniform(0, 6, (1, model.num_joints, 3)))
    norm = np.linalg.norm(ang, axis=-1, keepdims=True)
    wiggle = np.concatenate([np.cos(norm / 2), np.sin(norm / 2) * ang / np.maximum(norm, 1e-9)], -1)
    q = qmul(local[None], wiggle)
    yaw = np.stack([np.cos(t[:, 0, 0] / 80), 0 * t[:, 0, 0], np.sin(t[:, 0, 0] / 80), 0 * t[:, 0, 0]], -1)
    q[:, 0] = qmul(yaw, q[:, 0])
    root = np.stack([40 * np.sin(t[:, 0, 0] / 30), 95 + 2 * np.sin(t[:, 0, 0] / 4), 2.5 * t[:, 0, 0]], -1)
    q[:1] = euler_sign(q[:1])
    return root, remove_discontinuities(q, axis=0)


def wiggle(frames: int = 200, joints: int = 21, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A smooth random motion ``(root (F, 3), local_q (F, J, 4))`` of any skeleton with ``joints`` joints: every joint
    swinging at its own period (``seed``), the root moving forward and turning about +Y (not a plausible body motion:
    for tests of the machinery, not of the network's quality)."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames)
    root = np.stack([60 * np.sin(t / 40), 90 + 3 * np.sin(t / 7), 2.5 * t], -1)
    ang = 0.4 * np.sin(t[:, None, None] / rng.uniform(8, 20, (1, joints, 3)) + rng.uniform(0, 6, (1, joints, 3)))
    q = np.concatenate([np.ones((frames, joints, 1)), ang], -1)
    q[:, 0] = np.stack([np.cos(t / 60), 0 * t, np.sin(t / 60), 0 * t], -1)
    return root, q / np.linalg.norm(q, axis=-1, keepdims=True)
