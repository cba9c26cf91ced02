"""Runs inside real Blender (the ``bpy`` package): the extension fills a humanoid armature that is not the model's
skeleton (Rigify's Human meta-rig, a rig generated from it) through the bone map, and refuses an animal.  Driven by
tests/test_blender_addon.py:

    python bpy_humanoid_check.py CONFIG.json   (the bpy venv's python; BLENDER_USER_RESOURCES set to a temp dir)

CONFIG: {"zip": path, "out": folder, "scenarios": [{"name", "rig": "human" | "quadruped" | "wolf" | "generated" | "vrm",
"override": {bone: slot}, "undo": bool}]}.  Writes ``out/results.json`` and ``out/<name>_heads.npy`` (pose-bone heads
and tails of the mapped bones, every frame of the filled range, armature space; before and after the fill).
"""
from __future__ import annotations

import importlib
import json
import math
import os
import sys
import time
import traceback

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bpy_fill_check import install, run_fill, snapshot  # noqa: E402

KEYS = (1, 31, 61)
# meta-rig bone -> (axis, degrees at each key): a step, a crouch, a reach
POSES = {
    "spine": ("X", (0, 10, -5)), "spine.001": ("X", (0, 10, 5)), "spine.003": ("Y", (0, 20, -20)),
    "spine.004": ("X", (0, -10, 10)), "spine.006": ("Z", (0, 25, -15)),
    "thigh.L": ("X", (0, 60, -20)), "shin.L": ("X", (0, -70, -10)), "foot.L": ("X", (0, 20, -10)),
    "thigh.R": ("X", (0, -30, 45)), "shin.R": ("X", (0, -20, -60)), "foot.R": ("X", (0, -10, 20)),
    "upper_arm.L": ("Z", (0, 50, 20)), "forearm.L": ("X", (0, 60, 20)), "hand.L": ("Z", (0, 20, -20)),
    "upper_arm.R": ("Z", (0, -40, 10)), "forearm.R": ("X", (0, 30, 80)), "hand.R": ("Z", (0, -20, 20)),
    "shoulder.L": ("Y", (0, 10, 0)), "f_index.01.L": ("X", (0, 40, 0)),
}
# the same poses on a VRM humanoid (the VRM add-on's basic armature, bpy-vrm-format): meta-rig bone -> VRM bone
VRM_NAMES = {"spine": "hips", "spine.001": "spine", "spine.003": "chest", "spine.004": "neck", "spine.006": "head",
             "thigh": "upper_leg", "shin": "lower_leg", "foot": "foot", "upper_arm": "upper_arm",
             "forearm": "lower_arm", "hand": "hand", "shoulder": "shoulder", "f_index.01": "index_proximal"}


def vrm_name(name: str) -> str:
    if name.endswith((".L", ".R")):
        base, side = name[:-2], name[-1]
        return f"{VRM_NAMES[base]}.{side}"
    return VRM_NAMES[name]


SPINE_LOC = ((0, 0, 0), (0.1, 0.25, -0.1), (0.05, 0.6, 0.05))  # the hips bone's location channels (bone space)


def fresh() -> None:
    for coll in (bpy.data.objects, bpy.data.actions, bpy.data.armatures):
        for x in list(coll):
            coll.remove(x)


def rigify() -> None:
    import addon_utils

    addon_utils.enable("rigify", default_set=True)


def key_poses(obj, poses, loc_bone=None) -> None:
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = KEYS[0], KEYS[-1]
    for t, frame in enumerate(KEYS):
        for name, (axis, degs) in poses.items():
            pb = obj.pose.bones[name]
            pb.rotation_mode = "QUATERNION" if pb.rotation_mode == "QUATERNION" else pb.rotation_mode
            from mathutils import Euler

            e = Euler((0, 0, 0), "XYZ")
            setattr(e, axis.lower(), math.radians(degs[t]))
            if pb.rotation_mode == "QUATERNION":
                pb.rotation_quaternion = e.to_quaternion()
                pb.keyframe_insert("rotation_quaternion", frame=frame)
            elif pb.rotation_mode == "AXIS_ANGLE":
                axis, angle = e.to_quaternion().to_axis_angle()
                pb.rotation_axis_angle = (angle, *axis)
                pb.keyframe_insert("rotation_axis_angle", frame=frame)
            else:
                pb.rotation_euler = e.to_quaternion().to_euler(pb.rotation_mode)
                pb.keyframe_insert("rotation_euler", frame=frame)
        if loc_bone:
            obj.pose.bones[loc_bone].location = SPINE_LOC[t]
            obj.pose.bones[loc_bone].keyframe_insert("location", frame=frame)


