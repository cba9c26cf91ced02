"""Blender glue: pose channels in each rotation mode, and the rig of an armature of the model's own skeleton
(:class:`Rig`: the armature's animation <-> the model's root and local quaternions).

A pose bone's armature-space rotation is ``M_j = C G_j C^-1 R_j`` when the armature's rest pose is the model's zero
pose (what Blender's BVH importer builds): ``G_j`` the joint's global rotation in the model's world, ``C`` the
rotation (and scale ``s``) from the model's world to armature space, ``R_j`` the bone's rest rotation.  So a bone's
rotation channels (``matrix_basis``) are the model's local rotation conjugated by a constant per bone:
``q_basis = A_j L_j A_j^-1`` with ``A_j = R_j^-1 C``.  ``C`` and ``s`` are fitted to the rest pose's bone vectors
(whatever axis conversion and scale the importer used).  The model's root is placed through its parent bones'
evaluated pose (a static ``joint_Root`` above ``Hips`` in Bandai-Namco files).
"""
from __future__ import annotations

import numpy as np
from mathutils import Euler, Matrix, Quaternion, Vector

from inbetweening import dcc
from inbetweening.dcc import RigError
from inbetweening.geometry.quaternion import euler_to_quat_np, qinv, qmul, qnormalize
from inbetweening.runtime import ModelInfo

from .curves import ArmatureCurves, OnArmature, bone_path, channelbag, curve_values  # noqa: F401  (channelbag: benchmarks')

ROT_PATH = {"QUATERNION": ("rotation_quaternion", 4), "AXIS_ANGLE": ("rotation_axis_angle", 4)}


def rot_path(pb) -> tuple[str, int]:
    return ROT_PATH.get(pb.rotation_mode, ("rotation_euler", 3))


def rotation_quats(mode: str, values: np.ndarray) -> np.ndarray:
    """``(F, 4)`` (wxyz): the rotations of a bone's rotation channel values ``(F, n)`` in its rotation ``mode``, as
    Blender (``mathutils``) reads them (an Euler mode names the order the axes are applied in, the angles are x, y, z;
    an axis-angle's axis is normalised)."""
    v = np.asarray(values, dtype=np.float64)
    if mode == "QUATERNION":
        return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-30)
    if mode == "AXIS_ANGLE":
        n = np.linalg.norm(v[:, 1:], axis=-1, keepdims=True)
        q = np.concatenate([np.cos(v[:, :1] / 2), np.sin(v[:, :1] / 2) * v[:, 1:] / np.maximum(n, 1e-30)], -1)
        return np.where(n > 0, q, np.array([1.0, 0.0, 0.0, 0.0]))
    order = mode[::-1].lower()  # applied X then Y then Z ("XYZ") is q_z q_y q_x
    return euler_to_quat_np(v[:, ["xyz".index(a) for a in order]], order, degrees=False)


def rotation_values(pb, q: np.ndarray, frames, raw_prev: dict, k: int) -> np.ndarray:
    """The rotation channel values ``(F, n)`` of pose bone ``pb`` (its rotation mode) for basis rotations ``q (F, 4)`` at
    ``frames``: quaternions sign-continuous and Euler angles continuous with the previous frame's values (``raw_prev``:
    ``{frame: [values per bone]}`` at the frame before each run of frames; ``k`` the bone's index there)."""
    path, n = rot_path(pb)
    vals = np.zeros((len(frames), n))
    prev = None
    for t, fr in enumerate(frames):
        if fr - 1 in raw_prev:
            prev = raw_prev[fr - 1][k]
        quat = Quaternion(q[t])
        if pb.rotation_mode == "QUATERNION":
            if prev is not None and np.dot(q[t], prev) < 0:
                quat.negate()
            v = list(quat)
        elif pb.rotation_mode == "AXIS_ANGLE":
            axis, angle = quat.to_axis_angle()
            v = [angle, *axis]
        else:
            v = list(quat.to_euler(pb.rotation_mode, Euler(prev, pb.rotation_mode)) if prev is not None
                     else quat.to_euler(pb.rotation_mode))
        vals[t] = v
        prev = v
    return vals


def rotation_channels(pbones, qb: np.ndarray, frames, raw_prev: dict, bones=None) -> dict:
    """``{(k, data path, index): values over frames}`` of the rotation channels of ``pbones[k]`` for basis rotations
    ``qb (F, K, 4)`` (:func:`rotation_values`; ``bones``: the indices to write, default all)."""
    out = {}
    for k in range(len(pbones)) if bones is None else bones:
        pb = pbones[k]
        path, n = rot_path(pb)
        vals = rotation_values(pb, qb[:, k], frames, raw_prev, k)
        for i in range(n):
            out[(k, bone_path(pb.name, path), i)] = vals[:, i]
    return out


