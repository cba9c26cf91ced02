"""The per-frame solve that poses a generated Rigify rig's controls so its deform bones take the fill's pose
(:class:`ControlSolve`, used by :meth:`~.rigify.RigifyRig.basis_values`).

Rigify moves the deform bones through constraints, so the controls' channels are found against Blender's own
evaluation: each pass reads the evaluated pose, turns every control by what its bone still lacks, and lets Blender
evaluate again.

- **An FK control** (``hips``, ``chest``, ``neck``, ``head``, ``shoulder.L``, ``upper_arm_fk.L``, ... ``toe_fk.L``)
  carries its bone rigidly, so the turn ``T D^-1`` (``T`` the bone's target rotation, ``D`` its evaluated one) applied
  to the control in armature space puts the bone on its target.  Its channels are computed against its parent as that
  parent is about to move in the same pass (:meth:`ControlSolve._upstream`), so a chain settles in one pass.
- **torso** has no bone of its own.  Rigify hangs the hips below and the chest above its pivot, and bends the spine
  between them: with the hips and the chest held, the spine from the Spine bone's head to the chest's head turns about
  half as much as the torso.  The torso is turned so that line points, and the bone between the Spine and the Chest
  bones twists, where the fill puts them, through an estimate of how the spine turns per turn of the torso
  (:meth:`ControlSolve._torso_turn`: a half at first, corrected by every turn whose result is read); then moved so the
  hips' bone's head is where the fill puts it.  The spine's bend (the chest's distance from the Spine bone's head) and
  the Spine bone's roll are Rigify's.
- **A frame after a solved one** starts from one pass against the frame before's evaluated pose
  (``solve(..., evaluated=False)``), so the evaluation that sets the frame is the first check.
- The passes end when every FK control's bone is within :data:`TOLERANCE` of its target, the hips' head within
  :data:`TOLERANCE` of the hips' height and the torso's turn below :data:`TORSO_TOLERANCE`, or after
  :data:`MAX_PASSES` (measured, `benchmarks/blender_rigify.py --rig generated`: 56 passes for 290 generated frames
  besides their 290 frame changes; 182 with the torso's tolerance at 0.11 degrees, 425 starting from the frames
  before's solutions carried on).
- What Blender evaluates is the ``obj`` it is given: :meth:`~.rigify.RigifyRig.basis_values` gives it the rig's
  :class:`~.rig_proxy.RigProxy` (the bones :meth:`ControlSolve.bones` names and what poses them), so an evaluation
  costs a fraction of the rig's.
"""
from __future__ import annotations

import math

import bpy
import numpy as np
from mathutils import Matrix, Quaternion, Vector

MAX_PASSES = 12  # passes of the solve per generated frame, at most (a scene evaluation each)
TOLERANCE = 5e-4  # radians; and the hips' place, in units of the hips' height
TORSO_TOLERANCE = 5e-3  # radians (0.29 degrees): the torso's turn; Rigify's spine deviates from the fill's by degrees anyway


def rot(m) -> Quaternion:
    """The rotation of a pose matrix (Rigify's stretched bones carry a scale)."""
    return m.to_3x3().normalized().to_quaternion()


def angle(a: Quaternion, b: Quaternion) -> float:
    """The angle between two rotations (radians; accurate near zero)."""
    d = a.rotation_difference(b)
    return 2.0 * math.asin(min(1.0, Vector((d.x, d.y, d.z)).length))


def align(a1: Vector, a2: Vector, b1: Vector, b2: Vector) -> Quaternion:
    """The rotation taking direction ``a1`` to ``b1`` and, about ``b1``, ``a2`` as close as it gets to ``b2``."""
    first = a1.rotation_difference(b1)
    axis = b1.normalized()
    u, v = first @ a2, b2.copy()
    u, v = u - axis * u.dot(axis), v - axis * v.dot(axis)
    if u.length < 1e-9 or v.length < 1e-9:
        return first
    return Quaternion(axis, math.atan2(axis.dot(u.cross(v)), u.dot(v))) @ first


def set_rotation(pb, q: Quaternion) -> None:
    """Set a pose bone's rotation channels to ``q`` in its rotation mode (Euler angles near their current values)."""
    if pb.rotation_mode == "QUATERNION":
        pb.rotation_quaternion = q
    elif pb.rotation_mode == "AXIS_ANGLE":
        axis, a = q.to_axis_angle()
        pb.rotation_axis_angle = (a, *axis)
    else:
        pb.rotation_euler = q.to_euler(pb.rotation_mode, pb.rotation_euler)


