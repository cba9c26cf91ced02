"""Blender's curves: the armature's F-curves as the DCC core's :class:`~inbetweening.dcc.Curves` (a channel is an
F-curve, ``(data path, array index)``; a key the fill wrote has Blender's key type *Generated*, *Breakdown* before
Blender 4.2), and the record of the last fill on the action (:mod:`.record`)."""
from __future__ import annotations

import bpy
import numpy as np

from inbetweening.dcc import Curves, Keys

from . import record

ROT_LOC = ("location", "rotation_euler", "rotation_quaternion", "rotation_axis_angle")
GENERATED = "GENERATED" if "GENERATED" in bpy.types.Keyframe.bl_rna.properties["type"].enum_items.keys() else "BREAKDOWN"
POINT_FLOATS = ("co", "handle_left", "handle_right")
POINT_SCALARS = (("interpolation", np.int32), ("handle_left_type", np.int32), ("handle_right_type", np.int32),
                 ("type", np.int32), ("easing", np.int32), ("back", np.float32), ("amplitude", np.float32),
                 ("period", np.float32), ("select_control_point", np.int32), ("select_left_handle", np.int32),
                 ("select_right_handle", np.int32))


def _enum_index(prop: str, name: str) -> int:
    return bpy.types.Keyframe.bl_rna.properties[prop].enum_items.keys().index(name)


def channelbag(obj, create: bool = False):
    """The F-curve container of the object's action (the slot's channelbag in Blender 4.4+, the action before)."""
    ad = obj.animation_data
    if ad is None or ad.action is None:
        return None
    slot = getattr(ad, "action_slot", None)
    if slot is not None:
        from bpy_extras import anim_utils

        if create:
            return anim_utils.action_ensure_channelbag_for_slot(ad.action, slot)
        return anim_utils.action_get_channelbag_for_slot(ad.action, slot)
    return ad.action


def bone_path(name: str, prop: str) -> str:
    return f'pose.bones["{bpy.utils.escape_identifier(name)}"].{prop}'


def bone_of(data_path: str) -> str:
    """The bone name of a pose bone's curve path (:func:`bone_path`'s inverse); the path's head for other curves."""
    head = data_path.rsplit(".", 1)[0]
    if head.startswith('pose.bones["') and head.endswith('"]'):
        return head[len('pose.bones["'):-2].replace('\\"', '"').replace("\\\\", "\\")
    return head


def scan(fc) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A curve's keys: ``frame, value, type, selected``."""
    kp = fc.keyframe_points
    n = len(kp)
    co = np.zeros(2 * n, np.float32)
    typ = np.zeros(n, np.int32)
    sel = np.zeros(n, np.int32)
    if n:
        kp.foreach_get("co", co)
        kp.foreach_get("type", typ)
        kp.foreach_get("select_control_point", sel)
    return co[0::2], co[1::2], typ, sel.astype(bool)


def _flat(kp, y: np.ndarray) -> bool:
    """Whether keys of one value ``y`` with level handles and Bezier, linear or constant interpolation make a curve
    that is that value everywhere: Blender's evaluation between and beyond such keys is the key value exactly."""
    if np.ptp(y):
        return False
    n = len(kp)
    ipo = np.zeros(n, np.int32)
    kp.foreach_get("interpolation", ipo)
    if not np.isin(ipo, [_enum_index("interpolation", m) for m in ("BEZIER", "LINEAR", "CONSTANT")]).all():
        return False
    for name in ("handle_left", "handle_right"):
        h = np.zeros(2 * n, np.float32)
        kp.foreach_get(name, h)
        if (h[1::2] != y[0]).any():
            return False
    return True


def curve_values(fc, default: float, frames) -> np.ndarray:
    """``(F,)``: an F-curve's values at ``frames``: a key's own value where the curve has a key at the frame, before
    its first or after its last key the end key's value where the curve extrapolates constantly, the value of a
    constant curve (:func:`_flat`) anywhere (what Blender evaluates there), else the curve evaluated; ``default`` (the
    property's value) without a curve or with a muted one."""
    frames = np.asarray(frames, dtype=np.float64)
    if fc is None or fc.mute:
        return np.full(len(frames), float(default))
    out = np.full(len(frames), np.nan)
    n = len(fc.keyframe_points)
    if n and not len(fc.modifiers):
        co = np.zeros(2 * n, np.float32)
        fc.keyframe_points.foreach_get("co", co)
        order = np.argsort(co[0::2], kind="stable")
        x, y = co[0::2][order].astype(np.float64), co[1::2][order].astype(np.float64)
        i = np.clip(np.searchsorted(x, frames), 0, n - 1)
        hit = x[i] == frames
        out[hit] = y[i[hit]]
        if fc.extrapolation == "CONSTANT":  # outside the keys (the frames before a clip's first key, read as context)
            out[frames < x[0]], out[frames > x[-1]] = y[0], y[-1]
        if np.isnan(out).any() and _flat(fc.keyframe_points, y):  # a constant curve (a BVH's unused bone offsets)
            out[:] = y[0]
    miss = np.flatnonzero(np.isnan(out))
    out[miss] = [fc.evaluate(float(frames[t])) for t in miss]
    return out


