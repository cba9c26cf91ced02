"""Characters that really differ from the model's skeleton, on Bandai-Namco-2's standard test split: the same motion
played by other rigs, written by a writer that is not the project's (tests/bvh_variants.py: its own reader, FK and
writer, SciPy's rotations), filled through ``Inbetweener.fill`` (what ``predict`` and the API do).

    python benchmarks/characters.py [--ckpt A.ckpt ...] [--clip-step 1] [--out results/characters/characters.json]

Characters (each from every test clip):
- ``native``: the file as it is laid out (six channels, ZXY), the baseline;
- ``UE names, Z up, m, A-pose rest, axes rolled``: every bone's rest frame turned (arms lowered 45 degrees, bones
  rolled by a random angle about themselves), the world turned to Z up, metres, UE-mannequin names, Euler XYZ;
- ``legs, arms +15 %, spine -15 %`` and the other way: another character (its own truth);
- ``no toes`` / ``no hands``: those bones (and below) removed;
- ``extra bones``: a second spine bone, twist bones and fingers of their own motion, a moving bone above the hips.
Schedules: keys every 15 and 30 frames, random gaps (3-45, seeded per clip), the motion's extremes
(:mod:`inbetweening.evaluation.schedules`).  Per clip and pooled: the mean joint error over the generated frames, over
interpolation's (local rotations slerped, translations linear), on the joints the character shares with the original
(by name), against the original's on the same joints; the target: every character within 0.02 of it, per clip and
pooled.  Default: the shipped fill.
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
DATA = ROOT.parent / "shared" / "datasets" / "bandai-namco-2.zip"
SCHEDULES = ("every 15", "every 30", "random", "extremes")
TOLERANCE = 0.02


def characters(c):
    """``{name: clip}`` of the characters of clip ``c`` (module docstring)."""
    from scipy.spatial.transform import Rotation as R

    import bvh_variants as V
    from test_character_invariance import UE, _tpose_directions

    rng = np.random.default_rng(11)
    rolls = {n: float(a) for n, a in zip(c.names, rng.uniform(-180, 180, len(c.names)))}
    posed = V.rest(c, V.aim_frames(c, _tpose_directions(a_pose=45.0), roll=rolls))
    turned = V.scale(V.turn(V.rename(posed, UE), R.from_euler("X", 90, degrees=True)), 0.01)
    legs = ("UpperLeg_L", "UpperLeg_R", "LowerLeg_L", "LowerLeg_R")
    spine = ("Hips", "Spine", "Chest")
    arms = ("UpperArm_L", "UpperArm_R", "LowerArm_L", "LowerArm_R")

    def body(k: float) -> dict[str, float]:  # legs and arms by k, the spine the other way
        return {**{b: k for b in legs + arms}, **{b: 2.0 - k for b in spine}}
    extra = V.add_top(V.add_leaf(V.add_leaf(V.insert_bone(c, "Chest", "Spine2"), "UpperArm_L", "UpperArm_L_twist",
                                            [12.0, 0, 0], seed=1), "Hand_R", "Index_R", [-4.0, 1.0, 2.0], seed=2),
                      "world", moving=True)
    return {"native": c, "UE names, Z up, m, A-pose rest, axes rolled": turned,
            "legs, arms +15 %, spine -15 %": V.proportions(c, body(1.15)),
            "legs, arms -15 %, spine +15 %": V.proportions(c, body(0.85)),
            "no toes": V.drop(c, ["Toes_L", "Toes_R"]), "no hands": V.drop(c, ["Hand_L", "Hand_R"]),
            "extra bones": extra}


def schedule(name: str, c, seed: int) -> list[int]:
    import bvh_variants as V
    from inbetweening.evaluation.schedules import extreme_keyframes, keyframe_indices, random_keyframes

    n = c.frames
    if name.startswith("every"):
        return keyframe_indices(n, int(name.split()[1]))
    if name == "random":
        return random_keyframes(n, np.random.default_rng(seed))
    return extreme_keyframes(V.positions(c))


def fill_positions(inb, c, keys, tmp: Path, native_layout: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(filled, truth, interpolation)`` world positions ``(G, J, 3)`` of the generated frames of ``c``'s fill."""
    import bvh_variants as V
    from inbetweening.data.bvh_writer import write_bvh

    kw = {"orders": "ZXY", "six": range(len(c.names))} if native_layout else {}
    V.write(c, tmp / "in.bvh", **kw)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        write_bvh(inb.fill(str(tmp / "in.bvh"), keyframes=keys), tmp / "out.bvh")
    n = keys[-1] + 1
    gen = np.setdiff1d(np.arange(keys[0], n), keys)
    truth = V.positions(c)[:n]
    lerp = np.concatenate([truth[: keys[0]], V.positions(V.interpolate(c, keys))])[:n]
    return V.positions(V.read(tmp / "out.bvh"))[:n][gen], truth[gen], lerp[gen]


