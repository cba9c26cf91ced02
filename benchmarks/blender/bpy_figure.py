"""Runs inside real Blender (``bpy``): one clip with keys every K frames, before and after the fill, for the figures
of docs/blender.md.  Driven by benchmarks/blender_figures.py."""
from __future__ import annotations

import json
import os
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "tests", "blender"))
import bpy_bench  # noqa: E402
import bpy_fill_check as chk  # noqa: E402


def main() -> None:
    cfg = json.load(open(sys.argv[1]))
    chk.install(cfg["zip"])
    _, names = chk.model_names()
    obj = chk.import_bvh(cfg["bvh"], "NATIVE")
    scene = bpy.context.scene
    first, last = (int(round(x)) for x in obj.animation_data.action.frame_range)
    last = min(last, first + cfg["frames"] - 1)
    scene.frame_start, scene.frame_end = first, last
    keys = list(range(first, last + 1, cfg["every"]))
    frames = list(range(first, keys[-1] + 1))
    grid = np.arange(first, keys[-1] + 0.001, 0.25)
    chans = [(f'pose.bones["{b}"].{p}', i) for b, p, i in cfg["channels"]]

    def sample():
        cb = chk.channelbag(obj)
        return np.array([[cb.fcurves.find(p, index=i).evaluate(x) for x in grid] for p, i in chans])

    truth, truth_c = chk.heads(obj, names, frames), sample()
    chk.thin(obj, set(keys))
    bpy_bench.bezier_keys(obj)
    bez, bez_c = chk.heads(obj, names, frames), sample()
    bpy.ops.anim.inbetween_fill()
    ours, ours_c = chk.heads(obj, names, frames), sample()
    parents = [names.index(obj.data.bones[n].parent.name) if j else -1 for j, n in enumerate(names)]
    np.savez(cfg["out"], frames=frames, keys=keys, grid=grid, truth=truth, bezier=bez, fill=ours, truth_c=truth_c,
             bezier_c=bez_c, fill_c=ours_c, parents=parents, labels=[f"{b} {p}[{i}]" for b, p, i in cfg["channels"]])


if __name__ == "__main__":
    main()