class ArmatureCurves(Curves):
    """The F-curves of an armature's action (``bag``: its channelbag, ``None`` without an action).  Built for one fill
    (an operator's call): a channel's keys are read from Blender once and again only after this object changed them,
    so keys changed from elsewhere meanwhile are not seen."""

    def __init__(self, obj):
        self.obj, self.bag = obj, channelbag(obj)
        self.gen = _enum_index("type", GENERATED)
        self.mine = _enum_index("type", "KEYFRAME")
        self._scanned: dict = {}  # channel -> its keys as last read (dropped when this object changes the curve)

    def fcurve(self, path: str, index: int):
        return self.bag.fcurves.find(path, index=index) if self.bag is not None else None

    def _changed(self, channel) -> None:
        self._scanned.pop(tuple(channel), None)

    def bone_channels(self, bones) -> list:
        """The channels of the rotation and location curves (any rotation mode's) of the pose bones ``bones``."""
        heads = {bone_path(b, "")[:-1] for b in bones}
        return [(fc.data_path, fc.array_index) for fc in (self.bag.fcurves if self.bag is not None else ())
                if fc.data_path.rsplit(".", 1)[0] in heads and fc.data_path.rsplit(".", 1)[-1] in ROT_LOC]

    def keys(self, channel) -> Keys | None:
        """A channel's keys; read from Blender once per fill until this object changes the curve (a fill reads each
        channel's keys three or four times)."""
        hit = self._scanned.get(tuple(channel))
        if hit is None:
            fc = self.fcurve(*channel)
            if fc is None:
                return None
            x, y, typ, sel = scan(fc)
            hit = self._scanned[tuple(channel)] = (x, y, typ == self.gen, sel)
        return Keys(*(a.copy() for a in hit))

    def evaluate(self, channel, frames) -> np.ndarray:
        fc = self.fcurve(*channel)
        return np.array([fc.evaluate(k) for k in frames])

    def bone(self, channel) -> str:
        return bone_of(channel[0])

    def set_generated(self, channel, indices, generated: bool) -> None:
        fc = self.fcurve(*channel)
        typ = np.zeros(len(fc.keyframe_points), np.int32)
        fc.keyframe_points.foreach_get("type", typ)
        typ[indices] = self.gen if generated else self.mine
        fc.keyframe_points.foreach_set("type", typ)
        self._changed(channel)

    def add(self, channel, frame: int) -> None:
        path, index = channel
        pb = self.obj.pose.bones[bone_of(path)]
        pb.keyframe_insert(path.rsplit(".", 1)[1], index=index, frame=frame, group=pb.name)
        self._changed(channel)

    def write(self, channel, frames, values, spans) -> None:
        prefs = bpy.context.preferences.edit
        write_curve(self.fcurve(*channel), frames, values, spans, prefs.keyframe_new_interpolation_type,
                    prefs.keyframe_new_handle_type)
        self._changed(channel)

    def load_record(self):
        return record.entry(self.obj)

    def store_record(self, entry: dict) -> None:
        record.store(self.obj, entry)


class OnArmature:
    """What every rig of an armature shares (:class:`~.rig.Rig`, :class:`~.humanoid.HumanoidRig`,
    :class:`~.rigify.RigifyRig`): its F-curves by path (``curves``: its :class:`ArmatureCurves`)."""

    curves: ArmatureCurves

    def fcurve(self, path: str, index: int):
        return self.curves.fcurve(path, index)


