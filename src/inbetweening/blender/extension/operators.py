"""The operator ``anim.inbetween_fill`` and the sidebar panels."""
from __future__ import annotations

import time

import bpy
import numpy as np
from bpy.props import BoolProperty, CollectionProperty, PointerProperty, StringProperty

from inbetweening.runtime import FillRuntime, InbetweenError, ModelError
from inbetweening.runtime.bone_map import BoneMapError

from . import humanoid, rig
from .bone_map_panel import (
    INBETWEEN_OT_bone_map_add,
    INBETWEEN_OT_bone_map_remove,
    INBETWEEN_PT_bone_map_dopesheet,
    INBETWEEN_PT_bone_map_graph,
    INBETWEEN_PT_bone_map_view3d,
    InbetweenBoneOverride,
    bone_map_message,
)
from .model import LICENCE, MODEL_DIR, bundled_model, load_model  # noqa: F401  (the extension's API)

LAST_FILL: dict = {}  # the summary of the last fill (for benchmarks)


def make_rig(obj, info):
    """:class:`rig.Rig` for an armature with every bone of the model's skeleton, else :class:`humanoid.HumanoidRig` (the
    bone map detected, with the override saved on the armature; ``BoneMapError`` when it is no humanoid)."""
    if obj is None or obj.type != "ARMATURE":
        raise rig.RigError("select an armature (the active object is not one)")
    if humanoid.is_model_skeleton(obj, info):
        return rig.Rig(obj, info)
    if obj.data.get("rig_id") is not None:
        raise rig.RigError(humanoid.GENERATED_RIGIFY.format(name=obj.name))
    return humanoid.HumanoidRig(obj, info, humanoid.stored_override(obj))


