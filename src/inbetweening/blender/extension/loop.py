"""The animator's loop around the fill in Blender: the *Last Fill* sub-panel (what the model did per gap, from the
record: :func:`inbetweening.dcc.report.summary_lines`), the *Discard Edits* and *Auto Re-fill* settings, and the
handlers behind Auto Re-fill.  Hand edits and the re-fill plan are the DCC core's (:mod:`inbetweening.dcc`).

**Auto Re-fill.**  A ``depsgraph_update_post`` handler notices that the active armature's action changed (an update
of an Action ID) and compares a fingerprint of its keys (frames, values, key types) with the one it last saw; a
change arms a timer that re-fills once the keys have been still for :data:`SETTLE` seconds and no transform is
running (never while a key is being dragged).  The timer runs ``anim.inbetween_fill`` as an undoable operator, so the
re-fill is a step of its own.  Its own writes are not changes (the fingerprint is taken again after the fill, and the
handler ignores updates while it fills), and neither is an undo or redo (``undo_post``/``redo_post`` adopt the state
they restore: undoing a re-fill does not trigger it again).  The handlers and timer are Blender's, available the same
in 4.2 and 5.0.
"""
from __future__ import annotations

import time

import bpy
import numpy as np
from bpy.app.handlers import persistent
from bpy.props import BoolProperty

from inbetweening.dcc.record import digest
from inbetweening.dcc.report import summary_lines

from . import record
from .curves import channelbag

SETTLE = 0.3  # seconds the keys must stay unchanged before Auto Re-fill runs
BUSY_MODAL = ("TRANSFORM_OT", "GRAPH_OT", "ACTION_OT", "ANIM_OT", "POSE_OT")  # modal tools that move keys
FILL_OP = "anim.inbetween_fill"


def discard_edits_property():
    """The ``discard_edits`` option (the operator's and the panel's settings share it)."""
    return BoolProperty(
        name="Discard Edits",
        description="Re-fill every gap and replace the generated keys you edited (off: your edits are kept as keys)",
        default=False)


def auto_refill_property():
    return BoolProperty(
        name="Auto Re-fill",
        description="Re-fill the gaps next to a key you change, as soon as you let go of it (an undo step of its own)",
        default=False, update=lambda self, context: forget())


class _LastFillPanel:
    bl_region_type = "UI"
    bl_category = "In-between"
    bl_label = "Last Fill"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        return obj is not None and obj.type == "ARMATURE"

    def draw(self, context):
        col = self.layout.column(align=True)
        meta, _ = record.load(context.active_object)
        for text, icon in summary_lines(meta):
            col.label(text=text, icon=icon)


class INBETWEEN_PT_last_fill_dopesheet(_LastFillPanel, bpy.types.Panel):
    bl_space_type = "DOPESHEET_EDITOR"
    bl_idname = "INBETWEEN_PT_last_fill_dopesheet"
    bl_parent_id = "INBETWEEN_PT_dopesheet"


class INBETWEEN_PT_last_fill_graph(_LastFillPanel, bpy.types.Panel):
    bl_space_type = "GRAPH_EDITOR"
    bl_idname = "INBETWEEN_PT_last_fill_graph"
    bl_parent_id = "INBETWEEN_PT_graph"


class INBETWEEN_PT_last_fill_view3d(_LastFillPanel, bpy.types.Panel):
    bl_space_type = "VIEW_3D"
    bl_idname = "INBETWEEN_PT_last_fill_view3d"
    bl_parent_id = "INBETWEEN_PT_view3d"


# ---------------------------------------------------------------------------------------------- Auto Re-fill
_seen: dict = {}      # (object name, action name) -> fingerprint of its keys last seen
_pending: dict = {}   # what to re-fill: scene, object, fingerprint, when it changed last
_busy = False


def fingerprint(obj) -> str | None:
    """A digest of every key of the armature's animation (frame, value, key type per F-curve)."""
    cb = channelbag(obj) if obj is not None and obj.type == "ARMATURE" else None
    if cb is None:
        return None
    parts = []
    for fc in cb.fcurves:
        n = len(fc.keyframe_points)
        co = np.zeros(2 * n, np.float32)
        typ = np.zeros(n, np.int32)
        fc.keyframe_points.foreach_get("co", co)
        fc.keyframe_points.foreach_get("type", typ)
        parts += [f"{fc.data_path}[{fc.array_index}]".encode(), co, typ]
    return digest(*parts)


