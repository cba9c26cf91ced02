"""Runs inside real Blender (``bpy``): the latency of the animator's loop (one key changed, the gaps next to it
re-filled; nothing changed; Auto Re-fill).  Driven by benchmarks/blender_loop.py."""
from __future__ import annotations

import cProfile
import importlib
import json
import os
import pstats
import sys
import time

import bpy

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "tests", "blender"))
import bpy_fill_check as chk  # noqa: E402

CHANNEL = ('pose.bones["Hips"].rotation_euler', 0)


def nudge(obj, frame: int, step: float) -> None:
    """Change one channel of the key at ``frame`` (as an animator's drag would)."""
    fc = chk.channelbag(obj).fcurves.find(CHANNEL[0], index=CHANNEL[1])
    k = next(k for k in fc.keyframe_points if abs(k.co[0] - frame) < 1e-4)
    k.co[1] += step
    fc.update()


STAGES = (  # (stage, [(file name end, function)]): cumulative times summed over the functions
    ("the operator, end to end", [("inbetweening/operators.py", "execute")]),
    ("the rig built (armature read, bone map)", [("inbetweening/operators.py", "make_rig")]),
    ("the keys and hand edits read (record, curves)", [("dcc/edits.py", "__init__"), ("dcc/edits.py", "keyed_bones")]),
    ("the pose read at the keys and kept frames", [("dcc/fill.py", "read")]),
    ("the retargeting built from the keys", [("runtime/retarget.py", "__init__")]),
    ("the runtime's fill_rig (networks included)", [("runtime/rig_fill.py", "fill_rig")]),
    ("  the networks (ONNX Runtime)", [("runtime/onnx_backend.py", "predict")]),
    ("the channel values from the poses", [("inbetweening/humanoid.py", "basis_values"),
                                           ("inbetweening/rig.py", "basis_values")]),
    ("the curves written", [("inbetweening/curves.py", "write")]),
    ("the record stored", [("dcc/edits.py", "commit")]),
)


def stage_table(stats: dict, repeats: int) -> str:
    """A markdown table of :data:`STAGES`: ms per call of each profiled run (cProfile's cumulative times; the
    profiler's own overhead included, so read the shares)."""
    names = list(stats)
    rows = [f"| stage | {' | '.join(names)} |", "|---|" + "---:|" * len(names)]
    for stage, funcs in STAGES:
        cells = []
        for n in names:
            ct = sum(v[3] for (file, _, func), v in stats[n].stats.items()
                     if any(file.replace(os.sep, "/").endswith(end) and func == fn for end, fn in funcs))
            cells.append(f"{ct / repeats * 1e3:.1f}")
        rows.append(f"| {stage} | {' | '.join(cells)} |")
    return "ms per call under cProfile\n\n" + "\n".join(rows) + "\n"


def timed(fn) -> tuple[float, float]:
    t0, c0 = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - t0, time.process_time() - c0


def main() -> None:
    cfg = json.load(open(sys.argv[1]))
    chk.install(cfg["zip"])
    mod, _ = chk.model_names()
    loop = importlib.import_module("bl_ext.user_default.inbetweening.loop")
    chk.fresh()
    obj = chk.import_bvh(cfg["clip"], "NATIVE")
    scene = bpy.context.scene
    every, frames = cfg["every"], cfg["frames"]
    scene.frame_start, scene.frame_end = 1, frames
    keys = list(range(1, frames + 1, every))
    chk.thin(obj, set(keys))
    res = {"blender": bpy.app.version_string, "keys": keys, "runs": {}}

    def run(name, edit=None, profile=None, **kw):
        rows = []
        for i in range(cfg["repeats"]):
            if edit is not None:
                nudge(obj, edit, 0.01 if i % 2 == 0 else -0.01)
            mod.LAST_FILL.clear()
            if profile is not None:
                profile.enable()
            wall, cpu = timed(lambda: bpy.ops.anim.inbetween_fill(**kw))
            if profile is not None:
                profile.disable()
            rows.append({"wall": wall, "cpu": cpu, "model": mod.LAST_FILL.get("model_seconds", 0.0),
                         "refilled": mod.LAST_FILL.get("refilled"), "load": os.getloadavg()[0]})
        res["runs"][name] = rows
        print(name, rows[-1], flush=True)

    run("full", discard_edits=True)              # every gap (Discard Edits re-fills everything)
    profiles = {n: cProfile.Profile() for n in ("nothing changed", "last key changed")} if cfg.get("profile") else {}
    run("nothing changed", profile=profiles.get("nothing changed"))  # the record says nothing changed: no write
    run("last key changed", edit=keys[-1], profile=profiles.get("last key changed"))  # one gap re-filled
    if profiles:
        with open(cfg["profile"], "w") as f:
            print(stage_table({n: pstats.Stats(p) for n, p in profiles.items()}, cfg["repeats"]), file=f)
            for name, profile in profiles.items():
                print(f"==== {name}", file=f)
                pstats.Stats(profile, stream=f).sort_stats("cumulative").print_stats(60)
    run("middle key changed", edit=keys[len(keys) // 2])  # its two gaps and the gaps after them

    # Auto Re-fill: the handler's cost on an update, and the re-fill the timer runs
    scene.inbetween_settings.auto_refill = True
    loop.SETTLE = 0.0
    rows = []
    for i in range(cfg["repeats"]):
        nudge(obj, keys[-1], 0.01 if i % 2 == 0 else -0.01)
        handler, _ = timed(bpy.context.view_layer.update)
        assert loop._pending, "the handler did not notice the change"
        mod.LAST_FILL.clear()
        wall, cpu = timed(loop.tick)
        fingerprint, _ = timed(lambda: loop.fingerprint(obj))
        rows.append({"update": handler, "wall": wall, "cpu": cpu, "fingerprint": fingerprint,
                     "model": mod.LAST_FILL.get("model_seconds", 0.0), "refilled": mod.LAST_FILL.get("refilled"),
                     "load": os.getloadavg()[0]})
    res["runs"]["auto re-fill"] = rows
    print("auto", rows[-1], flush=True)
    json.dump(res, open(cfg["out"], "w"), indent=1)
    sys.stdout.flush()
    os._exit(0)


if __name__ == "__main__":
    main()