def stands_for(name: str) -> str:
    """The deform bone a Rigify bone moves with, by name (``MCH-foot_fk.L`` -> ``DEF-foot.L``)."""
    for prefix in ("ORG-", "MCH-", "DEF-"):
        name = name[len(prefix):] if name.startswith(prefix) else name
    return "DEF-" + name.replace("_fk", "")


def _chest(rig) -> int:
    """The joint of the Chest slot."""
    return rig.names.index(rig.map.slots["Chest"])


class ControlSolve:
    """The solve for a :class:`~.rigify.RigifyRig` (``rig.pbones``: its controls, ``torso`` last; ``rig.owned[k]``:
    the joint control ``k`` turns, the torso's the Spine bone; ``rig.seen[j] @ rig.rel[j]``: joint ``j``'s evaluated
    pose).  ``obj``: the armature it poses and reads (the rig, or its :class:`~.rig_proxy.RigProxy`'s copy: the
    same bone names); ``passes``: the evaluations it asked for."""

    def __init__(self, rig, obj=None):
        self.rig, self.passes = rig, 0
        self.obj = obj = rig.obj if obj is None else obj  # the armature evaluated: the rig or its proxy (same names)
        pose = obj.pose.bones
        self.chest = _chest(rig)
        self.between = rig.parents[self.chest]  # the bone between the Spine and the Chest bones (Rigify's spine.002)
        self.pbones = [pose[pb.name] for pb in rig.pbones]
        self.seen = {j: pose[name] for j, name in self.reads(rig).items()}
        self.between_bone = pose[rig.dbones[self.between].name]
        self.up = [self._upstream(k) for k in range(len(rig.pbones))]
        self.order: list[int] = []
        for k in range(len(rig.pbones)):
            self._visit(k)
        self.torso = len(rig.pbones) - 1
        self.hips_k = rig.owned.index(rig.hips)
        self.scale = max(rig.dbones[rig.hips].bone.head_local.length, 1e-6)
        self.jac, self.sent, self.sent_spin = Matrix.Identity(3) * 0.5, None, None  # see _torso_turn

    @staticmethod
    def reads(rig) -> dict:
        """``{joint: pose bone name}``: the bones the solve reads the pose of (the controls' joints, the Chest's and
        the bone between the Spine and the Chest bones)."""
        chest = _chest(rig)
        return {j: rig.seen[j].name for j in [*rig.owned, chest, rig.parents[chest]]}

    @staticmethod
    def bones(rig) -> list[str]:
        """Every pose bone the solve reads or writes (a :class:`~.rig_proxy.RigProxy`'s ``reads``)."""
        return ([pb.name for pb in rig.pbones] + list(ControlSolve.reads(rig).values())
                + [rig.dbones[rig.parents[_chest(rig)]].name])

    def _upstream(self, k: int) -> list[tuple[int, float]]:
        """``[(control, share)]``: the controls whose turns carry control ``k``'s parent, and the share of each turn it
        takes: the first bone above it that is a control (or moves with a deform bone an FK control turns) carries what
        is left after the bones on the way that copy a control's rotation with influence ``f`` (Rigify's neck and head
        follow the torso's rotation), which carry ``f`` of theirs."""
        rig = self.rig
        owner = {rig.names[j]: i for i, j in enumerate(rig.owned[:-1])}
        index = {pb.name: i for i, pb in enumerate(self.pbones)}

        def control(name):
            hit = index.get(name, owner.get(stands_for(name)))
            return hit if hit != k else None

        out, share = [], 1.0
        p = self.pbones[k].parent
        while p is not None and share > 0.0:
            hit = control(p.name)
            if hit is not None:
                return out + [(hit, share)]
            for c in p.constraints:
                if c.type in ("COPY_ROTATION", "COPY_TRANSFORMS") and not c.mute and c.influence > 0:
                    source = control(getattr(c, "subtarget", "")) if c.target == self.obj else None
                    if source is not None:
                        out.append((source, share * c.influence))
                    share *= 1.0 - c.influence
            p = p.parent
        return out

    def _visit(self, k: int, seen: tuple = ()) -> None:
        if k in self.order or k in seen:
            return
        for up, _ in self.up[k]:
            self._visit(up, seen + (k,))
        self.order.append(k)

    def _pose(self, j: int) -> Matrix:
        return self.seen[j].matrix @ self.rig.rel[j]

    def solve(self, target_q: np.ndarray, target_p: np.ndarray, evaluated: bool = True) -> tuple[float, float]:
        """Pose the controls at the current frame for the armature-space rotations ``target_q (J, 4)`` and heads
        ``target_p (J, 3)`` of the skeleton's joints; returns the residual (radians; the hips' distance in units of its
        height).  ``evaluated=False``: one pass against the pose Blender evaluated last (the frame before's, solved),
        no evaluation and no residual (``(nan, nan)``): the next frame's start, which its scene evaluation checks."""
        target = [Quaternion(target_q[j]) for j in self.rig.owned]
        at = tuple(Vector(target_p[j]) for j in (self.rig.hips, self.chest, self.rig.owned[self.torso]))
        between_q = Quaternion(target_q[self.between])
        if not evaluated:
            self._pass(target, at, between_q)
            return math.nan, math.nan
        for _ in range(MAX_PASSES):
            res = self._pass(target, at, between_q, check=True)
            if res is not None:
                return res
            bpy.context.view_layer.update()  # the proxy's alone: nothing else changed
            self.passes += 1
        return self._residual(target, at, [self._pose(j) for j in self.rig.owned])

    def _residual(self, target, at, deform) -> tuple[float, float]:
        """The FK controls' bones' largest angle from their targets (radians) and the hips' distance from theirs (in
        units of the hips' height), for the evaluated poses ``deform`` of ``rig.owned``."""
        return (max(angle(t, rot(d)) for t, d in zip(target[:-1], deform[:-1])),
                (at[0] - deform[self.hips_k].translation).length / self.scale)

    def _torso_turn(self, spin: Quaternion) -> Quaternion:
        """The torso's turn for the spine's ``spin`` (rotation vectors): ``J^-1 spin``, ``J`` how the spine turns per
        turn of the torso (a 3 x 3 matrix: its bend and its twist answer differently), from a half at the start and
        corrected after each turn whose result was read (Broyden's update)."""
        v = Vector(spin.to_exponential_map())
        if self.sent is not None and self.sent.length > 1e-4:
            u, got = self.sent, self.sent_spin - v  # the turn asked, the spin it removed
            r = (got - self.jac @ u) / u.length_squared
            self.jac = self.jac + Matrix([[a * b for b in u] for a in r])
        try:
            turn = self.jac.inverted() @ v
        except ValueError:  # a singular estimate: start again from a half
            self.jac = Matrix.Identity(3) * 0.5
            turn = self.jac.inverted() @ v
        self.sent, self.sent_spin = turn.copy(), v.copy()
        return Quaternion(turn)

    def _pass(self, target, at, between_q, check: bool = False):
        """One pass: read the evaluated pose, turn every control by what its bone lacks (``check``: unless every bone
        is within the tolerance already; then the residual is returned and nothing moves)."""
        rig, obj, torso, pbones = self.rig, self.obj, self.torso, self.pbones
        hips_at, chest_at, spine_at = at
        z, one = Vector((0.0, 0.0, 1.0)), Quaternion()
        mats = [pb.matrix.copy() for pb in pbones]
        deform = [self._pose(j) for j in rig.owned]
        spin = align(self._pose(self.chest).translation - deform[torso].translation,
                     rot(self.between_bone.matrix) @ z, chest_at - spine_at, between_q @ z)
        if check:
            res = self._residual(target, at, deform)
            if max(res) < TOLERANCE and angle(spin, one) < TORSO_TOLERANCE:
                self.sent = None  # the next turn is the next frame's: nothing to measure the spine's answer on
                return res
        moved: dict = {}
        for k in self.order:
            m = mats[k]
            w = Matrix.Identity(4)  # how the parent is about to move
            for up, share in self.up[k]:
                w = (moved[up] if share == 1.0 else Quaternion().slerp(moved[up].to_quaternion(), share)
                     .to_matrix().to_4x4()) @ w
            turn = self._torso_turn(spin) if k == torso else target[k] @ rot(deform[k]).inverted()
            new = Matrix.LocRotScale((w @ m).translation, turn @ rot(m), m.to_scale())
            basis = obj.convert_space(pose_bone=pbones[k], matrix=w.inverted() @ new, from_space="POSE",
                                      to_space="LOCAL")
            set_rotation(pbones[k], basis.to_quaternion())
            moved[k] = new @ m.inverted()
        m = moved[torso] @ mats[torso]  # the torso's place: what is left of the hips'
        m.translation = m.translation + hips_at - moved[self.hips_k] @ deform[self.hips_k].translation
        pbones[torso].location = obj.convert_space(pose_bone=pbones[torso], matrix=m, from_space="POSE",
                                                   to_space="LOCAL").translation
        return None