def fill_range(context, obj, model, only_selected: bool, report_progress=True, foot_lock: bool = True) -> dict:
    """Fill the armature ``obj``'s in-betweens with the fill runtime (``model``: its ONNX backend); returns a summary
    dict.  Raises ``rig.RigError`` / ``BoneMapError`` / ``ModelError`` / ``InbetweenError`` before changing anything.

    The model's own skeleton is filled directly (:class:`rig.Rig`); any other humanoid armature through the bone map
    and :meth:`FillRuntime.fill_rig` (:class:`humanoid.HumanoidRig`): the rotation channels of the bones with a slot or
    between slots, and the location of the bone carrying the hips, are keyed; bones without a slot (fingers, face,
    twist leaves, props) keep their own curves."""
    info = model.info
    r = make_rig(obj, info)
    any_rig = isinstance(r, humanoid.HumanoidRig)
    if r.fcurves is None:
        raise rig.RigError(f"armature '{obj.name}' has no animation: key at least two poses first")
    scene = context.scene
    lo, hi = scene.frame_start, scene.frame_end
    if any_rig:  # the key frames: any key on a rotation or location curve of a mapped bone (or one between)
        mapped = {r.names.index(b) for b in r.map.slots.values()}
        curves = [fc for fc in r.fcurves.fcurves
                  if any(fc.data_path.startswith(rig.bone_path(r.names[j], "")[:-1]) for j in mapped)
                  and fc.data_path.rsplit(".", 1)[-1] in ("location", "rotation_euler", "rotation_quaternion",
                                                          "rotation_axis_angle")]
        chans = None
    else:
        chans = r.channels()
        curves = [c for c in (r.fcurve(p, i) for _, p, i in chans) if c is not None]
    if only_selected:
        sel = rig.key_frames(curves, lo, hi, selected_only=True)
        if sel:
            lo, hi = min(sel), max(sel)
        elif scene.use_preview_range:
            lo, hi = max(lo, scene.frame_preview_start), min(hi, scene.frame_preview_end)
        else:
            raise rig.RigError("only selected range: no keys are selected and there is no preview range")
    keys = sorted(rig.key_frames(curves, lo, hi))
    gaps = [(a, b) for a, b in zip(keys, keys[1:]) if b - a > 1]
    if not gaps:
        raise rig.RigError(f"nothing to fill: frames {lo}..{hi} hold {len(keys)} key(s) and no gap between two keys")
    first, last = keys[0], keys[-1]
    p = info.n_past
    frames = np.arange(first - (p - 1), last + 1)
    known = set(range(first - (p - 1), first)) | set(keys)
    read_frames = [int(f) for f in frames if f in known]
    pos = {int(f): i for i, f in enumerate(frames)}
    wm = context.window_manager
    total_frames = sum(b - a - 1 for a, b in gaps)
    gen = np.array([f for a, b in gaps for f in range(a + 1, b)])
    idx = np.array([pos[int(f)] for f in gen])
    progress = None
    if any_rig:
        lq_k, lp_k, raw = r.read(read_frames)
        lq = np.full((len(frames),) + lq_k.shape[1:], np.nan)
        lp = np.full((len(frames),) + lp_k.shape[1:], np.nan)
        for t, f in enumerate(read_frames):
            lq[pos[f]], lp[pos[f]] = lq_k[t], lp_k[t]
        retarget = r.plan(lq[pos[first]])
        chans = r.channels()
    else:
        root_k, q_k, raw = r.read(read_frames)
        root = np.zeros((len(frames), 3))
        q = np.zeros((len(frames), info.skeleton.num_joints, 4))
        q[..., 0] = 1.0
        for t, f in enumerate(read_frames):
            root[pos[f]], q[pos[f]] = root_k[t], q_k[t]
        for a, b in gaps:  # placeholders (never read by the model): the previous key
            root[pos[a] + 1 : pos[b]], q[pos[a] + 1 : pos[b]] = root[pos[a]], q[pos[a]]
    if report_progress:
        wm.progress_begin(0, 100)

        def progress(done, total):
            wm.progress_update(int(100 * done / max(total, 1)))
    t0 = time.perf_counter()
    try:
        keys_idx = [pos[k] for k in keys]
        runtime = FillRuntime(model, foot_lock=foot_lock)
        if any_rig:
            out = runtime.fill_rig(retarget, lq, lp, keys_idx, movers=r.movers, progress=progress)
            filled = out.model
        else:
            filled = runtime.fill(root, q, keys_idx, progress=progress)
            out_r, out_q = filled.root, filled.local_q
    finally:
        if report_progress:
            wm.progress_end()
    t_model = time.perf_counter() - t0
    raw_prev = {f: raw[t] for t, f in enumerate(read_frames)}
    if any_rig:
        values = r.basis_values([int(f) for f in gen], out.local_q[idx], out.local_p[idx], raw_prev)
        if not all(np.isfinite(v).all() for v in values.values()):
            raise InbetweenError("the fill of the armature came out with non-finite values; nothing was changed")
    else:
        values = r.basis_values([int(f) for f in gen], out_r[idx], out_q[idx], raw_prev)
    prefs = context.preferences.edit
    spans = [(first, last)]
    for j, path, i in chans:
        fc = r.fcurve(path, i)
        if fc is None:
            pb = r.pbones[j]
            pb.keyframe_insert(path.rsplit(".", 1)[1], index=i, frame=first, group=pb.name)
            fc = r.fcurve(path, i)
        co = np.zeros(2 * len(fc.keyframe_points), dtype=np.float32)
        fc.keyframe_points.foreach_get("co", co)
        have = set(np.round(co[0::2]).astype(int).tolist())
        missing = [k for k in keys if k not in have]
        fr, val = gen.astype(np.float64), values[(j, path, i)]
        if missing:  # a key frame this channel has no key at: key its current value
            extra = np.array([fc.evaluate(k) for k in missing])
            fr, val = np.concatenate([fr, missing]), np.concatenate([val, extra])
        rig.write_curve(fc, fr, val, spans, prefs.keyframe_new_interpolation_type, prefs.keyframe_new_handle_type)
    summary = {"gaps": len(gaps), "frames": total_frames, "keys": len(keys), "range": (first, last),
               "model_seconds": t_model, "windows": model.calls, "feet_locked": filled.locked,
               "network_share": [w for _, _, w in filled.segments], "humanoid": any_rig}
    if any_rig:
        summary.update(bone_map=dict(r.map.slots), how=dict(r.map.how), keyed_bones=[r.names[j] for j in r.rot_bones],
                       movers=[r.names[j] for j in r.movers], rig_root=r.names[0])
    return summary


def only_selected_range_property():
    """The ``only_selected_range`` option (the operator's and the panel's settings share it)."""
    return BoolProperty(
        name="Only Selected Range",
        description="Fill only the gaps spanned by the selected keys (no keys selected: the preview range)",
        default=False)


def foot_lock_property():
    """The ``foot_lock`` option (the operator's and the panel's settings share it)."""
    return BoolProperty(
        name="Lock Feet",
        description="Hold the feet still where the model predicts them planted (models that predict foot contact)",
        default=True)


def model_path_property():
    """The ``model_path`` option (the operator's and the panel's settings share it)."""
    return StringProperty(
        name="Model", description="An exported in-betweening window model (.onnx); empty: the bundled model",
        default="", subtype="FILE_PATH")


