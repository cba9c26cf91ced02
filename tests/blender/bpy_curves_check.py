"""Runs inside real Blender (``bpy``): the extension's :func:`curve_values` (how the fill reads a channel at given
frames without evaluating the curve where it need not) against Blender's own ``FCurve.evaluate`` at every frame,
for curves with constant and linear extrapolation, a modifier, one key, a muted curve and curves of one value
(constant, or not: a tilted handle, an elastic key).  Driven by
tests/test_blender_addon.py:

    python bpy_curves_check.py CONFIG.json   (CONFIG: {"zip", "out"}; writes ``out/curves.json``)
"""
from __future__ import annotations

import importlib
import os
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bpy_fill_check as chk  # noqa: E402


def check(cfg: dict) -> dict:
    curves = importlib.import_module("bl_ext.user_default.inbetweening.curves")
    chk.fresh()
    obj = bpy.data.objects.new("keyed", None)
    bpy.context.scene.collection.objects.link(obj)
    rng = np.random.default_rng(0)
    for f in (5, 9, 10, 17, 30):
        obj.location = rng.normal(size=3)
        obj.rotation_euler = rng.normal(size=3)
        obj.keyframe_insert("location", frame=f)
        obj.keyframe_insert("rotation_euler", frame=f)
    obj.delta_location = (0.5, -0.5, 2.0)
    obj.keyframe_insert("delta_location", frame=12)  # one key only
    obj.scale = (1.5, 1.5, 1.5)
    for f in (12, 20, 26):  # one value: a constant curve, unless a handle or the interpolation says otherwise
        obj.keyframe_insert("scale", frame=f)
    bag = chk.channelbag(obj)
    fc = {(c.data_path, c.array_index): c for c in bag.fcurves}
    fc["scale", 1].keyframe_points[1].interpolation = "ELASTIC"
    tilted = fc["scale", 2].keyframe_points[1]
    tilted.handle_right_type = "FREE"
    tilted.handle_right = (tilted.handle_right[0], tilted.handle_right[1] + 0.5)
    fc["location", 1].extrapolation = "LINEAR"
    fc["location", 2].modifiers.new("CYCLES")
    fc["rotation_euler", 0].keyframe_points[2].interpolation = "LINEAR"
    fc["rotation_euler", 1].mute = True
    frames = np.concatenate([np.arange(-4.0, 36.0, 0.25), [5.0, 17.0, 30.0, -100.0, 100.0]])
    res = {}
    for (path, i), c in fc.items():
        default = list(getattr(obj, path))[i]
        ours = curves.curve_values(c, default, frames)
        theirs = np.full(len(frames), default) if c.mute else np.array([c.evaluate(float(f)) for f in frames])
        res[f"{path}[{i}]"] = {"equal": bool(np.array_equal(ours, theirs)),
                               "max_diff": float(np.abs(ours - theirs).max()), "extrapolation": c.extrapolation,
                               "varies_outside": bool(np.ptp(theirs[frames < 5]) > 0 or np.ptp(theirs[frames > 30]) > 0),
                               "varies": bool(np.ptp(theirs) > 0)}
    return res


if __name__ == "__main__":
    chk.run_script(check, "curves.json")
