"""Any humanoid character: the shipped model filling characters that are not its skeleton, through the fill runtime's
retargeting (``python -m inbetweening.predict`` and the Python API fill them so).

    python benchmarks/characters.py [--data ../shared/datasets/bandai-namco-2.zip] [--clip-step 8] [--out results/characters]

1. Bandai-Namco-2 test clips (standard split: take numbers divisible by 10, every ``--clip-step``-th in name order)
   played by generated characters (tests/characters.py: other bone names, proportions, an A-pose rest, extra spine,
   twist and finger bones, metres and Z up; and a T-pose Y-up cm one), keys every 15 and 30 frames: the fill's mean
   joint error over the generated frames, on the character's own joints, as a ratio to the interpolation of the same
   keys on the same character (rotations slerped, translations linear), against the same ratio of the same clips on
   the model's own skeleton.
2. Real BVH of other skeletons from Debian's assimp-testmodels (CMU ``01_01.bvh``, ``01_03.bvh`` at 120 fps, Poser
   ``Boxing_Toes.bvh`` at 100 fps): keys every 0.5 s and 1 s and at the motion's extremes, the same ratio; and the
   retargeting alone: the same fill with the do-no-harm blend at 0 (the model's skeleton interpolated, carried there
   and back) against the interpolation on the rig.
3. The fill time of a 300-frame character clip with 10 keys (one thread), median of 5 after a warm-up.

Writes ``<out>/characters.json`` and prints the tables of RESULTS.md's "Any humanoid character" section.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
ASSIMP = Path("/usr/share/assimp/models/BVH")
REAL = {"CMU 01_01": "01_01.bvh", "CMU 01_03": "01_03.bvh", "Poser Boxing_Toes": "Boxing_Toes.bvh"}
SCALE = {"legs": 1.12, "Spine": 0.88, "Chest": 1.1, "UpperArm_L": 1.12, "UpperArm_R": 1.12, "LowerArm_L": 0.9,
         "LowerArm_R": 0.9, "Neck": 1.15, "Head": 1.1}
CHARACTERS = {"UE-style, A-pose, proportions, extra bones, m, Z up": dict(a_pose=35.0, scale=SCALE),
              "renamed, T-pose, cm, Y up": dict(extras=False, z_up=False, unit=1.0)}


def read_real(path: Path, tmp: Path):
    """``(BVH, note)``: a test model as it is, or - when its MOTION block holds more frame lines than its ``Frames:``
    line declares (Poser's ``Boxing_Toes.bvh``: the project's reader refuses such a file) - a copy with the count
    corrected, and a note saying so."""
    from inbetweening.data.bvh import BVHError, read_bvh

    try:
        return read_bvh(path), ""
    except BVHError:
        text = path.read_text()
        head, motion = text.split("MOTION", 1)
        lines = motion.strip().splitlines()
        frames = [ln for ln in lines[2:] if ln.strip()]
        fixed = tmp / path.name
        fixed.write_text(f"{head}MOTION\nFrames: {len(frames)}\n{lines[1]}\n" + "\n".join(frames) + "\n")
        return read_bvh(fixed), f"'Frames:' corrected to the {len(frames)} frame lines the file holds"


def fk_positions(bvh, local_q=None, local_p=None) -> np.ndarray:
    from inbetweening.geometry.skeleton import fk

    q = bvh.local_rotations() if local_q is None else local_q
    p = bvh.channel_positions() if local_p is None else local_p
    return fk(q, p, bvh.parents)[1]


def interpolation(bvh, keys):
    """The keys' interpolation on the clip's own skeleton: every local rotation slerped, every translation linear."""
    from inbetweening.geometry.interp import interpolate_keyframes

    q, p = bvh.local_rotations(), bvh.channel_positions()
    span = slice(keys[0], keys[-1] + 1)
    ip, iq = interpolate_keyframes(p[span].reshape(len(q[span]), -1), q[span], [k - keys[0] for k in keys])
    return iq, ip.reshape(len(iq), -1, 3)


def errors(truth, filled, interp, keys, scale: float = 1.0) -> tuple[float, float]:
    """Mean joint distance over the generated frames (``scale``: to centimetres): the fill's, the interpolation's."""
    gen = np.setdiff1d(np.arange(keys[0], keys[-1] + 1), keys) - keys[0]
    t = truth[keys[0] : keys[-1] + 1][gen]
    return (float(np.linalg.norm(filled[gen] - t, axis=-1).mean() * scale),
            float(np.linalg.norm(interp[gen] - t, axis=-1).mean() * scale))


def score(ib, bvh, keys, unit_cm: float) -> dict:
    """``{"mapped": (fill, interp), "all": (fill, interp)}``: the mean errors on the bones the model fills (a
    character's bones with a slot; every joint of the model's own skeleton) and on every bone (those without a slot
    are interpolated between the keys by the fill too, so they add the same error to both)."""
    res = ib.fill_detailed(bvh, keyframes=keys)
    truth = fk_positions(bvh)
    filled = fk_positions(res.bvh)
    iq, ip = interpolation(bvh, keys)
    interp = fk_positions(bvh, iq, ip)
    idx = (list(range(bvh.num_joints)) if res.bone_map is None
           else [bvh.names.index(b) for b in res.bone_map.slots.values()])
    return {"mapped": errors(truth[:, idx], filled[:, idx], interp[:, idx], keys, unit_cm),
            "all": errors(truth, filled, interp, keys, unit_cm)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default=os.environ.get("BANDAI_NAMCO_PATH",
                                                     str(ROOT.parent / "shared" / "datasets" / "bandai-namco-2.zip")))
    ap.add_argument("--clip-step", type=int, default=8)
    ap.add_argument("--out", default=str(ROOT / "results" / "characters"))
    ap.add_argument("--properties", action="store_true",
                    help="one property of the generated character at a time (every 16th test clip, keys every 15)")
    args = ap.parse_args()
    if args.properties:
        return properties(args.data)
    import torch

    torch.set_num_threads(1)
    from characters import character
    from inbetweening.api.inbetweener import Inbetweener
    from inbetweening.data.bvh import read_bvh
    from inbetweening.data.bvh_writer import write_bvh
    from inbetweening.data.clips import clip_in_skeleton
    from inbetweening.evaluation.schedules import extreme_keyframes, keyframe_indices

    ib = Inbetweener.from_checkpoint(ROOT / "models" / "bn2_reference" / "model.ckpt")
    sk = ib.skeleton
    from inbetweening.predictor.checkpoint import load_predictor

    carrier = load_predictor(ROOT / "models" / "bn2_reference" / "model.ckpt")
    carrier.blend = (0.0,)  # the blend at 0: the model's skeleton interpolated - the retargeting alone
    ib_carry = Inbetweener(carrier, foot_lock=False)
    res: dict = {"date": time.strftime("%Y-%m-%d"), "model": "models/bn2_reference", "bn2": {}, "real": {}}
    with tempfile.TemporaryDirectory() as tmp, zipfile.ZipFile(args.data) as zf:
        tmp = Path(tmp)
        names = sorted(n for n in zf.namelist() if n.endswith(".bvh") and int(Path(n).stem[-3:]) % 10 == 0)
        names = names[:: args.clip_step]
        sums: dict = {}
        for n in names:
            path = tmp / Path(n).name
            path.write_bytes(zf.read(n))
            bvh = read_bvh(path)
            _, root, q = clip_in_skeleton(bvh, sk)
            for every in (15, 30):
                keys = keyframe_indices(bvh.num_frames, every)
                if len(keys) < 2:
                    continue
                native = score(ib, bvh, keys, 1.0)
                rows = {"native skeleton": native}
                for label, kw in CHARACTERS.items():
                    rig, _ = character(sk, root, q, **kw)
                    rig_path = tmp / f"character_{every}.bvh"
                    write_bvh(rig, rig_path)
                    rows[label] = score(ib, read_bvh(rig_path), keys, 1.0 / kw.get("unit", 0.01))
                for label, r in rows.items():
                    for part, (m, i) in r.items():
                        s = sums.setdefault(f"{label}@{every}@{part}", [0.0, 0.0, 0])
                        s[0] += m
                        s[1] += i
                        s[2] += 1
                res["bn2"].setdefault(Path(n).stem, {})[every] = {
                    k: {part: {"fill_cm": m, "interp_cm": i, "ratio": m / i} for part, (m, i) in r.items()}
                    for k, r in rows.items()}
            print(f"{Path(n).stem}: " + ", ".join(f"{k}={v['native skeleton']['mapped']['ratio']:.3f}"
                                                  for k, v in res["bn2"][Path(n).stem].items()), flush=True)
        res["bn2_pooled"] = {k: {"fill_cm": v[0] / v[2], "interp_cm": v[1] / v[2], "ratio": v[0] / v[1], "clips": v[2]}
                             for k, v in sums.items()}
        # real rigs of other skeletons
        for label, fname in REAL.items():
            if not (ASSIMP / fname).is_file():
                print(f"{label}: {ASSIMP / fname} missing (apt-get install assimp-testmodels)")
                continue
            bvh, note = read_real(ASSIMP / fname, tmp)
            fps = 1.0 / bvh.frame_time
            truth = fk_positions(bvh)
            unit = 1.0  # the ratio is unit-free; the figures are in the file's units
            schedules = {"0.5 s": keyframe_indices(bvh.num_frames, round(fps / 2)),
                         "1 s": keyframe_indices(bvh.num_frames, round(fps)),
                         "extremes": extreme_keyframes(truth, min_gap=round(8 * fps / 30), max_gap=round(45 * fps / 30))}
            out = {}
            for sched, keys in schedules.items():
                r = score(ib, bvh, keys, unit)
                out[sched] = {part: {"fill": m, "interp": i, "ratio": m / i} for part, (m, i) in r.items()}
                m, i = score(ib_carry, bvh, keys, unit)["mapped"]
                out[sched]["carried_interpolation"] = {"fill": m, "interp": i, "ratio": m / i}
                out[sched]["keys"] = len(keys)
            res["real"][label] = {"fps": fps, "frames": bvh.num_frames, "joints": bvh.num_joints, "note": note,
                                  "bone_map": ib.fill_detailed(bvh, keyframes=schedules["1 s"]).bone_map.slots, **out}
            print(f"{label}: " + ", ".join(f"{k} {v['mapped']['ratio']:.3f}" for k, v in out.items()), flush=True)
        # timing: 300 frames, 10 keys, a character with extra bones
        _, root, q = clip_in_skeleton(read_bvh(tmp / Path(names[0]).name), sk)
        reps = int(np.ceil(300 / len(root)))
        long_root = np.concatenate([root] * reps)[:300]
        long_q = np.concatenate([q] * reps)[:300]
        rig, _ = character(sk, long_root, long_q, a_pose=35.0, scale=SCALE)
        keys = [int(k) for k in np.linspace(0, 299, 10).round()]
        times = []
        for _ in range(6):
            t0 = time.perf_counter()
            ib.fill(rig, keyframes=keys)
            times.append(time.perf_counter() - t0)
        res["timing"] = {"frames": 300, "keys": 10, "joints": rig.num_joints, "seconds_median": statistics.median(times[1:]),
                         "seconds": times[1:], "threads": 1}
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "characters.json").write_text(json.dumps(res, indent=1))
    pooled = res["bn2_pooled"]
    print("\n| clips played by | keys every 15: fill / interp (cm) | ratio | every bone | keys every 30: fill / interp "
          "(cm) | ratio | every bone |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for label in ["native skeleton", *CHARACTERS]:
        a, b = pooled[f"{label}@15@mapped"], pooled[f"{label}@30@mapped"]
        print(f"| {label} | {a['fill_cm']:.2f} / {a['interp_cm']:.2f} | {a['ratio']:.3f} | "
              f"{pooled[f'{label}@15@all']['ratio']:.3f} | {b['fill_cm']:.2f} / {b['interp_cm']:.2f} | {b['ratio']:.3f} | "
              f"{pooled[f'{label}@30@all']['ratio']:.3f} |")
    print(f"\n({pooled['native skeleton@15@mapped']['clips']} clips)\n")
    print("| rig | fps | joints | 0.5 s | 1 s | extremes | every bone (0.5 s / 1 s / extremes) | the retargeting alone "
          "(0.5 s / 1 s / extremes) |")
    print("|---|---:|---:|---:|---:|---:|---|---|")
    for label, r in res["real"].items():
        alone = " / ".join(f"{r[k]['carried_interpolation']['ratio']:.3f}" for k in ("0.5 s", "1 s", "extremes"))
        print(f"| {label} | {r['fps']:.0f} | {r['joints']} | {r['0.5 s']['mapped']['ratio']:.3f} | "
              f"{r['1 s']['mapped']['ratio']:.3f} | {r['extremes']['mapped']['ratio']:.3f} | "
              f"{r['0.5 s']['all']['ratio']:.3f} / {r['1 s']['all']['ratio']:.3f} / {r['extremes']['all']['ratio']:.3f} | "
              f"{alone} |")
    t = res["timing"]
    print(f"\nfill of {t['frames']} frames, {t['keys']} keys, {t['joints']} joints: median {t['seconds_median']:.3f} s "
          "(one thread)")


def properties(data: str) -> None:
    """The ratio on the mapped bones with one property of the generated character at a time."""
    import torch

    torch.set_num_threads(1)
    from characters import character
    from inbetweening.api.inbetweener import Inbetweener
    from inbetweening.data.bvh import read_bvh
    from inbetweening.data.bvh_writer import write_bvh
    from inbetweening.data.clips import clip_in_skeleton
    from inbetweening.evaluation.schedules import keyframe_indices

    ib = Inbetweener.from_checkpoint(ROOT / "models" / "bn2_reference" / "model.ckpt")
    flat = dict(extras=False, z_up=False, unit=1.0)
    variants = {"A-pose (35 degrees)": {**flat, "a_pose": 35.0}, "proportions": {**flat, "scale": SCALE},
                "extra bones": dict(z_up=False, unit=1.0), "metres, Z up": dict(extras=False),
                "all of them": dict(a_pose=35.0, scale=SCALE)}
    sums: dict = {}
    with tempfile.TemporaryDirectory() as tmp, zipfile.ZipFile(data) as zf:
        tmp = Path(tmp)
        names = sorted(n for n in zf.namelist() if n.endswith(".bvh") and int(Path(n).stem[-3:]) % 10 == 0)[::16]
        for n in names:
            (tmp / "clip.bvh").write_bytes(zf.read(n))
            bvh = read_bvh(tmp / "clip.bvh")
            _, root, q = clip_in_skeleton(bvh, ib.skeleton)
            keys = keyframe_indices(bvh.num_frames, 15)
            rows = {"native skeleton": score(ib, bvh, keys, 1.0)["mapped"]}
            for label, kw in variants.items():
                rig, _ = character(ib.skeleton, root, q, **kw)
                write_bvh(rig, tmp / "rig.bvh")
                rows[label] = score(ib, read_bvh(tmp / "rig.bvh"), keys, 1.0)["mapped"]
            for label, (m, i) in rows.items():
                s = sums.setdefault(label, [0.0, 0.0])
                s[0] += m
                s[1] += i
    print(f"{len(names)} clips, keys every 15, ratio on the bones the model fills:")
    for label, (m, i) in sums.items():
        print(f"  {label}: {m / i:.3f}")


if __name__ == "__main__":
    main()
