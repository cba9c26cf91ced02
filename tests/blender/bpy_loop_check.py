"""Runs inside real Blender (``bpy``): the animator's loop of the extension (hand edits kept, only the changed gaps
re-filled, undo, Discard Edits, Auto Re-fill, the Last Fill panel).  Driven by tests/test_blender_addon.py:

    python bpy_loop_check.py CONFIG.json   (the bpy venv's python; BLENDER_USER_RESOURCES set to a temp dir)

CONFIG: {"zip", "bvh", "out", "model_path" (optional), "every", "only_panel", "human", "weights" (a real clip),
"turn" (the hips' turn at key 71 there, radians; default 1)}.
Writes ``out/loop.json``.
"""
from __future__ import annotations

import importlib
import json
import os
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bpy_fill_check as chk  # noqa: E402
from bpy_humanoid_check import POSES, MockLayout, add_rig, key_poses  # noqa: E402

EDIT = ('pose.bones["Neck"].rotation_euler', 0)
HIPS = ('pose.bones["Hips"].rotation_euler', 0)


def ext(name):
    return importlib.import_module(f"bl_ext.user_default.inbetweening.{name}")


def curves(obj) -> dict:
    """Every key of every F-curve: ``{(path, index): (co (n, 2), handles (n, 4), type (n,))}``."""
    out = {}
    for fc in chk.channelbag(obj).fcurves:
        kp = fc.keyframe_points
        n = len(kp)
        co, hl, hr = (np.zeros(2 * n, np.float32) for _ in range(3))
        typ = np.zeros(n, np.int32)
        kp.foreach_get("co", co)
        kp.foreach_get("handle_left", hl)
        kp.foreach_get("handle_right", hr)
        kp.foreach_get("type", typ)
        out[(fc.data_path, fc.array_index)] = (co.reshape(n, 2), np.concatenate([hl.reshape(n, 2), hr.reshape(n, 2)],
                                                                                1), typ)
    return out


def same_up_to(a: dict, b: dict, frame: float) -> bool:
    """Whether two :func:`curves` agree bit for bit on the keys up to ``frame`` (frames, values, handles, types)."""
    for k in a:
        ma, mb = a[k][0][:, 0] <= frame, b[k][0][:, 0] <= frame
        if not all(np.array_equal(x[ma], y[mb]) for x, y in zip(a[k], b[k])):
            return False
    return a.keys() == b.keys()


def values(obj, lo: float, hi: float) -> dict:
    grid = np.arange(lo, hi + 1e-6, 0.25)
    return {(fc.data_path, fc.array_index): np.array([fc.evaluate(f) for f in grid]) for fc in chk.channelbag(obj).fcurves}


