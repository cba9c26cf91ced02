"""Where a fill's error goes, per content and body part: the mean joint-position error (cm) of the fill and of
interpolation on the generated frames of Bandai-Namco-2 test clips filled from keys alone, split into the legs (the
root's subtrees that hold a foot), the arms (the upper body's limbs with a side), and the trunk and head (the rest).
It tells a network that cannot fill a motion from one that spoils what interpolation already gets right (a still
body's legs).

    python -m benchmarks run body_parts <checkpoint> [--split standard] [--keys 15] [--clips N] [--defaults | --network-alone]

By default the checkpoint fills as it is (its blend if calibrated; no self-check, no foot locking).  ``--network-alone``:
the same without its blend (a copy of the checkpoint whose blend is removed, in a temporary folder).  ``--defaults``: the
fill a user gets (self-check, feet locked).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))

from inbetweening.data.mirror import side_of  # noqa: E402
from inbetweening.data.specs import bandai_namco_content  # noqa: E402
from inbetweening.datasets import load_dataset  # noqa: E402
from inbetweening.evaluation.keyframes import keyed_clip, position_error  # noqa: E402
from inbetweening.evaluation.schedules import schedule_keyframes  # noqa: E402
from inbetweening.geometry.interp import interpolate_keyframes  # noqa: E402
from inbetweening.predictor.checkpoint import read_checkpoint  # noqa: E402
from inbetweening.training.evaluate import animator_fill  # noqa: E402
from inbetweening.training.tasks import upper_body, upper_limbs  # noqa: E402


def body_parts(skeleton, feet: list[int]) -> dict[str, np.ndarray]:
    """``{"legs", "arms", "trunk and head"}`` -> joint indices of ``skeleton``."""
    upper = upper_body(skeleton.parents, feet)
    arms = np.zeros(len(upper), bool)
    for limb in upper_limbs(skeleton.parents, upper):
        top = int(limb.nonzero()[0][0])
        if side_of(skeleton.names[top]):
            arms |= limb.numpy()
    legs = ~upper.numpy()
    legs[0] = False  # the root (hips) goes with the trunk
    return {"legs": np.flatnonzero(legs), "arms": np.flatnonzero(arms), "trunk and head": np.flatnonzero(~legs & ~arms)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("ckpt")
    ap.add_argument("--split", default="standard")
    ap.add_argument("--keys", type=int, default=15, help="a key every this many frames")
    ap.add_argument("--clips", type=int, default=None, help="score this many test clips, evenly spaced (default: all)")
    how = ap.add_mutually_exclusive_group()
    how.add_argument("--defaults", action="store_true", help="the fill's defaults: self-check and feet locked")
    how.add_argument("--network-alone", action="store_true", help="the checkpoint without its do-no-harm blend")
    ap.add_argument("--data", default=str(ROOT.parent / "shared" / "datasets" / "bandai-namco-2.zip"))
    args = ap.parse_args(argv)
    data = load_dataset("bandai_namco", path=args.data, split=args.split)
    sk = data.skeleton
    parts = body_parts(sk, list(data.contact.indices(sk.names)))
    ckpt, tmp = args.ckpt, None  # tmp: the network-alone copy's folder, removed when main returns
    if args.network_alone:
        import torch

        raw = read_checkpoint(ckpt)
        raw["hyper_parameters"] = {**raw["hyper_parameters"], "blend": None}
        tmp = tempfile.TemporaryDirectory()
        ckpt = str(Path(tmp.name) / "network_alone.ckpt")
        torch.save(raw, ckpt)
    fill, _ = animator_fill(ckpt, foot_lock=args.defaults, self_check=args.defaults)
    clips = list(data.test)
    if args.clips and args.clips < len(clips):
        clips = [clips[i] for i in np.linspace(0, len(clips) - 1, args.clips).round().astype(int)]
    sums: dict[tuple[str, str, str], list[float]] = {}  # (content, part, fill or interpolation) -> [error sum, count]
    counts: dict[str, int] = {}
    for clip in clips:
        content = bandai_namco_content(clip.name) or "(other)"
        keys = schedule_keyframes(args.keys, len(clip.root_pos), np.random.default_rng(0), None)
        if not keys:
            continue
        (root, q), (root_in, q_in), gen = keyed_clip(clip.root_pos, clip.local_q, keys)
        truth = sk.pose(root, q)[1]
        for who, (r, lq) in (("fill", fill(root_in, q_in, keys)), ("interpolation", interpolate_keyframes(root_in, q_in, keys))):
            pos = sk.pose(np.asarray(r, np.float64), np.asarray(lq, np.float64))[1]
            for part, joints in parts.items():
                total, n = position_error(pos[:, joints], truth[:, joints], gen)
                acc = sums.setdefault((content, part, who), [0.0, 0])
                acc[0] += total
                acc[1] += n
        counts[content] = counts.get(content, 0) + int(gen.sum())
    mode = ("the fill's defaults" if args.defaults else "the network alone, no blend" if args.network_alone
            else "as the checkpoint fills") + ("" if args.defaults else ", no self-check, feet free")
    print(f"keys every {args.keys}, {len(clips)} test clips of split {args.split}, {mode}: {args.ckpt}\n"
          f"per body part, fill / interpolation cm (ratio), mean over generated frames and the part's joints\n")
    names = list(parts)
    print("| content | frames | " + " | ".join(names) + " |\n|---|---:|" + "---|" * len(names))
    for content in sorted(counts):
        cells = []
        for part in names:
            f, i = (sums[content, part, w][0] / sums[content, part, w][1] for w in ("fill", "interpolation"))
            cells.append(f"{f:.2f} / {i:.2f} ({f / i:.2f})")
        print(f"| {content} | {counts[content]} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