def add_rig(kind: str):
    rigify()
    if kind == "human":
        bpy.ops.object.armature_human_metarig_add()
    elif kind == "quadruped":
        bpy.ops.object.armature_basic_quadruped_metarig_add()
    elif kind == "wolf":
        bpy.ops.object.armature_wolf_metarig_add()
    elif kind == "vrm":  # the VRM add-on (pip package bpy-vrm-format, module io_scene_vrm): its basic humanoid
        import addon_utils

        addon_utils.enable("io_scene_vrm", default_set=True)
        bpy.ops.icyp.make_basic_armature()
    elif kind == "generated":
        bpy.ops.object.armature_human_metarig_add()
        bpy.ops.pose.rigify_generate()
    obj = bpy.context.view_layer.objects.active
    assert obj is not None and obj.type == "ARMATURE", obj
    return obj


class MockLayout:
    """Records what a panel's ``draw`` puts in its layout (headless Blender draws no UI)."""

    def __init__(self, log=None):
        self.log = [] if log is None else log

    def _child(self, *a, **k):
        return MockLayout(self.log)

    column = row = box = split = _child

    def label(self, text="", **k):
        self.log.append(("label", text))

    def prop(self, data, prop, **k):
        assert hasattr(data, prop), prop
        self.log.append(("prop", prop))

    def prop_search(self, data, prop, search_data, search_prop, **k):
        assert hasattr(data, prop) and hasattr(search_data, search_prop), (prop, search_prop)
        self.log.append(("prop_search", prop, search_prop))

    def operator(self, idname, **k):
        self.log.append(("operator", idname))
        return type("Props", (), {})()


def draw_panel(mod) -> list:
    panel = type("P", (), {"layout": MockLayout()})()
    importlib.import_module("bl_ext.user_default.inbetweening.bone_map_panel")._BoneMapPanel.draw(panel, bpy.context)
    return [list(x) for x in panel.layout.log]


def ext_module():
    return importlib.import_module("bl_ext.user_default.inbetweening.operators")


def track(obj, names, frames) -> np.ndarray:
    """Heads and tails ``(F, 2 * len(names), 3)`` in armature space (the evaluated pose, constraints included)."""
    out = np.zeros((len(frames), 2 * len(names), 3))
    for t, f in enumerate(frames):
        bpy.context.scene.frame_set(int(f))
        dg = bpy.context.evaluated_depsgraph_get()
        ev = obj.evaluated_get(dg)
        for j, n in enumerate(names):
            out[t, 2 * j] = ev.pose.bones[n].head
            out[t, 2 * j + 1] = ev.pose.bones[n].tail
    return out


