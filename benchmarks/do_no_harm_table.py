"""The tables of the do-no-harm measurement (RESULTS.md section 5.1) from the runs of ``benchmarks/do_no_harm.sh``.

    python benchmarks/do_no_harm_table.py <out dir of do_no_harm.sh> [--copy results/do_no_harm]

Reads ``<out>/<split>_<plain|blended>_<lafan|keyframes>/benchmark.json``, ``<out>/<split>_interpolation_lafan/
benchmark.json`` and ``<out>/<split>_calibrate.log``; prints per split and variant the LAFAN protocol's L2P ratios
to interpolation on the same windows and the keyframes protocol's error ratios per schedule, then the fitted
weights.  ``--copy``: also copy the JSON files there (``<split>_<variant>_<protocol>.json``).
"""
from __future__ import annotations

import argparse
import json
import re
import shutil
from pathlib import Path

SPLITS, VARIANTS, LENGTHS = ("standard", "content"), ("plain", "blended"), (5, 15, 30, 45)
SCHEDULES = ("5", "15", "30", "45", "random", "extremes")


def load(path: Path) -> dict | None:
    return json.loads(path.read_text()) if path.is_file() else None


def weights(log: Path) -> list[tuple[int, float]]:
    """The (gap, weight) rows the calibration printed."""
    if not log.is_file():
        return []
    return [(int(m[1]), float(m[2])) for m in re.finditer(r"^\s*(\d+)\s+([01]\.\d+)\s", log.read_text(), re.M)]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("out", type=Path)
    ap.add_argument("--copy", type=Path)
    a = ap.parse_args()
    head = ["split", "variant"] + [f"L2P ratio @{n}" for n in LENGTHS] + [f"keys {s}: ratio" for s in SCHEDULES]
    lines = ["| " + " | ".join(head) + " |", "|---|---" + "|---:" * (len(head) - 2) + "|"]
    for split in SPLITS:
        interp = load(a.out / f"{split}_interpolation_lafan" / "benchmark.json")
        for variant in VARIANTS:
            lafan = load(a.out / f"{split}_{variant}_lafan" / "benchmark.json")
            kf = load(a.out / f"{split}_{variant}_keyframes" / "benchmark.json")
            cells = [split, variant]
            for n in LENGTHS:
                ok = lafan and interp
                cells.append(f"{lafan['metrics'][f'l2p@{n}'] / interp['metrics'][f'l2p@{n}']:.3f}" if ok else "–")
            for s in SCHEDULES:
                r = (kf or {}).get("keyframes", {}).get(s)
                cells.append(f"{r['ratio']:.3f}" if r else "–")
            lines.append("| " + " | ".join(cells) + " |")
    print("\n".join(lines))
    for split in SPLITS:
        w = weights(a.out / f"{split}_calibrate.log")
        if w:
            print(f"\n{split}: weights by gap " + ", ".join(f"{g}: {v:.2f}" for g, v in w))
    if a.copy:
        a.copy.mkdir(parents=True, exist_ok=True)
        for p in sorted(a.out.glob("*_*_*/benchmark.json")):
            shutil.copy(p, a.copy / f"{p.parent.name}.json")
        for p in sorted(a.out.glob("*_calibrate.log")):
            shutil.copy(p, a.copy / p.name)


if __name__ == "__main__":
    main()
