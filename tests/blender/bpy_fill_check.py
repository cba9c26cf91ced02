"""Runs inside real Blender (the ``bpy`` package, Python 3.11): installs the built extension into a throw-away user
directory, imports a BVH with Blender's own importer, thins its keys, runs ``anim.inbetween_fill`` and records what
happened.  Driven by tests/test_blender_addon.py:

    python bpy_fill_check.py CONFIG.json   (the bpy venv's python; BLENDER_USER_RESOURCES set to a temp dir)

CONFIG: {"zip": path, "bvh": path, "out": folder, "scenarios": [{"name", "kind", "keys_every", "rotate_mode", ...}]}.
Writes ``out/<name>.json`` (and ``out/<name>_heads.npy``: pose-bone heads of the model's bones, every frame of the
filled range) per scenario.
"""
from __future__ import annotations

import json
import os
import sys
import time
import traceback

import bpy
import numpy as np


def install(zip_path: str) -> None:
    bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
    if not hasattr(bpy.ops.anim, "inbetween_fill") or "inbetween_fill" not in dir(bpy.ops.anim):
        raise SystemExit("the extension did not register anim.inbetween_fill")


def fresh() -> None:
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob)
    for a in list(bpy.data.actions):
        bpy.data.actions.remove(a)
    for a in list(bpy.data.armatures):
        bpy.data.armatures.remove(a)


def channelbag(obj):
    ad = obj.animation_data
    if ad.action is None:  # unassigned for a test: the clip's action is still there
        return bpy.data.actions[0].layers[0].strips[0].channelbags[0] if hasattr(bpy.data.actions[0], "layers") and \
            bpy.data.actions[0].layers else bpy.data.actions[0]
    slot = getattr(ad, "action_slot", None)
    if slot is not None:
        from bpy_extras import anim_utils

        return anim_utils.action_get_channelbag_for_slot(ad.action, slot)
    return ad.action


def import_bvh(path: str, rotate_mode: str):
    bpy.ops.import_anim.bvh(filepath=path, rotate_mode=rotate_mode, update_scene_fps=True, update_scene_duration=True)
    obj = bpy.context.view_layer.objects.active
    assert obj is not None and obj.type == "ARMATURE", obj
    return obj


def thin(obj, keep: set[int]) -> None:
    """Delete every key not at a frame in ``keep`` (on every F-curve)."""
    for fc in channelbag(obj).fcurves:
        kp = fc.keyframe_points
        n = len(kp)
        co = np.zeros(2 * n, np.float32)
        kp.foreach_get("co", co)
        x = np.round(co[0::2]).astype(int)
        stay = np.array([f in keep for f in x])
        for i in np.nonzero(~stay)[0][::-1]:
            kp.remove(kp[int(i)], fast=True)
        fc.update()


def snapshot(obj) -> dict:
    out = {}
    for fc in channelbag(obj).fcurves:
        kp = fc.keyframe_points
        n = len(kp)
        co = np.zeros(2 * n, np.float32)
        kp.foreach_get("co", co)
        typ = np.zeros(n, np.int32)
        kp.foreach_get("type", typ)
        out[(fc.data_path, fc.array_index)] = (co.reshape(n, 2).copy(), typ, fc)
    return out


def curve_values(obj, frames) -> dict:
    return {(fc.data_path, fc.array_index): np.array([fc.evaluate(f) for f in frames])
            for fc in channelbag(obj).fcurves}


def heads(obj, names, frames) -> np.ndarray:
    out = np.zeros((len(frames), len(names), 3))
    for t, f in enumerate(frames):
        bpy.context.scene.frame_set(int(f))
        for j, n in enumerate(names):
            out[t, j] = obj.matrix_world @ obj.pose.bones[n].head
    return out


def model_names():
    import importlib

    mod = sys.modules.get("bl_ext.user_default.inbetweening.operators") or importlib.import_module(
        "bl_ext.user_default.inbetweening.operators")
    return mod, list(mod.load_model("").info.skeleton.names)


