"""Runs inside real Blender (``bpy``): the animator's loop on one clip for the figure of docs/blender.md (a fill with
a contact model, a generated key edited, the fill again).  Driven by benchmarks/blender_loop_figure.py."""
from __future__ import annotations

import importlib
import json
import os
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "tests", "blender"))
import bpy_fill_check as chk  # noqa: E402


def main() -> None:
    cfg = json.load(open(sys.argv[1]))
    chk.install(cfg["zip"])
    record = importlib.import_module("bl_ext.user_default.inbetweening.record")
    obj = chk.import_bvh(cfg["bvh"], "NATIVE")
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, cfg["frames"]
    keys = list(range(1, cfg["frames"] + 1, cfg["every"]))
    grid = np.arange(1, keys[-1] + 0.001, 0.25)
    path, index = cfg["channel"]
    fc = chk.channelbag(obj).fcurves.find(path, index=index)
    truth = np.array([fc.evaluate(x) for x in grid])
    chk.thin(obj, set(keys))
    out = {"keys": keys, "grid": grid.tolist(), "truth": truth.tolist(), "runs": []}
    kw = {"model_path": cfg["model_path"]}
    for step in range(2):
        if step == 1:  # the animator lifts the curve at one generated frame
            fc = chk.channelbag(obj).fcurves.find(path, index=index)
            k = next(k for k in fc.keyframe_points if abs(k.co[0] - cfg["edit"][0]) < 1e-4)
            k.co[1] += np.radians(cfg["edit"][1])
        bpy.ops.anim.inbetween_fill(**kw)
        fc = chk.channelbag(obj).fcurves.find(path, index=index)
        meta, _ = record.load(obj)
        out["runs"].append({"curve": [fc.evaluate(x) for x in grid], "gaps": meta["gaps"], "info": meta["info"],
                            "refilled": meta["last"]["refilled"],
                            "key_types": {str(round(k.co[0])): k.type for k in fc.keyframe_points}})
    json.dump(out, open(cfg["out"], "w"))
    sys.stdout.flush()
    os._exit(0)


if __name__ == "__main__":
    main()
