"""Prepare a dataset from scratch and load it again from the cache; report both wall times.

    python benchmarks/dataset_load.py [--name bandai_namco] [--path ../shared/datasets/bandai-namco-2.zip]

The first load reads every BVH file, folds the root, cuts and normalises the benchmark windows and
computes the statistics; the second one is served from the cache (memory-mapped .npy files keyed by
the source bytes and the preprocessing settings).
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from inbetweening.data.datasets import load_dataset

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--name", default="bandai_namco")
    ap.add_argument("--path", default=str(ROOT.parent / "shared" / "datasets" / "bandai-namco-2.zip"))
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as cache:
        t = time.perf_counter()
        data = load_dataset(args.name, path=args.path, cache_dir=cache)
        first = time.perf_counter() - t
        frames = sum(c.num_frames for c in data.train + data.test)
        cached = []
        for _ in range(args.repeats):
            t = time.perf_counter()
            load_dataset(args.name, path=args.path, cache_dir=cache)
            cached.append(time.perf_counter() - t)
    print(f"dataset {args.name}: {data.summary()}")
    print(f"first load (parse + prepare + write cache): {first:.1f} s  ({frames / first:,.0f} frames/s end to end)")
    print(f"cached load: median {sorted(cached)[len(cached) // 2]:.3f} s, max {max(cached):.3f} s over {args.repeats}")


if __name__ == "__main__":
    main()