def run_fill(**kw):
    """``(result set, error message or None, seconds)``."""
    t0 = time.perf_counter()
    try:
        res = bpy.ops.anim.inbetween_fill(**kw)
        return sorted(res), None, time.perf_counter() - t0
    except RuntimeError as e:
        return ["CANCELLED"], str(e), time.perf_counter() - t0


def scenario(cfg: dict, sc: dict, out_dir: str) -> dict:
    fresh()
    obj = import_bvh(cfg["bvh"], sc.get("rotate_mode", "NATIVE"))
    scene = bpy.context.scene
    mod, names = model_names()
    names = [sc.get("bone_names", {}).get(n, n) for n in names]  # a renamed armature: its own names of the joints
    first_frame, last_frame = scene.frame_start, scene.frame_end
    every = int(sc.get("keys_every", 15))
    act = obj.animation_data.action
    first_frame, last_frame = (int(round(x)) for x in act.frame_range)
    scene.frame_start, scene.frame_end = first_frame, last_frame
    keys = list(range(first_frame, last_frame + 1, every))
    thin(obj, set(keys))
    if sc.get("frame_end"):
        scene.frame_end = int(sc["frame_end"])
    if sc.get("rename"):
        old, new = sc["rename"]
        obj.data.bones[old].name = new
    if sc.get("drop_curves"):  # remove every F-curve of these bones' rotations
        cb = channelbag(obj)
        for fc in [fc for fc in cb.fcurves if any(f'"{b}"].rotation' in fc.data_path for b in sc["drop_curves"])]:
            cb.fcurves.remove(fc)
    if sc.get("drop_key"):  # remove one key of one channel: [bone, property, index, frame]
        b, prop, i, frame = sc["drop_key"]
        fc = channelbag(obj).fcurves.find(f'pose.bones["{b}"].{prop}', index=i)
        fc.keyframe_points.remove(next(k for k in fc.keyframe_points if round(k.co[0]) == frame))
    if sc.get("active_mesh"):  # the active object is not an armature
        bpy.ops.mesh.primitive_cube_add()
    if sc.get("no_animation"):
        obj.animation_data.action = None
    in_range = [k for k in keys if scene.frame_start <= k <= scene.frame_end]
    res = {"name": sc["name"], "keys": keys, "in_range_keys": in_range, "frame_start": scene.frame_start,
           "frame_end": scene.frame_end, "fps": scene.render.fps, "rotation_mode": obj.pose.bones[names[0]].rotation_mode,
           "bones": [b.name for b in obj.data.bones]}
    before = snapshot(obj)
    grid = np.arange(first_frame - 5, last_frame + 5.01, 0.25)
    values_before = curve_values(obj, grid)
    if sc.get("preview"):
        scene.use_preview_range = True
        scene.frame_preview_start, scene.frame_preview_end = sc["preview"]
    if sc.get("select"):  # select the keys at these frames (and deselect every other)
        lo_sel, hi_sel = sc["select"]
        for fc in channelbag(obj).fcurves:
            for k in fc.keyframe_points:
                k.select_control_point = lo_sel <= round(k.co[0]) <= hi_sel
    bpy.ops.ed.undo_push(message="before fill")
    res["undo_poll_before"] = bpy.ops.ed.undo.poll()
    kw = {k: sc[k] for k in ("only_selected_range", "model_path", "foot_lock") if k in sc}
    mod.LAST_FILL.clear()
    result, error, seconds = run_fill(**kw)
    res.update({"result": result, "error": error, "seconds": seconds, "feet_locked": mod.LAST_FILL.get("feet_locked"),
                "network_share": mod.LAST_FILL.get("network_share")})
    res["undo_poll_after"] = bpy.ops.ed.undo.poll()
    res["bl_options"] = sorted(bpy.types.ANIM_OT_inbetween_fill.bl_options)
    after = snapshot(obj)
    values_after = curve_values(obj, grid)
    # keys: every old key still there with its value
    lost = []
    for key, (co, _, _) in before.items():
        co2 = after[key][0]
        for x, y in co:
            hit = np.nonzero(np.abs(co2[:, 0] - x) < 1e-4)[0]
            if len(hit) != 1 or co2[hit[0], 1] != y:
                lost.append([key[0], key[1], float(x)])
    res["lost_keys"] = lost[:20]
    res["n_lost_keys"] = len(lost)
    res["changed_curves"] = sum(not np.array_equal(values_before[k], values_after.get(k)) for k in values_before)
    res["new_curves"] = sorted(f"{k[0]}[{k[1]}]" for k in values_after if k not in values_before)
    # which frames gained keys, per model channel
    chans = [c for c in after if any(f'"{n}"' in c[0] for n in names)]
    gained = {}
    for key in chans:
        had = set(np.round(before[key][0][:, 0]).astype(int)) if key in before else set()
        new = sorted(set(np.round(after[key][0][:, 0]).astype(int)) - had)
        gained[f"{key[0]}[{key[1]}]"] = [int(f) for f in new]
    res["gained"] = gained
    res["model_channels"] = len(chans)
    # curve values outside the filled range, on a quarter-frame grid
    if in_range:
        lo, hi = (sc["select_span"] if sc.get("select_span") else (in_range[0], in_range[-1]))
        outside = (grid <= lo) | (grid >= hi)
        res["max_change_outside"] = float(max(np.abs(values_before[k][outside] - values_after[k][outside]).max()
                                              for k in values_before if k in values_after))
    if in_range and result == ["FINISHED"]:
        frames = list(range(in_range[0], in_range[-1] + 1))
        renamed = dict([sc["rename"]]) if sc.get("rename") else {}
        h = heads(obj, [renamed.get(n, n) for n in names], frames)
        np.save(os.path.join(out_dir, f"{sc['name']}_heads.npy"), h)
        res["head_frames"] = frames
    if sc.get("undo"):
        if not res["undo_poll_after"]:  # no undo step from the operator: see whether pushing one helps
            bpy.ops.ed.undo_push(message="after fill")
            res["undo_poll_after_push"] = bpy.ops.ed.undo.poll()
        name = obj.name
        bpy.ops.ed.undo()
        obj = bpy.data.objects[name]
        undone = snapshot(obj)
        res["undo_equal"] = all(key in undone and np.array_equal(undone[key][0], co) for key, (co, _, _) in
                                before.items()) and len(undone) == len(before)
        res["undo_keys"] = int(sum(len(v[0]) for v in undone.values()))
        res["before_keys"] = int(sum(len(v[0]) for v in before.values()))
    if sc.get("refill"):  # fill again: the generated keys are replaced, nothing else changes
        r2, e2, _ = run_fill(**kw)
        again = snapshot(obj)
        res["refill"] = {"result": r2, "error": e2, "same": all(np.allclose(again[k][0], after[k][0], atol=1e-4)
                                                                for k in after)}
    return res


def run_script(run, out_name: str) -> None:
    """The body of a one-scenario check script: ``CONFIG.json`` (``sys.argv[1]``: ``zip``, ``out``, ...) read, the
    extension installed, ``run(cfg)`` (its dict, or ``{"crash": traceback}``) written to ``out/out_name``; then the
    process ends at once (Blender's module teardown is not needed)."""
    cfg = json.load(open(sys.argv[1]))
    install(cfg["zip"])
    try:
        res = run(cfg)
    except Exception:
        res = {"crash": traceback.format_exc()}
    json.dump(res, open(os.path.join(cfg["out"], out_name), "w"), indent=1)
    sys.stdout.flush()
    os._exit(0)


def main() -> None:
    cfg = json.load(open(sys.argv[1]))
    out_dir = cfg["out"]
    install(cfg["zip"])
    results = []
    for sc in cfg["scenarios"]:
        try:
            results.append(scenario(cfg, sc, out_dir))
        except Exception:
            results.append({"name": sc["name"], "crash": traceback.format_exc()})
    json.dump(results, open(os.path.join(out_dir, "results.json"), "w"), indent=1)


if __name__ == "__main__":
    main()
