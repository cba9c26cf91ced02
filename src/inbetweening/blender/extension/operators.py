"""The operator ``anim.inbetween_fill`` and the sidebar panels."""
from __future__ import annotations

import time

import bpy
import numpy as np
from bpy.props import BoolProperty, CollectionProperty, PointerProperty, StringProperty

from inbetweening.runtime import FillRuntime, InbetweenError, ModelError
from inbetweening.runtime.bone_map import BoneMapError

from . import humanoid, loop, record, rig
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


def fill_range(context, obj, model, only_selected: bool, report_progress=True, foot_lock: bool = True,
               discard_edits: bool = False) -> dict:
    """Fill the armature ``obj``'s in-betweens with the fill runtime (``model``: its ONNX backend); returns a summary
    dict.  Raises ``rig.RigError`` / ``BoneMapError`` / ``ModelError`` / ``InbetweenError`` before changing anything.
    Only what changed since the last fill is re-filled (the gaps whose inputs changed, and those the runtime adds:
    whose network share or context changed), and generated keys edited by hand are kept as keys (:mod:`.record`;
    ``discard_edits``: every gap re-filled, the edits replaced).

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
    past = record.Past(obj, r.fcurves, discard_edits)
    if only_selected:
        sel = past.key_frames(curves, lo, hi, selected_only=True)
        if sel:
            lo, hi = min(sel), max(sel)
        elif scene.use_preview_range:
            lo, hi = max(lo, scene.frame_preview_start), min(hi, scene.frame_preview_end)
        else:
            raise rig.RigError("only selected range: no keys are selected and there is no preview range")
    all_keys = sorted(past.key_frames(curves, lo, hi))
    all_gaps = [(a, b) for a, b in zip(all_keys, all_keys[1:]) if b - a > 1]
    if not all_gaps:
        raise rig.RigError(f"nothing to fill: frames {lo}..{hi} hold {len(all_keys)} key(s) and no gap between two keys")
    p = info.n_past
    reader = record.Reader(r)
    seen = list(range(all_keys[0] - (p - 1), all_keys[0])) + all_keys
    reader.read(seen)
    if any_rig:
        retarget = r.plan(reader.a[all_keys[0]])
        chans = r.channels()
    settings = record.settings_digest(record.model_key(model), foot_lock, chans, r.fcurves,
                                      getattr(r, "ancestors", ()))
    plan = past.plan(all_keys, all_gaps, p, reader.digests(seen), settings)
    summary = {"gaps": 0, "kept": len(all_gaps), "edits": past.new_edits, "keys": len(all_keys),
               "range": (all_keys[0], all_keys[-1]), "humanoid": any_rig, "model_seconds": 0.0, "windows": 0,
               "frames": 0, "feet_locked": False, "network_share": [], "refilled": []}
    if plan.nothing:
        return summary
    # every key, and the frames of the gaps the runtime may keep as they are now (the last fill's output)
    frames = np.arange(all_keys[0] - (p - 1), all_keys[-1] + 1)
    pos = {int(f): i for i, f in enumerate(frames)}
    changed = set(all_gaps) if plan.changed is None else plan.changed
    kept = [f for a, b in all_gaps if (a, b) not in changed for f in range(a + 1, b)]
    read_keys = set(seen)
    read_frames = sorted(read_keys | set(kept))
    only = None if plan.changed is None else {(pos[a], pos[b]) for a, b in plan.changed}
    previous = None if plan.previous is None else {(pos[a], pos[b]): w for (a, b), w in plan.previous.items()
                                                   if a in pos and b in pos}
    wm = context.window_manager
    progress = None
    rows = [pos[f] for f in read_frames]
    if any_rig:
        lq_k, lp_k, raw = reader.read(read_frames)
        lq = np.full((len(frames),) + lq_k.shape[1:], np.nan)
        lp = np.full((len(frames),) + lp_k.shape[1:], np.nan)
        lq[rows], lp[rows] = lq_k, lp_k
    else:
        root_k, q_k, raw = reader.read(read_frames)
        root = np.full((len(frames), 3), np.nan)
        q = np.full((len(frames), info.skeleton.num_joints, 4), np.nan)
        root[rows], q[rows] = root_k, q_k
    if report_progress:
        wm.progress_begin(0, 100)

        def progress(done, total):
            wm.progress_update(int(100 * done / max(total, 1)))
    t0 = time.perf_counter()
    try:
        keys_idx = [pos[k] for k in all_keys]
        runtime = FillRuntime(model, foot_lock=foot_lock)
        if any_rig:
            out = runtime.fill_rig(retarget, lq, lp, keys_idx, movers=r.movers, progress=progress, only=only,
                                   previous=previous)
            filled, generated = out.model, out.generated
        else:
            filled = runtime.fill(root, q, keys_idx, progress=progress, only=only, previous=previous)
            out_r, out_q, generated = filled.root, filled.local_q, filled.generated
    finally:
        if report_progress:
            wm.progress_end()
    t_model = time.perf_counter() - t0
    gaps = [(int(frames[a]), int(frames[b])) for a, b in generated]
    if not gaps:
        return summary
    first, last = gaps[0][0], gaps[-1][1]
    gen = np.array([f for a, b in gaps for f in range(a + 1, b)])
    idx = np.array([pos[int(f)] for f in gen])
    raw_prev = {f: raw[t] for t, f in enumerate(read_frames) if f in read_keys}  # Euler continuity from the keys
    if any_rig:
        values = r.basis_values([int(f) for f in gen], out.local_q[idx], out.local_p[idx], raw_prev)
        if not all(np.isfinite(v).all() for v in values.values()):
            raise InbetweenError("the fill of the armature came out with non-finite values; nothing was changed")
    else:
        values = r.basis_values([int(f) for f in gen], out_r[idx], out_q[idx], raw_prev)
    prefs = context.preferences.edit
    spans = record.runs(all_gaps, gaps)
    past.apply()
    gen_type = rig._enum_index("type", rig.GENERATED)
    for j, path, i in chans:
        fc = r.fcurve(path, i)
        if fc is None:
            pb = r.pbones[j]
            pb.keyframe_insert(path.rsplit(".", 1)[1], index=i, frame=first, group=pb.name)
            fc = r.fcurve(path, i)
        x, _, typ, _ = record.scan(fc)  # the animator's keys, and generated ones the write keeps
        xr = np.round(x).astype(int)
        mine = xr[typ != gen_type]
        have = set(mine.tolist()) | set(xr[(typ == gen_type) & ~record.inside(xr, spans)].tolist())
        missing = [k for k in all_keys if first <= k <= last and k not in have]
        free = ~np.isin(gen, mine)  # never over one of the animator's keys
        fr, val = gen[free].astype(np.float64), values[(j, path, i)][free]
        if missing:  # a key frame this channel has no key at: key its current value
            extra = np.array([fc.evaluate(k) for k in missing])
            fr, val = np.concatenate([fr, missing]), np.concatenate([val, extra])
        rig.write_curve(fc, fr, val, spans, prefs.keyframe_new_interpolation_type, prefs.keyframe_new_handle_type)
    done = loop.gap_info(frames, gaps, filled, info)
    summary.update(gaps=len(gaps), kept=len(all_gaps) - len(gaps), frames=len(gen), model_seconds=t_model,
                   windows=model.calls, feet_locked=filled.locked, refilled=[list(g) for g in gaps],
                   network_share=[w for g in gaps for _, _, w in done[g]["windows"]])
    past.commit(r.fcurves, chans, all_keys, all_gaps, p, reader.digests(seen), settings, done,
                {k: summary[k] for k in ("gaps", "kept", "edits", "refilled")})
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
    discard_edits: loop.discard_edits_property()

    @classmethod
    def poll(cls, context):
        return context.active_object is not None

    def execute(self, context):
        obj = context.active_object
        t0 = time.perf_counter()
        try:
            model = load_model(self.model_path)
            info = fill_range(context, obj, model, self.only_selected_range, foot_lock=self.foot_lock,
                              discard_edits=self.discard_edits)
        except (rig.RigError, BoneMapError, ModelError, InbetweenError) as e:
            self.report({"ERROR"}, bone_map_message(e) if isinstance(e, BoneMapError) else str(e))
            return {"CANCELLED"}
        LAST_FILL.clear()
        LAST_FILL.update(info, seconds=time.perf_counter() - t0)
        loop.adopt(obj)
        if not info["gaps"]:
            self.report({"INFO"}, f"In-between: nothing changed since the last fill ({info['kept']} gap(s) kept)")
            return {"CANCELLED"}
        context.view_layer.update()
        fps = context.scene.render.fps / context.scene.render.fps_base
        model_fps = model.info.fps
        if abs(fps - model_fps) > 0.5:
            self.report({"WARNING"}, f"the scene runs at {fps:.3g} fps, the model was trained at {model_fps:.3g} fps; "
                                     "gaps are counted in frames")
        LAST_FILL["seconds"] = time.perf_counter() - t0
        kept = f", {info['kept']} unchanged gap(s) kept" if info["kept"] else ""
        edits = f", {info['edits']} edited key(s) kept" if info["edits"] else ""
        self.report({"INFO"}, f"In-between: {info['frames']} frames in {info['gaps']} gap(s) between "
                              f"{info['keys']} keys{kept}{edits} ({time.perf_counter() - t0:.2f} s)")
        return {"FINISHED"}


class InbetweenSettings(bpy.types.PropertyGroup):
    only_selected_range: only_selected_range_property()
    model_path: model_path_property()
    foot_lock: foot_lock_property()
    discard_edits: loop.discard_edits_property()
    auto_refill: loop.auto_refill_property()


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
        col.prop(settings, "discard_edits")
        col.prop(settings, "auto_refill")
        col.prop(settings, "model_path", text="Model")
        op = col.operator(INBETWEEN_OT_fill.bl_idname, icon="IPO_BEZIER")
        op.only_selected_range = settings.only_selected_range
        op.model_path = settings.model_path
        op.foot_lock = settings.foot_lock
        op.discard_edits = settings.discard_edits
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