def shared(c, native) -> tuple[list[int], list[int]]:
    """The joints a character shares with the original, by name (the UE names mapped back): its and the original's."""
    from test_character_invariance import UE

    back = {v: k for k, v in UE.items()}
    mine, theirs = [], []
    for i, n in enumerate(c.names):
        n = back.get(n, n)
        if n in native.names:
            mine.append(i)
            theirs.append(native.names.index(n))
    return mine, theirs


def errors(p: tuple[np.ndarray, np.ndarray, np.ndarray], cols: list[int]) -> tuple[float, float]:
    """``(fill error, interpolation error)``: the mean distance over the generated frames and the joints ``cols``."""
    filled, truth, lerp = (x[:, cols] for x in p)
    return (float(np.linalg.norm(filled - truth, axis=-1).mean()), float(np.linalg.norm(lerp - truth, axis=-1).mean()))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ckpt", nargs="*", default=None, help="checkpoint(s); default the shipped fill")
    ap.add_argument("--data", default=str(DATA))
    ap.add_argument("--clip-step", type=int, default=1, help="every k-th test clip in name order (1: all)")
    ap.add_argument("--out", default=str(ROOT / "results" / "characters" / "characters.json"))
    args = ap.parse_args(argv)
    from _report import ratio_of, save_json

    import bvh_variants as V
    from inbetweening import Inbetweener
    from inbetweening.api.shipped import SHIPPED_CKPTS
    from inbetweening.data.specs import bandai_namco_split

    inb = Inbetweener.from_checkpoint(args.ckpt if args.ckpt else [str(ROOT / p) for p in SHIPPED_CKPTS])
    rows, t0 = [], time.perf_counter()
    with zipfile.ZipFile(args.data) as z, tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        names = sorted(n for n in z.namelist() if n.endswith(".bvh") and bandai_namco_split(Path(n).name) == "test")
        for i, member in enumerate(names[:: args.clip_step]):
            (tmp / "clip.bvh").write_bytes(z.read(member))
            clip = V.read(tmp / "clip.bvh")
            for s in SCHEDULES:
                keys = schedule(s, clip, seed=i)
                if len(keys) < 2 or keys[-1] - keys[0] < 2:
                    continue
                native = None
                for cname, c in characters(clip).items():
                    p = fill_positions(inb, c, keys, tmp, cname == "native")
                    native = p if native is None else native
                    mine, theirs = shared(c, clip)
                    err, base = errors(p, mine)
                    n_err, n_base = errors(native, theirs)  # the original on the same joints
                    rows.append(dict(clip=Path(member).stem, character=cname, keys=s, error=err, interpolation=base,
                                     native_error=n_err, native_interpolation=n_base))
            print(f"{i + 1} clips, {time.perf_counter() - t0:.0f} s", flush=True)
    summary = {}
    for cname in dict.fromkeys(r["character"] for r in rows):
        for s in SCHEDULES:
            sel = [r for r in rows if r["character"] == cname and r["keys"] == s]
            if not sel:
                continue
            pooled, pooled_native = ratio_of(sel), ratio_of(sel, "native_error", "native_interpolation")
            over = [r["clip"] for r in sel if r["error"] / r["interpolation"] >
                    r["native_error"] / r["native_interpolation"] + TOLERANCE]
            summary[f"{cname} | {s}"] = dict(pooled=pooled, native=pooled_native, clips=len(sel),
                                             clips_over=len(over), over=over[:10])
    print(f"\ncharacter | keys: pooled ratio (native), clips over native + {TOLERANCE} / clips")
    for k, v in summary.items():
        print(f"{k:62s} {v['pooled']:.3f} ({v['native']:.3f})  {v['clips_over']}/{v['clips']}")
    save_json(args.out, "characters.py", argv, rows=rows, summary=summary)
    return 0


if __name__ == "__main__":
    sys.exit(main())