# ---------------------------------------------------------------------------------------------- writing keys
def _points(fc) -> dict:
    kp = fc.keyframe_points
    n = len(kp)
    arr = {}
    for name in POINT_FLOATS:
        a = np.zeros(2 * n, dtype=np.float32)
        kp.foreach_get(name, a)
        arr[name] = a.reshape(n, 2)
    for name, dt in POINT_SCALARS:
        a = np.zeros(n, dtype=dt)
        kp.foreach_get(name, a)
        arr[name] = a
    return arr


def write_curve(fc, frames: np.ndarray, values: np.ndarray, spans, interp: str, handle: str) -> None:
    """Key ``values`` at ``frames`` on ``fc``; generated keys already inside the filled ``spans`` ``[(lo, hi)]`` are
    replaced, every other key is kept with all its properties; the keys at the span ends get frozen (``FREE``)
    handles and the keys outside keep theirs (Blender's recalculation is not bit-stable), so the curve outside the
    spans keeps its shape exactly."""
    old = _points(fc)
    x = old["co"][:, 0]
    gen = _enum_index("type", GENERATED)
    inside = np.zeros(len(x), dtype=bool)
    for lo, hi in spans:
        inside |= (x > lo + 1e-4) & (x < hi - 1e-4)
    drop = inside & (old["type"] == gen)
    keep = {k: v[~drop] for k, v in old.items()}
    free = _enum_index("handle_left_type", "FREE")
    for lo, hi in spans:
        for edge, outer in ((lo, "handle_left"), (hi, "handle_right")):
            at = np.nonzero(np.abs(keep["co"][:, 0] - edge) < 1e-4)[0]
            for i in at:
                keep["handle_left_type"][i] = keep["handle_right_type"][i] = free
                inner = "handle_right" if outer == "handle_left" else "handle_left"
                co, h = keep["co"][i], keep[inner][i]
                dx = h[0] - co[0]
                if abs(dx) > 1e-6:  # the inner handle: same slope, a third of a frame long
                    third = np.float32(1.0 / 3.0) * np.sign(dx)
                    keep[inner][i] = (co[0] + third, co[1] + (h[1] - co[1]) * third / dx)
    n_new = len(frames)
    new = {
        "co": np.stack([frames.astype(np.float32), values.astype(np.float32)], -1),
        "interpolation": np.full(n_new, _enum_index("interpolation", interp), np.int32),
        "handle_left_type": np.full(n_new, _enum_index("handle_left_type", handle), np.int32),
        "handle_right_type": np.full(n_new, _enum_index("handle_right_type", handle), np.int32),
        "type": np.full(n_new, gen, np.int32),
        "easing": np.zeros(n_new, np.int32),
        "back": np.full(n_new, 1.70158, np.float32), "amplitude": np.full(n_new, 0.8, np.float32),
        "period": np.full(n_new, 4.1, np.float32),
        "select_control_point": np.zeros(n_new, np.int32), "select_left_handle": np.zeros(n_new, np.int32),
        "select_right_handle": np.zeros(n_new, np.int32),
    }
    new["handle_left"] = new["co"] - np.array([1.0 / 3.0, 0.0], np.float32)
    new["handle_right"] = new["co"] + np.array([1.0 / 3.0, 0.0], np.float32)
    allp = {k: np.concatenate([keep[k], new[k]]) for k in keep}
    order = np.argsort(allp["co"][:, 0], kind="stable")
    allp = {k: v[order] for k, v in allp.items()}
    kp = fc.keyframe_points
    total = len(order)
    same = total == len(kp)  # then a property whose values are the curve's already is left as it is (a re-fill)
    if total > len(kp):
        kp.add(total - len(kp))
    elif total < len(kp):
        for _ in range(len(kp) - total):
            kp.remove(kp[len(kp) - 1], fast=True)
    for name in POINT_FLOATS + tuple(n for n, _ in POINT_SCALARS):
        if not (same and np.array_equal(allp[name], old[name])):
            kp.foreach_set(name, np.ascontiguousarray(allp[name]).reshape(-1))
    fc.update()
    x = allp["co"][:, 0]
    outside = np.ones(total, dtype=bool)
    for lo, hi in spans:
        outside &= (x <= lo + 1e-4) | (x >= hi - 1e-4)
    if len(kp) == total and outside.any():  # the keys outside the spans keep their handles bit for bit
        for name in ("handle_left", "handle_right"):
            h = np.zeros(2 * total, dtype=np.float32)
            kp.foreach_get(name, h)
            h = h.reshape(total, 2)
            h[outside] = allp[name][outside]
            kp.foreach_set(name, h.reshape(-1))
