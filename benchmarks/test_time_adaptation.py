"""Test-time adaptation on the user's keys (``fill.adapt_steps``, RESULTS.md section 3.4): the content-split ensemble
(motions it never saw: Bandai-Namco-2's ``run`` and ``wave-both-hands``) fills every ``--every``-th test clip of the
content split from keys every ``--keys`` frames, without adaptation and with each ``--steps`` setting; per clip the
joint error over interpolation's (every frame), whether the adapted network was kept and its held-out keys' error
ratio before and after, then the pooled ratio and the wall time.

    python benchmarks/test_time_adaptation.py [--keys 15] [--steps 0,10] [--lr 1e-4] [--every 90] [--clips 6]
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CKPTS = [ROOT / "models" / m / "model.ckpt" for m in ("bn2_content", "bn2_twin_content", "bn2_v2_content")]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--keys", type=int, default=15)
    ap.add_argument("--steps", default="0,10", help="adaptation steps to compare, comma-separated (0: off)")
    ap.add_argument("--lr", type=float, default=1e-4)
    ap.add_argument("--every", type=int, default=90, help="every k-th clip of the content split's test clips")
    ap.add_argument("--clips", type=int, default=6)
    ap.add_argument("--ckpt", nargs="+", default=[str(c) for c in CKPTS],
                    help="checkpoints (several: their ensemble) trained without the content split's test contents")
    args = ap.parse_args(argv)
    from inbetweening import Inbetweener
    from inbetweening.data.datasets import load_dataset
    from inbetweening.geometry.interp import interpolate_keyframes
    from inbetweening.runtime.settings import FillSettings

    data = load_dataset("bandai_namco", path=ROOT.parent / "shared" / "datasets" / "bandai-namco-2.zip", split="content")
    clips, sk = data.test[:: args.every][: args.clips], data.skeleton
    for steps in (int(s) for s in args.steps.split(",")):
        runtime = Inbetweener.from_checkpoint(args.ckpt if len(args.ckpt) > 1 else args.ckpt[0],
                                              settings=FillSettings(adapt_steps=steps, adapt_lr=args.lr)).runtime
        model = interp = 0.0
        t0 = time.perf_counter()
        for c in clips:
            keys = list(range(0, c.num_frames, args.keys))
            keys += [c.num_frames - 1] if keys[-1] != c.num_frames - 1 else []
            out = runtime.fill(c.root_pos, c.local_q, keys)
            gt = sk.pose(c.root_pos, c.local_q)[1]
            e = np.linalg.norm(sk.pose(out.root, out.local_q)[1] - gt, axis=-1).mean()
            ei = np.linalg.norm(sk.pose(*interpolate_keyframes(c.root_pos, c.local_q, keys))[1] - gt, axis=-1).mean()
            model, interp = model + e * c.num_frames, interp + ei * c.num_frames
            a = out.adaptation
            how = "" if a is None else f" kept={a.kept} held-out keys {a.before:.3f} -> {a.after:.3f}"
            print(f"steps {steps}: {c.name} {e / ei:.3f}{how}")
        print(f"steps {steps}, lr {args.lr:g}: pooled {model / interp:.3f} over {len(clips)} clips, "
              f"{time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
