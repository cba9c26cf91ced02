"""Runs inside real Blender (``bpy``): the extension's fill of a Rigify Human meta-rig, or of the rig Rigify generates
from it, against Blender's own default interpolation for new keys (Bezier, auto-clamped) on real clips carried onto
the rig with the fill runtime's retargeting, and the fill time.  Driven by benchmarks/blender_rigify.py.

Ground truth per clip: the clip imported with Blender's BVH importer, read in the model's representation
(``rig.Rig.read``), carried onto the rig with ``Retarget(rig, model skeleton, detected bone map).to_rig`` (the rig's
rest pose as the reference; bones without a slot at rest) and keyed on every frame: on the meta-rig with
``HumanoidRig.basis_values`` (the rotation channels of the bones with a slot or between slots, the hips' location);
on the generated rig (limbs in FK) with ``RigifyRig.basis_values`` (its FK controls and ``torso``, solved against
Blender's evaluated pose: what the rig can play of the clip).  The errors are measured on the deform bones of the
slots (the meta-rig's bones; the generated rig's ``DEF-`` bones, as Blender evaluates them).
"""
from __future__ import annotations

import importlib
import json
import os
import sys
import time

import bpy
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "tests", "blender"))
import bpy_fill_check as chk  # noqa: E402


def ext(name: str):
    return importlib.import_module(f"bl_ext.user_default.inbetweening.{name}")


def model_motion(path: str):
    """The clip in the model's representation: ``root (F, 3), local_q (F, J, 4)`` at its frames."""
    chk.fresh()
    obj = chk.import_bvh(path, "NATIVE")
    first, last = (int(round(x)) for x in obj.animation_data.action.frame_range)
    info = ext("operators").load_model("").info
    r = ext("rig").Rig(obj, info)
    root, lq, _ = r.read(list(range(first, last + 1)))
    return root, lq


def metarig():
    chk.fresh()
    import addon_utils

    addon_utils.enable("rigify", default_set=True)
    bpy.ops.object.armature_human_metarig_add()
    obj = bpy.context.view_layer.objects.active
    assert obj is not None and obj.type == "ARMATURE", obj
    return obj


def generated():
    """Rigify's rig generated from a fresh Human meta-rig, its limbs switched to FK."""
    metarig()
    bpy.ops.pose.rigify_generate()
    obj = bpy.context.view_layer.objects.active
    assert obj is not None and obj.data.get("rig_id"), obj
    for pb in obj.pose.bones:
        if "IK_FK" in pb.keys():
            pb["IK_FK"] = 1.0
    return obj


def key_motion(root, lq_model, frame0: int = 1, rig_kind: str = "metarig"):
    """A fresh meta-rig (or generated rig) keyed on every frame with the clip carried onto it; ``(obj, mapped bone
    names, frames)``."""
    info = ext("operators").load_model("").info
    if rig_kind == "generated":
        obj = generated()
        hr = ext("rigify").RigifyRig(obj, info, None)
    else:
        obj = metarig()
        hr = ext("humanoid").HumanoidRig(obj, info, None)
    n = len(root)
    ident = np.tile([1.0, 0.0, 0.0, 0.0], (len(hr.names), 1))
    hr.plan(ident)
    ret = hr.retarget
    free_q = np.repeat(ident[None], n, 0)
    free_p = np.repeat(hr.offsets[None], n, 0)
    lq, lp = ret.to_rig(root, lq_model, free_q, free_p, movers=hr.movers)
    frames = list(range(frame0, frame0 + n))
    values = hr.basis_values(frames, lq, lp, {})
    for j, path, i in hr.channels():  # create the curves, then set every frame's key at once
        pb = hr.pbones[j]
        pb.keyframe_insert(path.rsplit(".", 1)[1], index=i, frame=frame0, group=pb.name)
    bag = ext("curves").channelbag(obj)
    for (_, path, i), v in values.items():
        fc = bag.fcurves.find(path, index=i)
        kp = fc.keyframe_points
        if len(kp) < n:
            kp.add(n - len(kp))
        co = np.stack([np.asarray(frames, np.float32), v.astype(np.float32)], -1).reshape(-1)
        kp.foreach_set("co", co)
        fc.update()
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = frames[0], frames[-1]
    return obj, list(hr.map.slots.values()), frames


def heads(obj, names, frames) -> np.ndarray:
    """World-space pose-bone heads ``(F, len(names), 3)`` in cm (the meta-rig's metres x 100)."""
    return 100.0 * chk.heads(obj, names, frames)


