"""Blender glue for any humanoid armature (not the model's own skeleton): the armature's rest pose as a skeleton in the
BVH convention (every rest rotation the identity), its pose channels read and written, and the bone-map override
saved on the armature.  The bone map, the retargeting and the fill are the DCC core's
(:class:`inbetweening.dcc.MappedRig`): this module only reads and writes the armature.
"""
from __future__ import annotations

import numpy as np

from inbetweening import dcc
from inbetweening.runtime import ModelInfo

from .curves import ArmatureCurves, OnArmature, bone_path, curve_values
from .rig import RigError, _to_np, rot_path, rotation_channels, rotation_quats

VIRTUAL_ROOT = "(armature)"  # the joint above an armature's several root bones (the armature's origin)


def stored_override(obj) -> dict | None:
    """The bone-map override saved on the armature (``obj.data.inbetween_bone_map``: rows of bone and slot; the
    sidebar's Bone Map panel edits it) as ``{bone: slot or None}``; ``None`` when there is none."""
    rows = getattr(obj.data, "inbetween_bone_map", None) if obj is not None and obj.type == "ARMATURE" else None
    out = {r.bone: (None if r.slot == "NONE" else r.slot) for r in (rows or ()) if r.bone.strip()}
    return out or None


def is_model_skeleton(obj, model: ModelInfo) -> bool:
    """Whether the armature is filled as the model's own skeleton (:class:`~.rig.Rig`;
    :func:`inbetweening.dcc.is_model_skeleton` of its bones' names)."""
    return dcc.is_model_skeleton([b.name for b in obj.data.bones], model)


def armature_skeleton(obj):
    """``(names, parents, offsets, bones)`` of the armature's rest pose in the BVH convention (parents first; offsets:
    head to head in armature space, a root's its head; ``bones[j]``: the Bone, ``None`` for :data:`VIRTUAL_ROOT`, the
    joint added at the origin above an armature with several root bones)."""
    roots = [b for b in obj.data.bones if b.parent is None]
    order: list = []
    stack = list(reversed(roots))
    while stack:
        b = stack.pop()
        order.append(b)
        stack += list(reversed(b.children))
    bones = ([None] if len(roots) > 1 else []) + order
    index = {b.name: j for j, b in enumerate(bones) if b is not None}
    names, parents, offsets = [], [], []
    for b in bones:
        if b is None:
            names.append(VIRTUAL_ROOT), parents.append(-1), offsets.append((0.0, 0.0, 0.0))
            continue
        names.append(b.name)
        if b.parent is None:
            parents.append(0 if len(roots) > 1 else -1)
            offsets.append(tuple(b.head_local))
        else:
            parents.append(index[b.parent.name])
            offsets.append(tuple(b.head_local - b.parent.head_local))
    return names, parents, np.array(offsets, dtype=np.float64), bones


