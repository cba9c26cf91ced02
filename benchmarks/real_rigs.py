"""Real rigs nobody here wrote, filled by the shipped fill (or ``--ckpt``): the Character Creator rig of
``cmu-iclone-subset.zip`` (CMU walks, runs, jumps, punches, basketball, terrain; 60 fps, Z up, 100 joints; frame 0,
a T-pose, left out), ReActIdle's Blender-named rig (24 fps, no hands or toes) and assimp's CMU ``01_01``/``01_03``
(120 fps) and Poser ``Boxing_Toes`` (100 fps).

    python benchmarks/real_rigs.py [--ckpt A.ckpt ...] [--seconds 20] [--out results/characters/real_rigs.json]

Per clip, keys every 0.5 s and 1 s (and at the motion's extremes with ``--extremes``): the mean error of the mapped
bones' world positions over the generated frames, as a ratio to the interpolation of the same keys on the same rig
(local rotations slerped, translations linear).  The truth, the interpolation and the error are computed with
``tests/bvh_variants.py`` (a reader, FK and slerp of its own, SciPy's rotations), not with the project's code.
Pooled: total error over total interpolation error.  Each clip's first ``--seconds`` (after the T-pose frame).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
import zipfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "tests"))
SHARED = ROOT.parent / "shared" / "datasets"
ASSIMP = Path("/usr/share/assimp/models/BVH")
CMU_CC = {  # CMU subjects' takes (CMU's own descriptions): the kind of motion
    "002_01": "walk", "002_02": "walk", "002_03": "run", "002_04": "jump", "002_05": "punch/kick",
    "002_06": "punch/kick", "002_07": "swordplay", "002_08": "swordplay", "002_09": "wash", "002_10": "wash",
    "003_01": "walk (terrain)", "003_02": "walk (terrain)", "001_01": "climb", "001_08": "climb", "001_14": "climb",
}
LOCOMOTION = ("walk", "run")


def _extract(zip_name: str, dest: Path) -> Path:
    with zipfile.ZipFile(SHARED / zip_name) as z:
        z.extractall(dest)
    return dest


def clips(tmp: Path, seconds: float) -> list[tuple[str, str, str, Path]]:
    """``(rig, clip, kind, file)``: each file trimmed to its first ``seconds`` (after a T-pose frame 0) by the
    independent reader and writer."""
    import bvh_variants as V

    out = []
    found = []
    if (SHARED / "cmu-iclone-subset.zip").exists():
        root = _extract("cmu-iclone-subset.zip", tmp / "cc")
        for p in sorted(root.rglob("*.bvh")):
            kind = CMU_CC.get(p.stem, "basketball" if p.stem.startswith("006") else "other")
            found.append(("Character Creator (CMU)", p.stem, kind, p, 1))
    if (SHARED / "reactidle.zip").exists():
        root = _extract("reactidle.zip", tmp / "ri")
        for p in sorted(root.rglob("*.bvh"))[:8]:
            found.append(("ReActIdle", p.stem, "idle", p, 0))
    for name, kind in (("01_01.bvh", "playground"), ("01_03.bvh", "playground"), ("Boxing_Toes.bvh", "boxing")):
        if (ASSIMP / name).exists():
            found.append(("assimp " + ("Poser" if "Box" in name else "CMU"), Path(name).stem, kind, ASSIMP / name, 0))
    for rig, name, kind, path, skip in found:
        c = V.read(path)
        n = min(c.frames, skip + int(round(seconds / c.frame_time)) + 1)
        c = V.trim(c, skip, n)
        dst = tmp / "trimmed" / rig.replace(" ", "_") / f"{name}.bvh"
        dst.parent.mkdir(parents=True, exist_ok=True)
        V.write(c, dst)
        out.append((rig, name, kind, dst))
    return out


def schedules(c, extremes: bool) -> dict[str, list[int]]:
    fps = 1.0 / c.frame_time
    out = {}
    for s in (0.5, 1.0):
        step = max(2, int(round(s * fps)))
        out[f"{s:g} s"] = list(range(0, c.frames, step))
    if extremes:
        from inbetweening.evaluation.schedules import extreme_keys  # noqa: F401  (the project's rule, if asked)
    return out


def measure(inb, path: Path, keys: list[int], mapped: list[str]) -> tuple[float, float, float]:
    """``(fill error, interpolation error, seconds)`` over the generated frames, mapped bones, world positions."""
    import bvh_variants as V
    from inbetweening.data.bvh_writer import write_bvh

    c = V.read(path)
    n = keys[-1] + 1
    truth = V.positions(c)[:n]
    interp = V.positions(V.interpolate(c, keys))[:n]
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = inb.fill(str(path), keyframes=keys)
    dt = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as d:
        write_bvh(out, Path(d) / "o.bvh")
        filled = V.positions(V.read(Path(d) / "o.bvh"))[:n]
    gen = np.setdiff1d(np.arange(n), keys)
    cols = [c.names.index(b) for b in mapped]
    err = np.linalg.norm(filled[gen][:, cols] - truth[gen][:, cols], axis=-1).mean()
    base = np.linalg.norm(interp[gen][:, cols] - truth[gen][:, cols], axis=-1).mean()
    return float(err), float(base), dt


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ckpt", nargs="*", default=None, help="checkpoint(s); default the shipped fill")
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--out", default=str(ROOT / "results" / "characters" / "real_rigs.json"))
    args = ap.parse_args(argv)
    from _report import ratio_of, save_json

    import bvh_variants as V
    from inbetweening import Inbetweener
    from inbetweening.api.shipped import SHIPPED_CKPTS
    from inbetweening.data.bvh import read_bvh
    from inbetweening.runtime.bone_map import detect_bone_map

    inb = Inbetweener.from_checkpoint(args.ckpt if args.ckpt else [str(ROOT / p) for p in SHIPPED_CKPTS])
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for rig, name, kind, path in clips(Path(d), args.seconds):
            bvh = read_bvh(path)
            bm = detect_bone_map(bvh.names, bvh.parents, bvh.offsets, where=bvh.source)
            mapped = sorted(set(bm.slots.values()))
            c = V.read(path)
            for sched, keys in schedules(c, False).items():
                err, base, dt = measure(inb, path, keys, mapped)
                rows.append(dict(rig=rig, clip=name, kind=kind, keys=sched, error=err, interpolation=base,
                                 ratio=err / base, seconds=dt, frames=keys[-1] + 1))
                print(f"{rig:26s} {name:16s} {kind:15s} {sched:6s} {err:7.2f} / {base:7.2f} = {err / base:.3f}"
                      f"  ({dt:.2f} s)", flush=True)
    summary = {}
    for rig in sorted({r["rig"] for r in rows}):
        for sched in ("0.5 s", "1 s"):
            for group, test in (("locomotion", lambda k: k.startswith(LOCOMOTION)),
                                ("other", lambda k: not k.startswith(LOCOMOTION))):
                sel = [r for r in rows if r["rig"] == rig and r["keys"] == sched and test(r["kind"])]
                if sel:
                    summary[f"{rig} | {group} | {sched}"] = dict(
                        pooled=ratio_of(sel),
                        worse=sum(r["ratio"] > 1.05 for r in sel), clips=len(sel),
                        worst=max(r["ratio"] for r in sel))
    print("\nrig | motions | keys: pooled ratio (clips worse than interpolation by > 5 % / clips, worst)")
    for k, v in summary.items():
        print(f"{k:55s} {v['pooled']:.3f} ({v['worse']}/{v['clips']}, worst {v['worst']:.3f})")
    save_json(args.out, "real_rigs.py", argv, rows=rows, summary=summary)
    return 0


if __name__ == "__main__":
    sys.exit(main())
