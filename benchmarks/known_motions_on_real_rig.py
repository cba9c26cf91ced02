"""Motions the model knows, on a rig nobody here wrote: Bandai-Namco-2 standard-test clips moved onto the Character
Creator rig of ``cmu-iclone-subset.zip`` (100 joints, Z up, metres-scaled offsets of its own), filled there by the
shipped fill, against the same clips filled on the model's own skeleton with the same keys.

    python benchmarks/known_motions_on_real_rig.py [--ckpt A.ckpt ...] [--step 1] [--out results/characters/known_on_cc.json]

It separates the rig from the motion: ``real_rigs.py`` measures CMU's own walks on that rig (motions of other people,
captured elsewhere); here the motions are the model's own data, so any difference is the rig's road (bone map,
retargeting both ways, the rig's other bones).  The clip goes onto the rig with the runtime's ``Retarget.to_rig``
(the rig's natural pose from one of its own takes, ``002_01``, frame 0 — a T-pose — left out) and is written by the
project's BVH writer; the errors are measured by ``tests/bvh_variants.py`` (its own reader and FK) on the rig's mapped
bones and on the model's joints (``joint_Root`` excluded), keys every 15 and 30 frames.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "tests"))
SHARED = ROOT.parent / "shared" / "datasets"
CONTENTS = ("walk", "walk-turn-left", "walk-turn-right", "run", "dash", "wave-both-hands", "raise-up-both-hands")
TAKE = "002_01"  # the CC rig's take whose poses give the rig its natural pose


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ckpt", nargs="*", default=None, help="checkpoint(s); default the shipped fill")
    ap.add_argument("--step", type=int, default=1, help="every k-th clip of those contents in name order")
    ap.add_argument("--out", default=str(ROOT / "results" / "characters" / "known_on_cc.json"))
    args = ap.parse_args(argv)
    from _report import ratio_of, save_json
    from real_rigs import measure

    from inbetweening import Inbetweener
    from inbetweening.api.shipped import SHIPPED_CKPTS
    from inbetweening.data.bvh import read_bvh
    from inbetweening.data.bvh_writer import write_bvh
    from inbetweening.data.clips import clip_in_skeleton
    from inbetweening.data.specs import bandai_namco_split
    from inbetweening.evaluation.schedules import keyframe_indices
    from inbetweening.runtime.bone_map import detect_bone_map
    from inbetweening.runtime.retarget import Retarget

    inb = Inbetweener.from_checkpoint(args.ckpt if args.ckpt else [str(ROOT / p) for p in SHIPPED_CKPTS])
    conv = inb.runtime.info.convention
    rows, t0 = [], time.perf_counter()
    with tempfile.TemporaryDirectory() as d, zipfile.ZipFile(SHARED / "bandai-namco-2.zip") as z:
        tmp = Path(d)
        with zipfile.ZipFile(SHARED / "cmu-iclone-subset.zip") as cz:
            cz.extractall(tmp / "cc")
        cc = read_bvh(next((tmp / "cc").rglob(f"{TAKE}.bvh")))
        bm = detect_bone_map(cc.names, cc.parents, cc.offsets, where=cc.source)
        mapped = sorted(set(bm.slots.values()))
        lq, lp = cc.local_rotations()[1:], cc.channel_positions()[1:]  # frame 0: the T-pose
        movers = [j for j, ch in enumerate(cc.channels) if any(c.lower().endswith("position") for c in ch)]
        to_rig = Retarget(cc.skeleton(), inb.skeleton, bm, reference=lq[0], poses=lq, ends=cc.end_sites,
                          translations=lp)
        names = sorted(n for n in z.namelist() if n.endswith(".bvh") and bandai_namco_split(Path(n).name) == "test"
                       and any(f"_{c}_" in Path(n).name for c in CONTENTS))[:: args.step]
        for member in names:
            (tmp / "own.bvh").write_bytes(z.read(member))
            own = read_bvh(tmp / "own.bvh")
            _, root, q = clip_in_skeleton(own, inb.skeleton)
            if not conv.is_project:
                root, q = conv.to_project(root, q)
            f = len(root)
            rq, rp = to_rig.to_rig(root, q, np.repeat(lq[:1], f, 0), np.repeat(lp[:1], f, 0), movers)
            write_bvh(cc.with_motion(rq, rp, frame_time=own.frame_time), tmp / "rig.bvh")
            content = Path(member).stem.split("_")[1]
            for k in (15, 30):
                keys = keyframe_indices(f, k)
                err, base, _ = measure(inb, tmp / "rig.bvh", keys, mapped)
                n_err, n_base, _ = measure(inb, tmp / "own.bvh", keys, list(inb.skeleton.names))
                rows.append(dict(clip=Path(member).stem, content=content, keys=f"every {k}", error=err,
                                 interpolation=base, own_error=n_err, own_interpolation=n_base))
                print(f"{Path(member).stem:45s} keys {k:2d}: on the CC rig {err / base:.3f}, on its own skeleton "
                      f"{n_err / n_base:.3f}", flush=True)
    summary = {}
    print(f"\n{len(names)} clips, {time.perf_counter() - t0:.0f} s\ncontent | keys: CC rig (own skeleton), clips over "
          "own + 0.02 / clips")
    for content in (*CONTENTS, "all"):
        for k in ("every 15", "every 30"):
            sel = [r for r in rows if r["keys"] == k and content in ("all", r["content"])]
            if not sel:
                continue
            over = [r["clip"] for r in sel if r["error"] / r["interpolation"] > r["own_error"] / r["own_interpolation"]
                    + 0.02]
            summary[f"{content} | {k}"] = dict(rig=ratio_of(sel), own=ratio_of(sel, "own_error", "own_interpolation"),
                                               over=over, clips=len(sel))
            s = summary[f"{content} | {k}"]
            print(f"{content} | {k}: {s['rig']:.3f} ({s['own']:.3f})  {len(over)}/{len(sel)}")
    save_json(args.out, "known_motions_on_real_rig.py", argv, rows=rows, summary=summary)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
