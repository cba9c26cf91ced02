"""The Blender extension on a Rigify Human meta-rig (or the rig Rigify generates from it) in real Blender: the fill
(through the bone map and the fill runtime's retargeting) against Blender's own default interpolation for new keys
(Bezier, auto-clamped) on real Bandai-Namco-2 test clips carried onto the rig, and the fill time of a 300-frame
timeline.

    python benchmarks/blender_rigify.py [--rig metarig|generated] [--data ../shared/datasets/bandai-namco-2.zip]
                                        [--every 15 30] [--clip-step 8] [--repeats 5] [--no-write]

Builds the extension (linux-x64 zip; wheels cached), runs benchmarks/blender/bpy_rigify.py headless in the ``bpy``
venv on one thread.  Clips: the test split (take number divisible by 10), every ``--clip-step``-th in name order.
Ground truth: each clip imported with Blender's BVH importer, read in the model's representation, carried onto the
meta-rig with ``Retarget(...).to_rig`` (the meta-rig's rest pose as the reference, bones without a slot at rest) and
keyed on every frame with ``HumanoidRig``'s channel writer (``--rig generated``: the generated rig's FK controls and
``torso`` keyed with ``RigifyRig``'s, solved against Blender's evaluated pose).  Keys every K frames from the first;
every other key deleted; the rest Bezier / auto-clamped.  Error: mean distance of the heads of the mapped bones (the
generated rig's ``DEF-`` bones; world space, the rig's metres x 100 = cm) to the ground truth over the frames between
the first and the last key that are not keys.  Prints the markdown tables; writes results/blender_rigify.json (the
generated rig's under its key ``generated``; unless ``--no-write``).
"""
from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import tempfile
import zipfile
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def content(clip: str) -> str:
    m = re.match(r"dataset-2_(.+)_([a-z-]+)_\d{3}\.bvh$", clip)
    return m.group(1) if m else clip


def table(rows_by_every: dict, key=lambda r: "all") -> None:
    print("| keys every | group | clips | generated frames | Blender Bezier (auto-clamped), cm | the fill, cm | ratio |")
    print("|---:|---|---:|---:|---:|---:|---:|")
    for every, rows in rows_by_every.items():
        groups = defaultdict(list)
        for r in rows:
            groups[key(r)].append(r)
        for g, rs in sorted(groups.items()):
            n = sum(r["n"] for r in rs)
            bez = sum(r["bezier_sum"] for r in rs) / n
            fill = sum(r["fill_sum"] for r in rs) / n
            print(f"| {every} | {g} | {len(rs)} | {sum(r['generated'] for r in rs)} | {bez:.2f} | {fill:.2f} | "
                  f"{fill / bez:.3f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rig", choices=["metarig", "generated"], default="metarig")
    ap.add_argument("--data", default=str(ROOT.parent / "shared" / "datasets" / "bandai-namco-2.zip"))
    ap.add_argument("--every", type=int, nargs="*", default=[15, 30])
    ap.add_argument("--clip-step", type=int, default=8)
    ap.add_argument("--max-clips", type=int, default=0, help="at most this many clips (0: all of the step)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args()
    from inbetweening.blender.bpyenv import bpy_python
    from inbetweening.blender.build import build

    exe = bpy_python()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (zip_path,) = build(tmp / "dist", platforms=["linux-x64"], log=lambda *a: None)
        with zipfile.ZipFile(args.data) as zf:
            names = [n for n in sorted(zf.namelist())
                     if (m := re.search(r"_(\d{3})\.bvh$", n)) and int(m.group(1)) % 10 == 0][:: args.clip_step]
            if args.max_clips:
                names = names[: args.max_clips]
            clips = []
            for n in names:
                (tmp / Path(n).name).write_bytes(zf.read(n))
                clips.append(str(tmp / Path(n).name))
            long = None
            if args.repeats:
                long = next(n for n in sorted(zf.namelist()) if n.endswith(".bvh") and zf.read(n).count(b"\n") > 440)
                (tmp / "long.bvh").write_bytes(zf.read(long))
        cfg = {"rig": args.rig, "zip": str(zip_path), "clips": clips, "every": args.every, "out": str(tmp / "res.json"),
               "timing_clip": str(tmp / "long.bvh") if long else None, "timing_frames": 300, "timing_keys": 10,
               "repeats": args.repeats}
        (tmp / "cfg.json").write_text(json.dumps(cfg))
        env = {**os.environ, "BLENDER_USER_RESOURCES": str(tmp / "user"), "OMP_NUM_THREADS": "1"}
        subprocess.run([str(exe), str(ROOT / "benchmarks" / "blender" / "bpy_rigify.py"), str(tmp / "cfg.json")],
                       check=True, env=env)
        res = json.loads((tmp / "res.json").read_text())
    res["timing_clip"] = Path(long).name if long else None
    rig = "Rigify Human meta-rig" if args.rig == "metarig" else "the rig Rigify generates from it (FK)"
    print(f"\nBlender {res['blender']}; {rig}; mean head distance of the mapped bones over the generated frames (cm)\n")
    table(res["errors"])
    print()
    table(res["errors"], key=lambda r: content(r["clip"]))
    if res["timing"]:
        t = res["timing"]
        print(f"\n300-frame timeline, 10 keys ({res['timing_clip']}), {len(t)} runs, one thread: wall median "
              f"{statistics.median(x['seconds'] for x in t):.3f} s (min {min(x['seconds'] for x in t):.3f}, max "
              f"{max(x['seconds'] for x in t):.3f}), CPU median {statistics.median(x['cpu_seconds'] for x in t):.3f} s, "
              f"model part median {statistics.median(x['model_seconds'] for x in t):.3f} s, {t[0]['windows']} "
              f"windows, {t[0]['channels']} F-curves; load median {statistics.median(x['load'] for x in t):.2f}")
        if t[0].get("solve_passes"):
            print(f"solve: {t[0]['solve_passes']} scene evaluations for the 290 generated frames")
    if not args.no_write:
        path = ROOT / "results" / "blender_rigify.json"
        if args.rig == "generated":
            res = {**json.loads(path.read_text()), "generated": res} if path.exists() else {"generated": res}
        else:
            res = {**res, **{k: v for k, v in (json.loads(path.read_text()) if path.exists() else {}).items()
                             if k == "generated"}}
        json.dump(res, open(path, "w"), indent=1)
        print("wrote results/blender_rigify.json")


if __name__ == "__main__":
    main()
