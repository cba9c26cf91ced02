"""The Blender extension in real Blender: fill time of a 300-frame timeline with 10 keys, and the fill's error
against Blender's own default interpolation for new keys (Bezier, auto-clamped) on real Bandai-Namco-2 test clips.

    python benchmarks/blender_fill.py [--data ../shared/datasets/bandai-namco-2.zip] [--every 15 30]
                                      [--clip-step 4] [--repeats 5] [--no-write]
    python benchmarks/blender_fill.py --every          # the timing only

Builds the extension (linux-x64 zip; wheels cached), runs it headless in a ``bpy`` venv (``.venv-bpy``, created if
missing) on one thread.  Clips: the test split (take number divisible by 10), every ``--clip-step``-th in name
order.  Keys every K frames from the first frame; every other key deleted; the rest set to Bezier / auto-clamped
(Blender's default for new keys).  Error: mean distance of the model's 21 joints (pose-bone heads, cm) to the
original clip over the frames between the first and the last key that are not keys.  Writes the
"## Blender extension" section of BENCHMARKS.md (timing) and prints the RESULTS.md table (errors).
"""
from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import _report  # noqa: E402  (benchmarks/ helper)

ROOT = Path(__file__).resolve().parents[1]
SECTION = "## Blender extension"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default=str(ROOT.parent / "shared" / "datasets" / "bandai-namco-2.zip"))
    ap.add_argument("--every", type=int, nargs="*", default=[15, 30], help="key spacings (none: timing only)")
    ap.add_argument("--clip-step", type=int, default=4)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args()
    from inbetweening.blender.bpyenv import bpy_python
    from inbetweening.blender.build import build

    exe = bpy_python()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (zip_path,) = build(tmp / "dist", platforms=["linux-x64"], log=lambda *a: None)
        names = []
        with zipfile.ZipFile(args.data) as zf:
            for n in sorted(zf.namelist()):
                m = re.search(r"_(\d{3})\.bvh$", n)
                if m and int(m.group(1)) % 10 == 0:
                    names.append(n)
            names = names[:: args.clip_step]
            clips = []
            for n in names:
                (tmp / Path(n).name).write_bytes(zf.read(n))
                clips.append(str(tmp / Path(n).name))
            long = next(n for n in sorted(zf.namelist()) if n.endswith(".bvh") and zf.read(n).count(b"\n") > 440)
            (tmp / "long.bvh").write_bytes(zf.read(long))
        cfg = {"zip": str(zip_path), "clips": clips, "every": args.every, "out": str(tmp / "res.json"),
               "timing_clip": str(tmp / "long.bvh"), "timing_frames": 300, "timing_keys": 10, "repeats": args.repeats}
        (tmp / "cfg.json").write_text(json.dumps(cfg))
        env = {**os.environ, "BLENDER_USER_RESOURCES": str(tmp / "user"), "OMP_NUM_THREADS": "1"}
        subprocess.run([str(exe), str(ROOT / "benchmarks" / "blender" / "bpy_bench.py"), str(tmp / "cfg.json")],
                       check=True, env=env)
        res = json.loads((tmp / "res.json").read_text())
    times = [t["seconds"] for t in res["timing"]]
    date = _dt.date.today().isoformat()
    load = statistics.median(t["load"] for t in res["timing"])
    model = [t["model_seconds"] for t in res["timing"]]
    windows = res["timing"][0]["windows"]
    cpu = [t["cpu_seconds"] for t in res["timing"]]
    body = f"""`python benchmarks/blender_fill.py` on {date} (Blender {res['blender']} as the `bpy` module, headless, one
thread: `OMP_NUM_THREADS=1`, ONNX Runtime `intra_op_num_threads=1`; median 1-minute load average {load:.2f} over
the runs, on the shared 2-core machine).

A 300-frame timeline (frames 1-300 of `{Path(long).name}`, imported with Blender's BVH importer) with 10 keys
(every 33 frames; 9 gaps of 32-33 frames, one model window each): `bpy.ops.anim.inbetween_fill()` end to end
(reading the keys, the ONNX windows, writing 290 frames x 66 F-curves), {len(times)} runs:

| wall median | wall min | wall max | CPU time median | windows | of which the model (wall), median |
|---:|---:|---:|---:|---:|---:|
| {statistics.median(times):.3f} s | {min(times):.3f} s | {max(times):.3f} s | {statistics.median(cpu):.3f} s | {windows} | \
{statistics.median(model):.3f} s |

CPU time is the process's (one busy thread), which depends less on the other jobs of the shared machine than the
wall time.  The model part is the fill runtime (ONNX Runtime and the numpy frame changes); the rest is Blender glue:
evaluating the keys' poses, converting 290 poses to bone channels, writing the keys.
"""
    _report.publish(body, SECTION, not args.no_write)
    if not res["errors"]:
        return
    print("\nRESULTS.md table (mean joint error over the generated frames, cm):\n")
    print("| keys every | clips | generated frames | Blender Bezier (auto-clamped) | the extension's fill | ratio |")
    print("|---:|---:|---:|---:|---:|---:|")
    for every, rows in res["errors"].items():
        n = sum(r["n"] for r in rows)
        bez = sum(r["bezier_sum"] for r in rows) / n
        fill = sum(r["fill_sum"] for r in rows) / n
        gen = sum(r["generated"] for r in rows)
        print(f"| {every} | {len(rows)} | {gen} | {bez:.2f} | {fill:.2f} | {fill / bez:.3f} |")
    per_clip = [r["seconds"] for rows in res["errors"].values() for r in rows]
    print(f"\nper-clip fill time: median {statistics.median(per_clip):.3f} s")
    json.dump(res, open(ROOT / "results" / "blender_fill.json", "w"), indent=1)
    print(f"wrote results/blender_fill.json ({sys.argv[0]})")


if __name__ == "__main__":
    main()