def bezier_keys(obj) -> None:
    for fc in ext("curves").channelbag(obj).fcurves:
        for k in fc.keyframe_points:
            k.interpolation = "BEZIER"
            k.handle_left_type = k.handle_right_type = "AUTO_CLAMPED"
        fc.update()


def thin(obj, keep: set[int]) -> None:
    for fc in ext("curves").channelbag(obj).fcurves:
        kp = fc.keyframe_points
        co = np.zeros(2 * len(kp), np.float32)
        kp.foreach_get("co", co)
        x = np.round(co[0::2]).astype(int)
        for i in np.nonzero([f not in keep for f in x])[0][::-1]:
            kp.remove(kp[int(i)], fast=True)
        fc.update()


def clip_errors(motion, name: str, every: int, rig_kind: str = "metarig") -> dict:
    root, lq = motion
    obj, names, frames = key_motion(root, lq, rig_kind=rig_kind)
    keys = list(range(frames[0], frames[-1] + 1, every))
    frames = list(range(keys[0], keys[-1] + 1))
    gen = [f - keys[0] for f in frames if f not in keys]
    truth = heads(obj, names, frames)
    thin(obj, set(keys))
    bezier_keys(obj)
    bez = heads(obj, names, frames)
    bpy.context.view_layer.objects.active = obj
    t0 = time.perf_counter()
    res = bpy.ops.anim.inbetween_fill()
    seconds = time.perf_counter() - t0
    assert res == {"FINISHED"}, res
    info = dict(ext("operators").LAST_FILL)
    ours = heads(obj, names, frames)

    def err(x):
        return np.linalg.norm(x[gen] - truth[gen], axis=-1)

    return {"clip": name, "keys": len(keys), "generated": len(gen), "seconds": seconds, "bones": len(names),
            "bezier_sum": float(err(bez).sum()), "fill_sum": float(err(ours).sum()), "n": int(err(bez).size),
            "model_seconds": info["model_seconds"], "solve_passes": info.get("solve_passes"),
            "solve_residual_deg": info.get("solve_residual_deg")}


def timing(motion, frames: int, n_keys: int, repeats: int, rig_kind: str = "metarig") -> list[dict]:
    root, lq = motion
    out = []
    mod = ext("operators")
    for _ in range(repeats):
        obj, _, _ = key_motion(root[:frames], lq[:frames], rig_kind=rig_kind)
        keys = {1 + round(i * (frames - 1) / (n_keys - 1)) for i in range(n_keys)}
        thin(obj, keys)
        bezier_keys(obj)
        bpy.context.view_layer.objects.active = obj
        calls = mod.load_model("").calls
        t0, c0 = time.perf_counter(), time.process_time()
        res = bpy.ops.anim.inbetween_fill()
        assert res == {"FINISHED"}, res
        out.append({"seconds": time.perf_counter() - t0, "cpu_seconds": time.process_time() - c0,
                    "windows": mod.load_model("").calls - calls, "channels": len(ext("curves").channelbag(obj).fcurves),
                    "model_seconds": mod.LAST_FILL["model_seconds"], "load": os.getloadavg()[0],
                    "solve_passes": mod.LAST_FILL.get("solve_passes")})
    return out


def main() -> None:
    cfg = json.load(open(sys.argv[1]))
    chk.install(cfg["zip"])
    kind = cfg.get("rig", "metarig")
    res = {"blender": bpy.app.version_string, "rig": kind, "errors": {str(e): [] for e in cfg["every"]},
           "timing": None}
    if cfg.get("timing_clip"):
        res["timing"] = timing(model_motion(cfg["timing_clip"]), cfg["timing_frames"], cfg["timing_keys"],
                               cfg["repeats"], kind)
        print("timing", res["timing"], flush=True)
    for i, path in enumerate(cfg["clips"]):
        motion = model_motion(path)
        for every in cfg["every"]:
            row = clip_errors(motion, os.path.basename(path), every, kind)
            res["errors"][str(every)].append(row)
            print(every, i, row, flush=True)
        json.dump(res, open(cfg["out"], "w"), indent=1)
    json.dump(res, open(cfg["out"], "w"), indent=1)
    sys.stdout.flush()
    os._exit(0)  # Blender 4.2's module teardown can crash after Rigify has generated a rig: nothing is left to do


if __name__ == "__main__":
    main()