class HumanoidRig(OnArmature, dcc.MappedRig):
    """Any humanoid armature (not the model's skeleton): its bones mapped to the model's slots (with the override saved
    on the armature), its channels read and written in the BVH convention of :class:`inbetweening.dcc.MappedRig`.

    With ``R_b`` a bone's rest rotation (``bone.matrix_local``) and ``B_b`` its channels (``matrix_basis``), its
    armature-space pose is ``M_b = M_parent R_parent^-1 R_b B_b``; the BVH convention's global rotation
    ``G_b = rot(M_b) R_b^-1`` (identity at rest) makes the local rotation a conjugation per bone,
    ``L_b = G_parent^-1 G_b = R_b rot(B_b) R_b^-1``, and the local translation ``offset_b + R_b loc(B_b)`` (a
    connected bone's location is ignored, as Blender does).  Bone scale, constraints and drivers are not read.
    """

    def __init__(self, obj, model: ModelInfo, override: dict | None = None):
        if obj is None or obj.type != "ARMATURE":
            raise RigError("select an armature (the active object is not one)")
        self.obj = obj
        names, parents, offsets, bones = armature_skeleton(obj)
        super().__init__(ArmatureCurves(obj), model, f"armature '{obj.name}'", names, parents, offsets, override)
        self.bones = bones
        self.pbones = [obj.pose.bones[b.name] if b is not None else None for b in bones]
        self.r = np.array([_to_np(b.matrix_local.to_quaternion()) if b is not None else [1.0, 0, 0, 0]
                           for b in bones])

    def key_channels(self) -> list:
        """The rotation and location curves of the mapped bones: their keys are the fill's."""
        return self.curves.bone_channels(self.map.slots.values())

    def is_bone(self, j: int) -> bool:
        return self.pbones[j] is not None

    def connected(self, j: int) -> bool:
        return self.bones[j] is not None and self.bones[j].use_connect

    def has_location(self, j: int) -> bool:
        pb = self.pbones[j]
        return pb is not None and any(self.fcurve(bone_path(pb.name, "location"), i) is not None for i in range(3))

    def ends(self) -> dict[int, np.ndarray]:
        """Per leaf bone, head to tail in armature space (a BVH end site: a forearm without a hand points by it)."""
        return {j: np.array(b.tail_local - b.head_local, dtype=np.float64) for j, b in enumerate(self.bones)
                if b is not None and not b.children}

    def channels(self):
        """``[(joint, data_path, index)]`` of every channel the fill writes (after :meth:`plan`)."""
        out = []
        for j in self.rot_bones:
            pb = self.pbones[j]
            path, n = rot_path(pb)
            out += [(j, bone_path(pb.name, path), i) for i in range(n)]
        for j in self.movers:
            out += [(j, bone_path(self.pbones[j].name, "location"), i) for i in range(3)]
        return out

    def read_channels(self, frames):
        """The raw rotation values ``[F][J]`` and locations ``(F, J, 3)`` of the bones at ``frames`` (F-curves
        evaluated; the current value where a channel has no curve)."""
        f, j = len(frames), len(self.pbones)
        raw = [[None] * j for _ in range(f)]
        loc = np.zeros((f, j, 3))
        for k, pb in enumerate(self.pbones):
            if pb is None:
                raw_k = [[1.0, 0.0, 0.0, 0.0]] * f
            else:
                path, n = rot_path(pb)
                cur = list(getattr(pb, path))
                raw_k = np.stack([curve_values(self.fcurve(bone_path(pb.name, path), i), cur[i], frames)
                                  for i in range(n)], -1)
                if not self.bones[k].use_connect:
                    lcur = list(pb.location)
                    loc[:, k] = np.stack([curve_values(self.fcurve(bone_path(pb.name, "location"), i), lcur[i], frames)
                                          for i in range(3)], -1)
            for t in range(f):
                raw[t][k] = raw_k[t]
        return raw, loc

    def read(self, frames):
        """BVH-convention ``local_q (F, J, 4)``, ``local_p (F, J, 3)`` at ``frames`` and the raw rotation values."""
        raw, loc = self.read_channels(frames)
        f, j = len(frames), len(self.pbones)
        qb = np.zeros((f, j, 4))
        qb[..., 0] = 1.0
        for k, pb in enumerate(self.pbones):
            if pb is not None:
                qb[:, k] = rotation_quats(pb.rotation_mode, np.array([raw[t][k] for t in range(f)]))
        lq, lp = self.to_local(qb, loc)
        return lq, lp, raw

    def basis_values(self, frames, local_q, local_p, raw_prev):
        """Channel values ``{(joint, path, index): array over frames}`` of :meth:`channels` posing the armature as the
        BVH-convention ``local_q``, ``local_p`` at ``frames`` (Euler and quaternion values continuous with
        ``raw_prev``, as :meth:`Rig.basis_values <.rig.Rig.basis_values>`)."""
        qb, loc = self.to_basis(local_q, local_p)
        out = rotation_channels(self.pbones, qb, frames, raw_prev, self.rot_bones)
        for k in self.movers:
            for i in range(3):
                out[(k, bone_path(self.pbones[k].name, "location"), i)] = loc[:, k, i]
        return out