def _to_np(q) -> np.ndarray:
    return np.array([q.w, q.x, q.y, q.z], dtype=np.float64)


def _fit_rotation(src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, float]:
    """Rotation ``C`` and scale ``s`` minimising ``|dst - s C src|`` over rows (Kabsch)."""
    h = src.T @ dst
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(vt.T @ u.T))
    c = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    s = float(np.sum(dst * (src @ c.T)) / max(np.sum(src * src), 1e-12))
    return c, s


class Rig(OnArmature, dcc.Rig):
    """An armature of the model's own skeleton (every joint a bone of the model's name; a model whose joints are not
    the humanoid slots): the DCC core's :class:`~inbetweening.dcc.Rig`, its poses the model's ``root (F, 3)`` and
    ``local_q (F, J, 4)`` (the model-to-armature frame fitted on the rest pose)."""

    def __init__(self, obj, model: ModelInfo):
        sk = model.skeleton
        if obj is None or obj.type != "ARMATURE":
            raise RigError("select an armature (the active object is not one)")
        bones = obj.data.bones
        missing = [n for n in sk.names if bones.get(n) is None]
        if missing:
            raise RigError(f"armature '{obj.name}' does not match the model's skeleton: missing bones "
                           f"{', '.join(missing)} (the model expects {len(sk.names)} bones: "
                           f"{', '.join(sk.names)})")
        for j, name in enumerate(sk.names[1:], start=1):
            parent = bones[name].parent
            want = sk.names[sk.parents[j]]
            if parent is None or parent.name != want:
                raise RigError(f"armature '{obj.name}' does not match the model's skeleton: bone '{name}' has parent "
                               f"'{parent.name if parent else None}', the model's is '{want}'")
        self.obj, self.model = obj, model
        self.pbones = [obj.pose.bones[n] for n in sk.names]
        heads = np.array([bones[n].head_local for n in sk.names], dtype=np.float64)
        vec = np.array([heads[j] - heads[p] for j, p in enumerate(sk.parents) if p >= 0])
        off = np.array([sk.offsets[j] for j, p in enumerate(sk.parents) if p >= 0])
        c, s = _fit_rotation(off, vec)
        err = np.abs(vec - s * off @ c.T).max()
        if not np.isfinite(err) or s <= 0 or err > 1e-3 * max(np.abs(vec).max(), 1e-6):
            raise RigError(f"armature '{obj.name}': its rest pose does not match the model's skeleton offsets "
                           f"(residual {err:.3g}); import the clip with Blender's BVH importer")
        self.C, self.s = c, s
        self.c = _to_np(Matrix(c.tolist()).to_quaternion())
        rest = [bones[n].matrix_local for n in sk.names]
        self.r = np.array([_to_np(m.to_quaternion()) for m in rest])  # bone rest rotations
        self.A = qmul(qinv(self.r), self.c[None])  # (J, 4)
        root = bones[sk.names[0]]
        # armature-space matrix of the root = P(f) @ root_rel @ basis, P(f) = the parent's pose @ its rest^-1
        self.root_rel = (root.parent.matrix_local.inverted() @ root.matrix_local) if root.parent else root.matrix_local.copy()
        self.ancestors = []
        b = root.parent
        while b is not None:
            self.ancestors.insert(0, obj.pose.bones[b.name])
            b = b.parent
        self.curves, self.where = ArmatureCurves(obj), f"armature '{obj.name}'"

    # ------------------------------------------------------------------ channels
    @property
    def joint_names(self) -> list[str]:
        return [pb.name for pb in self.pbones]

    def key_channels(self) -> list:
        """The channels the fill writes that have a curve: their keys are the animator's."""
        return [(p, i) for _, p, i in self.channels() if self.fcurve(p, i) is not None]

    def settings_parts(self) -> list:
        """The key points of the curves of the bones above the model's root (they place it on every frame)."""
        parts = []
        for pb in self.ancestors:
            for fc in self.curves.bag.fcurves:
                if fc.data_path.startswith(f'pose.bones["{pb.name}"]'):
                    co = np.zeros(2 * len(fc.keyframe_points), np.float32)
                    fc.keyframe_points.foreach_get("co", co)
                    parts += [fc.data_path.encode(), co]
        return parts

    def channels(self):
        """``[(joint, data_path, index)]`` of every channel the fill writes."""
        out = []
        for j, pb in enumerate(self.pbones):
            path, n = rot_path(pb)
            out += [(j, bone_path(pb.name, path), i) for i in range(n)]
            if j == 0:
                out += [(0, bone_path(pb.name, "location"), i) for i in range(3)]
        return out

    def _values(self, pb, prop: str, n: int, frames) -> np.ndarray:
        """``(F, n)``: a pose bone property's channel values at ``frames`` (:func:`curve_values`)."""
        cur = list(getattr(pb, prop))
        return np.stack([curve_values(self.fcurve(bone_path(pb.name, prop), i), cur[i], frames) for i in range(n)], -1)

    def _bases(self, pb, frames) -> list[Matrix]:
        """A pose bone's ``matrix_basis`` at each of ``frames``."""
        loc = self._values(pb, "location", 3, frames)
        path, n = rot_path(pb)
        rot = rotation_quats(pb.rotation_mode, self._values(pb, path, n, frames))
        scale = self._values(pb, "scale", 3, frames)
        return [Matrix.LocRotScale(Vector(a), Quaternion(b), Vector(c)) for a, b, c in zip(loc, rot, scale)]

    def parent_matrices(self, frames) -> list[Matrix]:
        """``P(f)`` at each of ``frames``: the pose matrix of the root's parent chain times the root's rest relation."""
        out = [Matrix.Identity(4) for _ in frames]
        prev = None
        for pb in self.ancestors:
            rel = (prev.bone.matrix_local.inverted() @ pb.bone.matrix_local) if prev is not None else pb.bone.matrix_local
            out = [m @ rel @ b for m, b in zip(out, self._bases(pb, frames))]
            prev = pb
        return [m @ self.root_rel for m in out]

    def read(self, frames) -> tuple[np.ndarray, np.ndarray, list]:
        """Model-space ``root (F, 3), local_q (F, J, 4)`` of the animation at ``frames``, and the raw rotation channel
        values ``[F][J]`` (for Euler continuity)."""
        f, j = len(frames), len(self.pbones)
        qb = np.zeros((f, j, 4))
        raw = [[None] * j for _ in range(f)]
        root = np.zeros((f, 3))
        for k, pb in enumerate(self.pbones):
            path, n = rot_path(pb)
            vals = self._values(pb, path, n, frames)
            qb[:, k] = rotation_quats(pb.rotation_mode, vals)
            for t in range(f):
                raw[t][k] = vals[t]
        local = qmul(qmul(qinv(self.A)[None], qb), self.A[None])
        cinv = np.linalg.inv(self.C)
        rots = np.zeros((f, 4))
        for t, (p, b) in enumerate(zip(self.parent_matrices(frames), self._bases(self.pbones[0], frames))):
            m = p @ b
            rots[t] = _to_np(m.to_quaternion())
            root[t] = cinv @ np.array(m.translation) / self.s
        local[:, 0] = qmul(qmul(qinv(self.c)[None], rots),
                                  qmul(qinv(self.r[0]), self.c)[None])
        return root, qnormalize(local, 0.0), raw

    def basis_values(self, frames, root, local_q, raw_prev):
        """Channel values ``{(joint, path, index): array over frames}`` that pose the armature as ``root (F, 3),
        local_q (F, J, 4)`` at ``frames`` (in order; Euler and quaternion values continuous with ``raw_prev``, the
        rotation channel values at the frame before each run of frames: ``{frame: [J values]}``)."""
        qb = qmul(qmul(self.A[None], local_q), qinv(self.A)[None])
        locs = np.zeros((len(frames), 3))
        rots = qmul(qmul(self.c[None], local_q[:, 0]), qmul(qinv(self.c), self.r[0])[None])
        heads = (root @ self.C.T) * self.s
        for t, parent in enumerate(self.parent_matrices(frames)):
            m = Matrix.LocRotScale(Vector(heads[t]), Quaternion(rots[t]), None)
            basis = parent.inverted() @ m
            locs[t] = np.array(basis.translation)
            qb[t, 0] = _to_np(basis.to_quaternion())
        out = rotation_channels(self.pbones, qb, frames, raw_prev)
        for i in range(3):
            out[(0, bone_path(self.pbones[0].name, "location"), i)] = locs[:, i]
        return out
