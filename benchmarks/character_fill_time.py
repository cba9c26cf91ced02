"""Fill time with retargeting: 300 frames of a Character Creator take (100 joints, 60 fps; its T-pose frame left out),
10 keys, one thread, the shipped fill (or ``--ckpt``), through ``Inbetweener.fill`` as ``predict`` calls it.

    python benchmarks/character_fill_time.py [--ckpt A.ckpt ...] [--runs 5]

Prints the median, minimum and maximum of ``--runs`` fills after one warm-up (the network loaded once, as ``predict``
loads it once); the target is 1 s (issue: 300 frames, 10 keys, a 100-joint rig on one thread).
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
import warnings
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
DATA = ROOT.parent / "shared" / "datasets" / "cmu-iclone-subset.zip"
TAKE = "CMU-iClone-subset/subjects/002/002_09.bvh"  # 517 frames


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ckpt", nargs="*", default=None)
    ap.add_argument("--runs", type=int, default=5)
    args = ap.parse_args(argv)
    import torch

    import bvh_variants as V
    from inbetweening import Inbetweener
    from inbetweening.api.shipped import SHIPPED_CKPTS
    from inbetweening.data.bvh import read_bvh

    torch.set_num_threads(1)
    inb = Inbetweener.from_checkpoint(args.ckpt if args.ckpt else [str(ROOT / p) for p in SHIPPED_CKPTS])
    with zipfile.ZipFile(DATA) as z, tempfile.TemporaryDirectory() as d:
        path = Path(d) / "take.bvh"
        path.write_bytes(z.read(TAKE))
        V.write(V.trim(V.read(path), 1, 301), path)
        bvh = read_bvh(path)
        keys = [round(i * 299 / 9) for i in range(10)]
        times = []
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for i in range(args.runs + 1):
                t0 = time.perf_counter()
                inb.fill(bvh, keyframes=keys)
                if i:
                    times.append(time.perf_counter() - t0)
    print(f"{bvh.num_joints} joints, {bvh.num_frames} frames, 10 keys, one thread: median {statistics.median(times):.3f} s "
          f"(min {min(times):.3f}, max {max(times):.3f}, {args.runs} runs)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
