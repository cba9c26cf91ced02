"""Runs inside real Blender (``bpy``): partial keys.  A frame where the animator keyed the left arm only constrains
the arm; the frame's other bones are generated (not frozen at their curves), the arm's keys stay the animator's
exactly; a second fill changes nothing; changing the arm key re-fills its (last) gap only; undo restores.  Driven by
tests/test_blender_addon.py:

    python bpy_partial_check.py CONFIG.json   (CONFIG: {"zip", "bvh", "out"}; writes ``out/partial.json``)
"""
from __future__ import annotations

import os
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bpy_fill_check as chk  # noqa: E402
from bpy_loop_check import curves, equal, fill, panel, same_up_to  # noqa: E402

ARM = ("UpperArm_L", "LowerArm_L", "Hand_L")
AT = 76


def types_at(c: dict, bone: str, frame: int) -> set:
    out = set()
    for (path, _), (co, _, typ) in c.items():
        if f'"{bone}"' in path:
            out |= {int(t) for t, x in zip(typ, co[:, 0]) if abs(x - frame) < 1e-4}
    return out


def scenario(cfg: dict) -> dict:
    mod, names = chk.model_names()
    chk.fresh()
    obj = chk.import_bvh(cfg["bvh"], "NATIVE")
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 91
    chk.thin(obj, {1, 31, 61, 91})
    bpy.ops.ed.undo_push(message="keys")
    thinned = curves(obj)
    res = {"whole": fill(mod)}  # the fill without the partial key, for comparison
    bpy.ops.ed.undo_push(message="whole")
    name = obj.name
    bpy.ops.ed.undo()
    obj, scene = bpy.data.objects[name], bpy.context.scene  # (undo replaces the data blocks)
    res["whole_undone"] = equal(curves(obj), thinned)
    scene.frame_set(AT)
    for i, bone in enumerate(ARM):  # the animator raises the arm at frame 16 and keys the arm alone
        pb = obj.pose.bones[bone]
        pb.rotation_euler[0] += 0.5 if i == 0 else 0.2
        pb.keyframe_insert("rotation_euler", frame=AT, group=bone)
    bpy.ops.ed.undo_push(message="arm key")
    keyed = curves(obj)
    spine_before = {k: v for k, v in chk.curve_values(obj, [AT]).items() if '"Spine"' in k[0]}
    res["fill"] = fill(mod)
    res["partial_keys"] = mod.LAST_FILL.get("partial_keys")
    after = curves(obj)
    key_type = bpy.types.Keyframe.bl_rna.properties["type"].enum_items["KEYFRAME"].value
    gen_type = bpy.types.Keyframe.bl_rna.properties["type"].enum_items["GENERATED"].value
    res["arm_keys_kept"] = all(np.array_equal(keyed[k][0], after[k][0][np.isin(after[k][0][:, 0], keyed[k][0][:, 0])])
                               for k in keyed if any(f'"{b}"' in k[0] for b in ARM))
    res["arm_types"] = sorted(types_at(after, "UpperArm_L", AT))
    res["spine_types"] = sorted(types_at(after, "Spine", AT))
    res["key_type"], res["gen_type"] = key_type, gen_type
    spine_after = chk.curve_values(obj, [AT])
    res["spine_moved_deg"] = float(np.degrees(max(abs(spine_after[k][0] - v[0]) for k, v in spine_before.items())))
    res["panel"] = panel()
    res["noop"] = fill(mod)
    res["noop_same"] = equal(curves(obj), after)
    first = curves(obj)
    scene.frame_set(AT)
    obj.pose.bones["LowerArm_L"].rotation_euler[0] += 0.4  # the animator changes the partial key
    obj.pose.bones["LowerArm_L"].keyframe_insert("rotation_euler", frame=AT, group="LowerArm_L")
    bpy.ops.ed.undo_push(message="arm key changed")
    before_refill = curves(obj)
    res["refill"] = fill(mod)
    again = curves(obj)
    res["left_gaps_same"] = same_up_to(first, again, 60)  # key 61 starts the re-fill: its handle into it may move
    res["own_gap_changed"] = not same_up_to(first, again, 91)
    bpy.ops.ed.undo_push(message="refill")
    bpy.ops.ed.undo()
    obj, scene = bpy.data.objects[name], bpy.context.scene
    res["undo_restores"] = equal(curves(obj), before_refill)
    return res


def main() -> None:
    chk.run_script(scenario, "partial.json")


if __name__ == "__main__":
    main()