def equal(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(all(np.array_equal(x, y) for x, y in zip(a[k], b[k])) for k in a)


def key_at(obj, chan, frame):
    fc = chk.channelbag(obj).fcurves.find(chan[0], index=chan[1])
    return next(k for k in fc.keyframe_points if abs(k.co[0] - frame) < 1e-4)


def move_key(obj, src: int, dst: int) -> None:
    """Move the key at ``src`` to ``dst`` on every curve, as a drag in the Dope Sheet does (it replaces what is at
    ``dst``)."""
    for fc in chk.channelbag(obj).fcurves:
        kp = fc.keyframe_points
        for k in [k for k in kp if abs(k.co[0] - dst) < 1e-4]:
            kp.remove(k, fast=True)
        for k in kp:
            if abs(k.co[0] - src) < 1e-4:
                k.co[0] += dst - src
                k.handle_left[0] += dst - src
                k.handle_right[0] += dst - src
        fc.update()


def fill(mod, **kw) -> dict:
    result, error, seconds = chk.run_fill(**kw)
    return {"result": result, "error": error, "seconds": seconds,
            **{k: mod.LAST_FILL.get(k) for k in ("gaps", "kept", "edits", "refilled", "feet_locked")}}


def panel() -> list:
    p = type("P", (), {"layout": MockLayout()})()
    ext("loop")._LastFillPanel.draw(p, bpy.context)
    return [x[1] for x in p.layout.log if x[0] == "label"]


def record_meta(obj) -> str:
    return json.dumps(ext("record").load(obj)[0], sort_keys=True)


def scenario(cfg: dict) -> dict:
    mod, _ = chk.model_names()
    loop = ext("loop")
    chk.fresh()
    obj = chk.import_bvh(cfg["bvh"], "NATIVE")
    scene = bpy.context.scene
    every = int(cfg.get("every", 15))
    scene.frame_start, scene.frame_end = 1, 121
    chk.thin(obj, set(range(1, 122, every)))
    kw = {"model_path": cfg["model_path"]} if cfg.get("model_path") else {}
    if "self_check" in cfg:  # the operator's and the panel's (Auto Re-fill fills with the panel's)
        kw["self_check"] = bpy.context.scene.inbetween_settings.self_check = bool(cfg["self_check"])
    res = {"first": fill(mod, **kw), "panel_first": panel()}
    first = curves(obj)
    res["noop"] = fill(mod, **kw)
    res["noop_same"] = equal(curves(obj), first)
    if cfg.get("only_panel"):
        return res

    # the animator edits a generated key and moves a key
    k = key_at(obj, EDIT, 100)
    res["edit_type_before"] = k.type
    k.co[1] += 0.3
    edited = float(k.co[1])
    move_key(obj, 46, 48)
    bpy.ops.ed.undo_push(message="edits")
    before_refill, meta_before, edited_values = curves(obj), record_meta(obj), values(obj, 1, 31)
    res["refill"] = fill(mod, **kw)
    after = curves(obj)
    k = key_at(obj, EDIT, 100)
    res["edit_kept"] = float(k.co[1]) == edited
    res["edit_type_after"] = k.type
    res["far_keys_same"] = same_up_to(before_refill, after, 30)  # key 31 starts the re-fill: its handle into it is frozen
    res["far_values_same"] = all(np.array_equal(v, values(obj, 1, 31)[k]) for k, v in edited_values.items())
    res["far_key_values_as_first_fill"] = all(np.array_equal(first[k][0][first[k][0][:, 0] <= 31],
                                                             after[k][0][after[k][0][:, 0] <= 31]) for k in first)
    res["near_changed"] = not same_up_to(first, after, 61)
    res["panel"] = panel()
    res["again"] = fill(mod, **kw)
    res["again_same"] = equal(curves(obj), after)

    # undo the re-fill: the edits without it, and the record as it was
    name = obj.name
    bpy.ops.ed.undo_push(message="refill")
    bpy.ops.ed.undo()
    obj = bpy.data.objects[name]
    res["undo_curves"] = equal(curves(obj), before_refill)
    res["undo_record"] = record_meta(obj) == meta_before
    bpy.ops.ed.redo()
    obj = bpy.data.objects[name]
    res["redo_curves"] = equal(curves(obj), after)

    # the re-fill against a fill of every gap with the same keys (another setting re-fills every gap, edits kept; and
    # back: every gap again)
    res["full"] = fill(mod, foot_lock=False, **kw)
    res["full_edit_kept"] = float(key_at(obj, EDIT, 100).co[1]) == edited
    res["full_again"] = fill(mod, **kw)
    full = curves(obj)
    res["partial_vs_full"] = max(float(np.abs(after[k][0] - full[k][0]).max()) for k in after)
    after = full

    # save and reload: the record comes back with the file (nothing to re-fill)
    path = os.path.join(cfg["out"], "loop.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    obj = bpy.data.objects[name]
    res["reloaded"] = fill(mod, **kw)
    res["reloaded_same"] = equal(curves(obj), after)

    # Discard Edits: every gap re-filled, the edit replaced
    res["discard"] = fill(mod, discard_edits=True, **kw)
    k = key_at(obj, EDIT, 100)
    res["discard_type"], res["discard_value_changed"] = k.type, float(k.co[1]) != edited

    # Auto Re-fill: a changed key arms the timer, the re-fill runs once, its own writes and an undo do not re-arm it
    bpy.ops.ed.undo_push(message="discard")
    bpy.context.scene.inbetween_settings.auto_refill = True
    loop.SETTLE = 0.0
    bpy.context.view_layer.update()
    res["auto_idle"] = dict(loop._pending)
    key_at(obj, EDIT, 106).co[1] += 0.2
    bpy.context.view_layer.update()
    res["auto_armed"] = bool(loop._pending) and bpy.app.timers.is_registered(loop.tick)
    mod.LAST_FILL.clear()
    loop.tick()
    res["auto_fill"] = {k: mod.LAST_FILL.get(k) for k in ("gaps", "kept", "refilled")}
    bpy.context.view_layer.update()
    res["auto_after_own_write"] = dict(loop._pending)
    bpy.ops.ed.undo_push(message="auto")
    bpy.ops.ed.undo()
    obj = bpy.data.objects[name]
    bpy.context.view_layer.update()
    res["auto_after_undo"] = dict(loop._pending)
    bpy.context.scene.inbetween_settings.auto_refill = False
    bpy.context.scene.inbetween_settings.self_check = True
    return res


def weights(cfg: dict) -> dict:
    """A real clip keyed every 10 frames, filled; the hips of key 71 turned (``turn`` rad) and filled again: the self-check
    at 61, 71 and 81 changes, and with it the network share of gaps up to three gaps away on either side, so gaps left
    of the key's own are re-filled too; the re-fill against a fill of every gap (the record dropped)."""
    mod, _ = chk.model_names()
    chk.fresh()
    obj = chk.import_bvh(cfg["weights"], "NATIVE")
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 121
    chk.thin(obj, set(range(1, 122, 10)))
    res = {"first": fill(mod), "panel_first": panel()}
    fc = chk.channelbag(obj).fcurves.find(HIPS[0], index=HIPS[1])
    next(k for k in fc.keyframe_points if abs(k.co[0] - 71) < 1e-4).co[1] += float(cfg.get("turn", 1.0))
    fc.update()
    changed = curves(obj)
    res["refill"] = fill(mod)
    res["panel"] = panel()
    after = curves(obj)
    lo = res["refill"]["refilled"][0][0]
    res["kept_same"] = same_up_to(changed, after, lo - 1)  # (key lo starts the re-fill: its handle into it is frozen)
    action, _ = ext("record").holder(obj)
    del action[ext("record").RECORD]
    res["full"] = fill(mod)
    full = curves(obj)
    res["partial_vs_full"] = max(float(np.abs(after[k][0] - full[k][0]).max()) for k in after)
    return res


def humanoid() -> dict:
    """Rigify's Human meta-rig keyed at 1, 31, 61 (the bone map and ``fill_rig``): filled, filled again (nothing
    changed), a generated key of a mapped bone edited at frame 45 and filled again (the new key is self-checked: the
    share of the gap before changes)."""
    mod, _ = chk.model_names()
    chk.fresh()
    obj = add_rig("human")
    key_poses(obj, POSES, loc_bone="spine")
    res = {"first": fill(mod), "panel_first": panel()}
    res["noop"] = fill(mod)
    chan = ('pose.bones["forearm.L"].rotation_quaternion', 1)
    k = key_at(obj, chan, 45)
    res["edit_type_before"] = k.type
    k.co[1] += 0.2
    edited = float(k.co[1])
    res["refill"] = fill(mod)
    res["panel"] = panel()
    k = key_at(obj, chan, 45)
    res["edit_kept"], res["edit_type_after"] = float(k.co[1]) == edited, k.type
    return res


def everything(cfg: dict) -> dict:
    res = scenario(cfg)
    if cfg.get("human"):
        res["human"] = humanoid()
    if cfg.get("weights"):
        res["weights"] = weights(cfg)
    return res


def main() -> None:
    chk.run_script(everything, "loop.json")


if __name__ == "__main__":
    main()