def _key(obj):
    action, _ = record.holder(obj)
    return obj.name, action.name if action is not None else ""


def adopt(obj) -> None:
    """Take the armature's keys as they are now as seen (after a fill, an undo or a redo): not a change to re-fill."""
    if obj is not None and obj.type == "ARMATURE" and obj.animation_data is not None:
        _seen[_key(obj)] = fingerprint(obj)
    _pending.clear()


def forget() -> None:
    _seen.clear()
    _pending.clear()


def _active(scene, view_layer=None):
    layer = view_layer or bpy.context.view_layer
    obj = layer.objects.active if layer is not None else None
    return obj if obj is not None and obj.type == "ARMATURE" and obj.animation_data is not None else None


@persistent
def on_depsgraph_update(scene, depsgraph) -> None:
    """Arm the re-fill when the active armature's keys changed (Auto Re-fill on)."""
    settings = getattr(scene, "inbetween_settings", None)
    if _busy or settings is None or not settings.auto_refill:
        return
    if not any(isinstance(u.id, bpy.types.Action) for u in depsgraph.updates):
        return
    obj = _active(scene, depsgraph.view_layer)
    if obj is None or record.load(obj)[0] is None:  # only an armature filled before
        return
    fp = fingerprint(obj)
    if _seen.get(_key(obj)) == fp:
        return
    _pending.update(scene=scene.name, obj=obj.name, fingerprint=fp, at=time.monotonic())
    if not bpy.app.timers.is_registered(tick):
        bpy.app.timers.register(tick, first_interval=SETTLE)


@persistent
def on_undo_redo(scene, *_) -> None:
    adopt(_active(scene))


@persistent
def on_load(*_) -> None:
    forget()


def _moving() -> bool:
    """Whether a tool that moves keys is running (a drag in the Graph Editor or Dope Sheet)."""
    wm = bpy.context.window_manager
    for win in getattr(wm, "windows", ()):
        for op in getattr(win, "modal_operators", ()):
            if op.bl_idname.startswith(BUSY_MODAL):
                return True
    return False


def tick() -> float | None:
    """The Auto Re-fill timer: re-fill once the keys have settled; returns when to look again (None: done)."""
    global _busy
    if not _pending:
        return None
    wait = _pending["at"] + SETTLE - time.monotonic()
    if wait > 0:
        return wait
    if _moving():
        return SETTLE
    scene = bpy.data.scenes.get(_pending["scene"])
    obj = bpy.data.objects.get(_pending["obj"])
    _pending.clear()
    if scene is None or obj is None or not scene.inbetween_settings.auto_refill:
        return None
    s = scene.inbetween_settings
    wm = bpy.context.window_manager
    win = next(iter(getattr(wm, "windows", ())), None)
    override = {"window": win} if win is not None else {}
    _busy = True
    try:
        with bpy.context.temp_override(**override, scene=scene, active_object=obj, object=obj):
            bpy.ops.anim.inbetween_fill("EXEC_DEFAULT", True, only_selected_range=s.only_selected_range,
                                        model_path=s.model_path, foot_lock=s.foot_lock, self_check=s.self_check,
                                        discard_edits=False)
    except RuntimeError as e:  # the fill's own error report (nothing was changed)
        print(f"In-between Auto Re-fill: {e}")
    finally:
        _busy = False
        adopt(obj)
    return None


CLASSES = (INBETWEEN_PT_last_fill_dopesheet, INBETWEEN_PT_last_fill_graph, INBETWEEN_PT_last_fill_view3d)
HANDLERS = ((bpy.app.handlers.depsgraph_update_post, on_depsgraph_update), (bpy.app.handlers.undo_post, on_undo_redo),
            (bpy.app.handlers.redo_post, on_undo_redo), (bpy.app.handlers.load_post, on_load))


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    for handlers, fn in HANDLERS:
        if fn not in handlers:
            handlers.append(fn)


def unregister():
    for handlers, fn in HANDLERS:
        if fn in handlers:
            handlers.remove(fn)
    if bpy.app.timers.is_registered(tick):
        bpy.app.timers.unregister(tick)
    forget()
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
