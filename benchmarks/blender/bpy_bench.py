"""Runs inside real Blender (``bpy``): the extension's fill against Blender's own default interpolation for new keys
(Bezier, auto-clamped) on real clips, and the fill time.  Driven by benchmarks/blender_fill.py."""
from __future__ import annotations

import json
import os
import sys
import time

import bpy
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "tests", "blender"))
import bpy_fill_check as chk  # noqa: E402


def heads_all(obj, names, frames):
    return chk.heads(obj, names, frames)


def bezier_keys(obj) -> None:
    """Blender's default for new keys: Bezier with auto-clamped handles on every remaining key."""
    for fc in chk.channelbag(obj).fcurves:
        for k in fc.keyframe_points:
            k.interpolation = "BEZIER"
            k.handle_left_type = k.handle_right_type = "AUTO_CLAMPED"
        fc.update()


def clip_errors(path: str, every: int, names) -> dict:
    chk.fresh()
    obj = chk.import_bvh(path, "NATIVE")
    scene = bpy.context.scene
    first, last = (int(round(x)) for x in obj.animation_data.action.frame_range)
    scene.frame_start, scene.frame_end = first, last
    keys = list(range(first, last + 1, every))
    frames = list(range(keys[0], keys[-1] + 1))
    gen = [f - keys[0] for f in frames if f not in keys]
    truth = heads_all(obj, names, frames)
    chk.thin(obj, set(keys))
    bezier_keys(obj)
    bez = heads_all(obj, names, frames)
    t0 = time.perf_counter()
    bpy.ops.anim.inbetween_fill()
    seconds = time.perf_counter() - t0
    ours = heads_all(obj, names, frames)

    def err(x):
        return np.linalg.norm(x[gen] - truth[gen], axis=-1)  # (frames, joints)

    return {"clip": os.path.basename(path), "keys": len(keys), "generated": len(gen), "seconds": seconds,
            "bezier_sum": float(err(bez).sum()), "fill_sum": float(err(ours).sum()), "n": int(err(bez).size)}


def timing(path: str, frames: int, n_keys: int, repeats: int) -> list[dict]:
    out = []
    for _ in range(repeats):
        chk.fresh()
        obj = chk.import_bvh(path, "NATIVE")
        scene = bpy.context.scene
        scene.frame_start, scene.frame_end = 1, frames
        keys = {1 + round(i * (frames - 1) / (n_keys - 1)) for i in range(n_keys)}
        chk.thin(obj, keys)
        mod, _ = chk.model_names()
        calls = mod.load_model("").calls
        t0, c0 = time.perf_counter(), time.process_time()
        bpy.ops.anim.inbetween_fill()
        out.append({"seconds": time.perf_counter() - t0, "cpu_seconds": time.process_time() - c0,
                    "windows": mod.load_model("").calls - calls,
                    "model_seconds": mod.LAST_FILL["model_seconds"], "load": os.getloadavg()[0]})
    return out


def main() -> None:
    cfg = json.load(open(sys.argv[1]))
    chk.install(cfg["zip"])
    _, names = chk.model_names()
    res = {"blender": bpy.app.version_string, "errors": {}, "timing": None}
    if cfg.get("timing_clip"):
        res["timing"] = timing(cfg["timing_clip"], cfg["timing_frames"], cfg["timing_keys"], cfg["repeats"])
        print("timing", res["timing"], flush=True)
    for every in cfg["every"]:
        rows = []
        for i, path in enumerate(cfg["clips"]):
            rows.append(clip_errors(path, every, names))
            if i % 10 == 0:
                print(every, i, rows[-1], flush=True)
        res["errors"][str(every)] = rows
    json.dump(res, open(cfg["out"], "w"), indent=1)


if __name__ == "__main__":
    main()
