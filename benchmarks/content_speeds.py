"""How fast each content of Bandai-Namco-2 moves: the hip's horizontal speed (cm/s) per content, percentiles over
every frame of every take (both splits).  It says which held-out motions leave the training contents' range: the
content split's ``run`` moves faster than any walk, so a network fed velocities meets speeds it never saw there.

    python -m benchmarks run content_speeds [zip or folder]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))

from inbetweening.data.specs import bandai_namco_content  # noqa: E402
from inbetweening.datasets import load_dataset  # noqa: E402
from inbetweening.evaluation.keyframes import horizontal_speed  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("path", nargs="?", default=str(ROOT.parent / "shared" / "datasets" / "bandai-namco-2.zip"))
    args = ap.parse_args(argv)
    data = load_dataset("bandai_namco", path=args.path)
    fps = data.fps
    speeds: dict[str, list[np.ndarray]] = {}
    for clip in list(data.train) + list(data.test):
        speeds.setdefault(bandai_namco_content(clip.name) or "(other)", []).append(
            horizontal_speed(np.asarray(clip.root_pos)[:, None], fps)[:, 0])
    print(f"hip speed over the floor, cm/s, every frame of every take ({fps:.0f} fps)\n")
    print("| content | takes | median | 90th | 99th | max |\n|---|---:|---:|---:|---:|---:|")
    for content, parts in sorted(speeds.items()):
        a = np.concatenate(parts)
        p50, p90, p99 = np.percentile(a, [50, 90, 99])
        print(f"| {content} | {len(parts)} | {p50:.1f} | {p90:.1f} | {p99:.1f} | {a.max():.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
