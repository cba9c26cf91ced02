"""The animator's loop around the fill: what the model did per gap (the *Last Fill* sub-panel), the *Discard Edits*
and *Auto Re-fill* settings, and the handlers behind Auto Re-fill.

**What the model did.**  Per gap the fill re-filled: the network's share of each window (the do-no-harm blend
weight, 100 % where the model has no blend) and the frames where each foot is planted (the model's predicted contact
above one half, or the contact rule on the fill for a model without contact channels); kept in the record
(:mod:`.record`), so gaps kept from an earlier fill show what was done then.

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

from inbetweening.data.contacts import CONTACT_THRESHOLD
from inbetweening.data.mirror import side_of
from inbetweening.runtime.foot_lock import legs

from . import record

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


# ---------------------------------------------------------------------------------------------- what the model did
def _runs(frames: np.ndarray, flags: np.ndarray) -> list[list[int]]:
    """``[[start, end], ...]`` (inclusive frames) of the runs of True in ``flags`` over consecutive ``frames``."""
    out: list[list[int]] = []
    for f, on in zip(frames.tolist(), flags.tolist()):
        if on and out and out[-1][1] == f - 1:
            out[-1][1] = f
        elif on:
            out.append([f, f])
    return out


def gap_info(frames: np.ndarray, gaps, filled, model_info) -> dict:
    """``{(a, b): {"windows": [[a, b, share]], "planted": {"L": [[s, e]], "R": ...} or None}}`` for the gaps filled
    now, from the runtime's :class:`~inbetweening.runtime.fill.Filled` over ``frames`` (its rows); the shares exact
    (the next re-fill compares them with its own)."""
    out = {}
    contact = filled.contact
    sides = []
    if contact is not None and filled.feet:  # the model's feet, or those found by name (a model without them)
        sk = model_info.skeleton
        for _, _, ankle in legs(sk, filled.feet):  # a foot is planted where its ankle or toe is
            side = side_of(sk.names[ankle])
            joints = [j for j in filled.feet if j == ankle or (side and side_of(sk.names[j]) == side)]
            sides.append(({"left": "L", "right": "R"}.get(side, sk.names[ankle]), joints))
    pos = {int(f): i for i, f in enumerate(frames)}
    for a, b in gaps:
        windows = [[int(frames[i]), int(frames[j]), float(w)] for i, j, w in filled.segments
                   if a <= frames[i] and frames[j] <= b]
        planted = None
        if sides:
            rows = np.array([pos[f] for f in range(a + 1, b)])
            gen = np.arange(a + 1, b)
            planted = {name: _runs(gen, (np.nan_to_num(contact[rows][:, js]) > CONTACT_THRESHOLD).any(-1))
                       for name, js in sides}
        out[(a, b)] = {"windows": windows, "planted": planted}
    return out


def _spans(runs) -> str:
    return ", ".join(f"{s}" if s == e else f"{s}–{e}" for s, e in runs) or "none"


def summary_lines(meta: dict | None) -> list[tuple[str, str]]:
    """The Last Fill panel's lines ``(text, icon)`` for a record's meta (:func:`record.load`)."""
    if meta is None:
        return [("Not filled yet", "INFO")]
    last = meta.get("last", {})
    lines = [(f"Last fill: {last.get('gaps', 0)} gap(s) filled, {last.get('kept', 0)} kept", "IPO_BEZIER")]
    if last.get("edits"):
        lines.append((f"{last['edits']} hand edit(s) kept as keys", "KEYFRAME_HLT"))
    if last.get("partial_keys"):
        lines.append((f"{last['partial_keys']} partial key(s): some bones keyed", "KEYFRAME"))
    refilled = {tuple(g) for g in last.get("refilled", [])}
    for (a, b), gi in zip(meta["gaps"], meta["info"]):
        shares = " / ".join(f"{100 * w:.0f} %" for _, _, w in gi.get("windows", [])) or "?"
        mark = "" if (a, b) in refilled else "  (kept)"
        lines.append((f"{a}–{b}: network {shares}{mark}", "IPO_EASE_IN_OUT"))
        planted = gi.get("planted")
        if planted is not None:
            feet = " · ".join(f"{side} {_spans(runs)}" for side, runs in planted.items())
            lines.append((f"feet planted: {feet}", "BLANK1"))
    return lines


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
    from .rig import channelbag

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
    return record.digest(*parts)


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