class INBETWEEN_OT_fill(bpy.types.Operator):
    """Generate a pose on every frame between consecutive keys of the active armature with the in-betweening model
    (existing keys are kept exactly)"""

    bl_idname = "anim.inbetween_fill"
    bl_label = "Fill In-betweens"
    bl_options = {"REGISTER", "UNDO"}

    only_selected_range: only_selected_range_property()
    model_path: model_path_property()
    foot_lock: foot_lock_property()

    @classmethod
    def poll(cls, context):
        return context.active_object is not None

    def execute(self, context):
        obj = context.active_object
        t0 = time.perf_counter()
        try:
            model = load_model(self.model_path)
            info = fill_range(context, obj, model, self.only_selected_range, foot_lock=self.foot_lock)
        except (rig.RigError, BoneMapError, ModelError, InbetweenError) as e:
            self.report({"ERROR"}, bone_map_message(e) if isinstance(e, BoneMapError) else str(e))
            return {"CANCELLED"}
        context.view_layer.update()
        fps = context.scene.render.fps / context.scene.render.fps_base
        model_fps = model.info.fps
        if abs(fps - model_fps) > 0.5:
            self.report({"WARNING"}, f"the scene runs at {fps:.3g} fps, the model was trained at {model_fps:.3g} fps; "
                                     "gaps are counted in frames")
        LAST_FILL.clear()
        LAST_FILL.update(info, seconds=time.perf_counter() - t0)
        self.report({"INFO"}, f"In-between: {info['frames']} frames in {info['gaps']} gap(s) between "
                              f"{info['keys']} keys ({time.perf_counter() - t0:.2f} s)")
        return {"FINISHED"}


class InbetweenSettings(bpy.types.PropertyGroup):
    only_selected_range: only_selected_range_property()
    model_path: model_path_property()
    foot_lock: foot_lock_property()


class _Panel:
    bl_region_type = "UI"
    bl_category = "In-between"
    bl_label = "In-betweening"

    def draw(self, context):
        layout = self.layout
        settings = context.scene.inbetween_settings
        col = layout.column()
        col.prop(settings, "only_selected_range")
        col.prop(settings, "foot_lock")
        col.prop(settings, "model_path", text="Model")
        op = col.operator(INBETWEEN_OT_fill.bl_idname, icon="IPO_BEZIER")
        op.only_selected_range = settings.only_selected_range
        op.model_path = settings.model_path
        op.foot_lock = settings.foot_lock
        obj = context.active_object
        box = layout.box()
        box.scale_y = 0.7
        if obj is None or obj.type != "ARMATURE":
            box.label(text="Select an armature", icon="INFO")
        if not settings.model_path:
            for line in ("Bundled model: Bandai-Namco-2 skeleton,", "trained on CC BY-NC 4.0 data:",
                         "non-commercial use only."):
                box.label(text=line)


class INBETWEEN_PT_dopesheet(_Panel, bpy.types.Panel):
    bl_space_type = "DOPESHEET_EDITOR"
    bl_idname = "INBETWEEN_PT_dopesheet"


class INBETWEEN_PT_graph(_Panel, bpy.types.Panel):
    bl_space_type = "GRAPH_EDITOR"
    bl_idname = "INBETWEEN_PT_graph"


class INBETWEEN_PT_view3d(_Panel, bpy.types.Panel):
    bl_space_type = "VIEW_3D"
    bl_idname = "INBETWEEN_PT_view3d"


# ---------------------------------------------------------------------------------------------- bone map
CLASSES = (InbetweenSettings, InbetweenBoneOverride, INBETWEEN_OT_fill, INBETWEEN_OT_bone_map_add,
           INBETWEEN_OT_bone_map_remove, INBETWEEN_PT_dopesheet, INBETWEEN_PT_graph, INBETWEEN_PT_view3d,
           INBETWEEN_PT_bone_map_dopesheet, INBETWEEN_PT_bone_map_graph, INBETWEEN_PT_bone_map_view3d)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.inbetween_settings = PointerProperty(type=InbetweenSettings)
    bpy.types.Armature.inbetween_bone_map = CollectionProperty(
        type=InbetweenBoneOverride, name="Bone Map Override",
        description="Bones and the model's joints they play, on top of the detected bone map (In-between sidebar)")


def unregister():
    del bpy.types.Armature.inbetween_bone_map
    del bpy.types.Scene.inbetween_settings
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