def scenario(sc: dict, out_dir: str) -> dict:
    fresh()
    obj = add_rig(sc["rig"])
    mod = ext_module()
    res = {"name": sc["name"], "bones": len(obj.data.bones)}
    if sc["rig"] == "generated":
        # the animator keys the FK controls (and the torso control for the hips' place)
        fk = {"torso": ("X", (0, 0, 0)), "hips": ("X", (0, 10, -5)), "chest": ("Y", (0, 20, -20)),
              "neck": ("X", (0, -10, 10)), "head": ("Z", (0, 25, -15)),
              "thigh_fk.L": ("X", (0, 60, -20)), "shin_fk.L": ("X", (0, -70, -10)), "foot_fk.L": ("X", (0, 20, -10)),
              "thigh_fk.R": ("X", (0, -30, 45)), "shin_fk.R": ("X", (0, -20, -60)),
              "upper_arm_fk.L": ("Z", (0, 50, 20)), "forearm_fk.L": ("X", (0, 60, 20)),
              "upper_arm_fk.R": ("Z", (0, -40, 10)), "forearm_fk.R": ("X", (0, 30, 80))}
        for side in ("L", "R"):  # switch arms and legs to FK
            for part in ("upper_arm_parent", "thigh_parent"):
                pb = obj.pose.bones.get(f"{part}.{side}")
                if pb is not None and "IK_FK" in pb:
                    pb["IK_FK"] = 1.0
        fk = {k: v for k, v in fk.items() if k in obj.pose.bones}
        res["fk_bones"] = sorted(fk)
        key_poses(obj, fk, loc_bone="torso" if "torso" in obj.pose.bones else None)
    elif sc["rig"] == "human":
        if sc.get("rotation_mode"):  # every bone in this rotation mode (Euler orders, axis-angle)
            for pb in obj.pose.bones:
                pb.rotation_mode = sc["rotation_mode"]
        key_poses(obj, POSES, loc_bone="spine")
    elif sc["rig"] == "vrm":
        key_poses(obj, {vrm_name(k): v for k, v in POSES.items()}, loc_bone="hips")
    else:
        bones = [b.name for b in obj.data.bones][:8]
        key_poses(obj, {b: ("X", (0, 20, -10)) for b in bones})
    for bone, slot in (sc.get("override") or {}).items():
        row = obj.data.inbetween_bone_map.add()
        row.bone, row.slot = bone, slot or "NONE"
    if sc.get("extra_root"):  # a second root bone (a prop): the armature gets a joint at its origin above both
        bpy.ops.object.mode_set(mode="EDIT")
        eb = obj.data.edit_bones.new(sc["extra_root"])
        eb.head, eb.tail = (0.5, 0.0, 0.0), (0.5, 0.0, 0.3)
        bpy.ops.object.mode_set(mode="OBJECT")
    if sc.get("panel"):
        res["panel"] = draw_panel(mod)
    try:
        panel_mod = importlib.import_module("bl_ext.user_default.inbetweening.bone_map_panel")
        bm, err = panel_mod.detected_map(obj, mod.load_model("").info)
        res["detected"] = dict(bm.slots) if bm else None
        res["detected_how"] = dict(bm.how) if bm else None
        res["detect_error"] = err
    except Exception:
        res["detect_crash"] = traceback.format_exc()
    if sc.get("roundtrip"):  # the BVH-convention reading and the channel writing are inverse

        rigmod = importlib.import_module("bl_ext.user_default.inbetweening.humanoid")
        hr = rigmod.HumanoidRig(obj, mod.load_model("").info, rigmod.stored_override(obj))
        lq, lp, raw = hr.read(list(KEYS))
        hr.plan(lq[0])
        vals = hr.basis_values(list(KEYS), lq, lp, {})
        err = 0.0
        for (j, path, i), v in vals.items():
            fc = hr.fcurve(path, i)
            cur = [fc.evaluate(f) if fc is not None else getattr(hr.pbones[j], path.rsplit(".", 1)[1])[i]
                   for f in KEYS]
            if "quaternion" in path:  # (sign free)
                cur = np.abs(cur)
                v = np.abs(v)
            err = max(err, float(np.abs(np.asarray(cur) - v).max()))
        res["roundtrip_error"] = err
        res["roundtrip_channels"] = len(vals)
    if sc.get("dump"):  # the armature's motion in the BVH convention, for the same fill outside Blender

        rigmod = importlib.import_module("bl_ext.user_default.inbetweening.humanoid")
        hr = rigmod.HumanoidRig(obj, mod.load_model("").info, rigmod.stored_override(obj))
        p = mod.load_model("").info.n_past
        dump_frames = list(range(KEYS[0] - (p - 1), KEYS[-1] + 1))
        lq, lp, _ = hr.read(dump_frames)
        np.savez(os.path.join(out_dir, f"{sc['name']}_dump.npz"), lq=lq, lp=lp, frames=dump_frames,
                 names=np.array(hr.names), parents=np.array(hr.parents), offsets=hr.offsets)
    before = snapshot(obj)
    grid = np.arange(KEYS[0] - 3, KEYS[-1] + 3.01, 0.5)
    values_before = {k: np.array([v[2].evaluate(f) for f in grid]) for k, v in before.items()}
    frames = list(range(KEYS[0], KEYS[-1] + 1))
    mapped = list(res["detected"].values()) if res.get("detected") else []
    if mapped:
        np.save(os.path.join(out_dir, f"{sc['name']}_before.npy"), track(obj, mapped, frames))
    bpy.ops.ed.undo_push(message="before fill")
    res["undo_poll_before"] = bpy.ops.ed.undo.poll()
    mod.LAST_FILL.clear()
    result, error, seconds = run_fill()
    res.update({"result": result, "error": error, "seconds": seconds})
    res["undo_poll_after"] = bpy.ops.ed.undo.poll()
    info = dict(mod.LAST_FILL)
    res["fill"] = {k: info.get(k) for k in ("humanoid", "keyed_bones", "movers", "bone_map", "how", "frames", "keys",
                                            "range", "rig_root")}
    after = snapshot(obj)
    lost = []
    for key, (co, _, _) in before.items():
        co2 = after[key][0]
        for x, y in co:
            hit = np.nonzero(np.abs(co2[:, 0] - x) < 1e-4)[0]
            if len(hit) != 1 or co2[hit[0], 1] != y:
                lost.append([key[0], key[1], float(x)])
    res["n_lost_keys"] = len(lost)
    res["lost_keys"] = lost[:10]
    values_after = {k: np.array([v[2].evaluate(f) for f in grid]) for k, v in after.items()}
    res["changed_curves"] = sum(not np.array_equal(values_before[k], values_after.get(k)) for k in values_before)
    res["new_curves"] = sorted(f"{k[0]}[{k[1]}]" for k in after if k not in before)
    gained = {}
    for key in after:
        had = set(np.round(before[key][0][:, 0]).astype(int)) if key in before else set()
        new = sorted(set(np.round(after[key][0][:, 0]).astype(int)) - had)
        if new:
            gained[f"{key[0]}[{key[1]}]"] = [int(f) for f in new]
    res["gained"] = gained
    outside = (grid <= KEYS[0]) | (grid >= KEYS[-1])
    res["max_change_outside"] = float(max((np.abs(values_before[k][outside] - values_after[k][outside]).max()
                                           for k in values_before), default=0.0))
    res["bezier_diff"] = float(max((np.abs(values_before[k] - values_after[k]).max() for k in values_before),
                                   default=0.0))
    if result == ["FINISHED"] and mapped:
        np.save(os.path.join(out_dir, f"{sc['name']}_after.npy"), track(obj, mapped, frames))
        res["mapped_order"] = mapped
    if sc.get("dump") and result == ["FINISHED"]:
        lq, lp, _ = hr.read(dump_frames)
        np.savez(os.path.join(out_dir, f"{sc['name']}_filled.npz"), lq=lq, lp=lp)
    if sc.get("blend"):  # the override survives a save and reload
        path = os.path.join(out_dir, f"{sc['name']}.blend")
        name = obj.name
        bpy.ops.wm.save_as_mainfile(filepath=path)
        bpy.ops.wm.open_mainfile(filepath=path)
        o = bpy.data.objects[name]
        res["reloaded_override"] = [(r.bone, r.slot) for r in o.data.inbetween_bone_map]
        obj = o
    if sc.get("undo"):
        res["mode"] = obj.mode
        res["undo_poll"] = bpy.ops.ed.undo.poll()
        if not res["undo_poll"]:
            bpy.ops.ed.undo_push(message="after fill")
        name = obj.name
        bpy.ops.ed.undo()
        obj = bpy.data.objects[name]
        undone = snapshot(obj)
        res["undo_equal"] = all(key in undone and np.array_equal(undone[key][0], co) for key, (co, _, _) in
                                before.items()) and len(undone) == len(before)
    return res


def main() -> None:
    cfg = json.load(open(sys.argv[1]))
    out_dir = cfg["out"]
    install(cfg["zip"])
    results = []
    for sc in cfg["scenarios"]:
        t0 = time.perf_counter()
        try:
            r = scenario(sc, out_dir)
        except Exception:
            r = {"name": sc["name"], "crash": traceback.format_exc()}
        r["wall"] = time.perf_counter() - t0
        results.append(r)
        with open(os.path.join(out_dir, "results.json"), "w") as f:  # after every scenario: a crash keeps the rest
            json.dump(results, f, indent=1)
    sys.stdout.flush()
    os._exit(0)  # Blender 4.2's module teardown can crash after Rigify has generated a rig: nothing is left to do


if __name__ == "__main__":
    main()
