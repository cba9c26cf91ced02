"""Benchmark: reading every BVH clip of the Bandai-Namco dataset 2 zip.

Usage (from the repository root)::

    python benchmarks/bvh_read.py [PATH_TO_ZIP_OR_FOLDER] [--repeat 3] [--limit N] [--no-baseline] [--facts]

Reports files, frames, wall/CPU time and frames/s for
  (a) ``parse_bvh`` only, from bytes already in memory (best of ``--repeat`` runs),
  (b) zip read + parse (``read_bvh_many``),
  (c) BASELINE: a naive line-by-line Python reader (``float()`` per token) on the same bytes,
and checks that (a) and (c) give bit-identical arrays.  ``--facts`` prints a few dataset facts
(position channels vs offsets, the static ``joint_Root``).
"""

from __future__ import annotations

import argparse
import itertools
import platform
import sys
import time
from pathlib import Path

import numpy as np

try:
    from inbetweening.data.bvh import BVH, iter_bvh_sources, parse_bvh, read_bvh_many
except ImportError:  # a checkout without `pip install -e .`
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))
    from inbetweening.data.bvh import BVH, iter_bvh_sources, parse_bvh, read_bvh_many

REPO = Path(__file__).resolve().parents[1]
DEFAULT = REPO.parent / "shared" / "datasets" / "bandai-namco-2.zip"


def naive_parse(data: bytes) -> tuple[list[str], np.ndarray]:
    """BASELINE reader: decode, split lines, parse the hierarchy and then every frame with float() per token.

    Returns ``(joint names, motion (F, C))``.
    """
    lines = data.decode("utf-8").splitlines()
    names: list[str] = []
    i = 0
    while not lines[i].strip().startswith("MOTION"):
        tokens = lines[i].split("#")[0].split()
        if tokens and tokens[0] in ("ROOT", "JOINT"):
            names.append(tokens[1])
        i += 1
    frames = int(lines[i + 1].split(":")[1])
    rows = [[float(t) for t in line.split()] for line in lines[i + 3 :] if line.strip()]
    motion = np.array(rows, dtype=np.float64)
    if motion.shape[0] != frames:
        raise ValueError(f"expected {frames} frames, got {motion.shape[0]}")
    return names, motion


def timed(fn):
    """Run ``fn()`` and return ``(result, wall seconds, CPU seconds)``."""
    w, c = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w, time.process_time() - c


def report(label: str, files: int, frames: int, nbytes: int, wall: float, cpu: float) -> None:
    print(
        f"{label:<46} files={files:>5}  frames={frames:>7,}  wall={wall:6.2f} s  cpu={cpu:6.2f} s  "
        f"{frames / wall:>8,.0f} frames/s ({frames / cpu:>8,.0f} per cpu-s)  {nbytes / wall / 1e6:5.1f} MB/s"
    )


def facts(clips: list[BVH]) -> None:
    """Dataset facts: do non-root position channels equal the offsets; is joint_Root static?"""
    per_joint = np.max([np.abs(b.channel_positions() - b.offsets).max(axis=(0, 2)) for b in clips], axis=0)
    names = clips[0].names
    print("max |position channel - OFFSET| per joint over all clips:")
    print("  " + ", ".join(f"{n}={v:.6g}" for n, v in zip(names, per_joint, strict=True)))
    root_off = max(np.abs(b.offsets[0]).max() for b in clips)
    root_pos = max(np.abs(b.motion[:, :3]).max() for b in clips)
    root_rot = max(np.abs(b.motion[:, 3:6]).max() for b in clips)
    print(f"{names[0]}: max |OFFSET| = {root_off}, max |position channel| = {root_pos}, max |rotation| = {root_rot}")
    topologies = {(tuple(b.names), tuple(b.parents.tolist())) for b in clips}
    hierarchies = {(tuple(b.names), b.offsets.tobytes(), tuple(b.channels)) for b in clips}
    print(f"distinct topologies: {len(topologies)}, distinct hierarchies (with offsets): {len(hierarchies)}")
    print(f"frame times: {sorted({b.frame_time for b in clips})}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("path", nargs="?", default=str(DEFAULT), help="zip file or folder of .bvh files")
    ap.add_argument("--repeat", type=int, default=3, help="runs of the in-memory parse (best is reported)")
    ap.add_argument("--limit", type=int, default=None, help="only the first N files (sorted by name)")
    ap.add_argument("--no-baseline", action="store_true", help="skip the naive line-by-line baseline")
    ap.add_argument("--facts", action="store_true", help="print dataset facts")
    args = ap.parse_args()

    print(f"# {args.path}")
    print(f"# python {platform.python_version()}, numpy {np.__version__}, {platform.machine()}")
    sources, wall, cpu = timed(lambda: list(itertools.islice(iter_bvh_sources(args.path), args.limit)))
    nbytes = sum(len(d) for _, d in sources)
    print(f"zip/folder read only: {len(sources)} files, {nbytes / 1e6:.1f} MB uncompressed, wall={wall:.2f} s")

    best = None
    for _ in range(max(args.repeat, 1)):
        clips, wall, cpu = timed(lambda: [parse_bvh(d, n) for n, d in sources])
        if best is None or wall < best[0]:
            best = (wall, cpu)
    frames = sum(b.num_frames for b in clips)
    report(f"(a) parse_bvh, bytes in memory (best of {args.repeat})", len(clips), frames, nbytes, *best)

    if args.limit is None:
        many, wall, cpu = timed(lambda: read_bvh_many(args.path))
    else:
        many, wall, cpu = timed(
            lambda: [parse_bvh(d, n) for n, d in itertools.islice(iter_bvh_sources(args.path), args.limit)]
        )
    report("(b) zip read + parse (read_bvh_many)", len(many), sum(b.num_frames for b in many), nbytes, wall, cpu)

    if not args.no_baseline:
        naive, wall, cpu = timed(lambda: [naive_parse(d) for _, d in sources])
        report("(c) BASELINE naive line-by-line Python reader", len(naive), frames, nbytes, wall, cpu)
        same = all(names == b.names and np.array_equal(m, b.motion) for (names, m), b in zip(naive, clips, strict=True))
        print(f"baseline and parse_bvh agree bit for bit: {same}")
        if not same:
            raise SystemExit("MISMATCH between the baseline and parse_bvh")
    if args.facts:
        facts(clips)


if __name__ == "__main__":
    main()
