"""The table of the graph-free candidate against today's shipped fill (issue 51 item 4, RESULTS.md 3.3) from the runs
of ``benchmarks/nograph_ship.sh``, and the ship rule's verdict.

    python benchmarks/nograph_ship_table.py <out dir> [--copy results/nograph_ship]

Per split and fill: the LAFAN protocol's L2P over interpolation's at 5 / 15 / 30 / 45 frames, and keys only: the
pooled ratio per schedule (share of clips worse than interpolation by more than 5 %, foot skating in cm/s).  The
rule (nograph_ship.sh, fixed before any score): on the standard split and on the content split the candidate is
within 0.02 of the shipped fill at every LAFAN length and keys-only schedule (the recipe's gain on the folds is
RESULTS.md 3.3's)."""
from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

from never_worse_table import SCHEDULES, cell  # benchmarks/ helper

LENGTHS = ("5", "15", "30", "45")
FILLS = ("shipped", "candidate", "nograph")
TOLERANCE = 0.02


def load(out: Path, split: str, fill: str, protocol: str) -> dict | None:
    p = out / f"{split}_{fill}_{protocol}" / "benchmark.json"
    return json.loads(p.read_text()) if p.exists() else None


def lafan_ratios(out: Path, split: str, fill: str) -> dict[str, float]:
    res, ref = load(out, split, fill, "lafan"), load(out, split, "interpolation", "lafan")
    if not res or not ref:
        return {}
    return {n: res["metrics"][f"l2p@{n}"] / ref["metrics"][f"l2p@{n}"] for n in LENGTHS}


def keyframes(out: Path, split: str, fill: str) -> dict[str, dict]:
    res = load(out, split, fill, "keyframes")
    return (res or {}).get("keyframes") or {}


def table(out: Path) -> str:
    lines = ["| split | fill | LAFAN L2P ÷ interpolation @5 / 15 / 30 / 45 | keys only "
             + " / ".join(SCHEDULES) + " (clips worse by > 5 %, skating cm/s) |", "|---|---|---|---|"]
    for split in ("standard", "content"):
        for fill in FILLS:
            lr, kf = lafan_ratios(out, split, fill), keyframes(out, split, fill)
            if not lr and not kf:
                continue
            lafan = " / ".join(f"{lr[n]:.3f}" for n in LENGTHS) if lr else "–"
            keys = " · ".join(f"{s}: {cell(kf.get(s))}" for s in SCHEDULES) if kf else "–"
            lines.append(f"| {split} | {fill} | {lafan} | {keys} |")
    return "\n".join(lines)


def verdict(out: Path) -> str:
    """The ship rule (module docstring) on the runs found, in words."""
    figs = {(split, fill): ({n: v for n, v in lafan_ratios(out, split, fill).items()},
                            {s: r["ratio"] for s, r in keyframes(out, split, fill).items()})
            for split in ("standard", "content") for fill in ("shipped", "candidate")}
    if any(not a or not b for a, b in figs.values()):
        return "verdict: not every run is there"
    parts, ok = [], True
    for split in ("standard", "content"):
        (cl, ck), (sl, sk) = figs[(split, "candidate")], figs[(split, "shipped")]
        losses = {f"LAFAN@{n}": cl[n] - sl[n] for n in LENGTHS} | {f"keys@{s}": ck[s] - sk[s] for s in SCHEDULES}
        worst, best = max(losses, key=losses.get), min(losses, key=losses.get)
        ok &= losses[worst] <= TOLERANCE
        parts.append(f"{split}: largest loss {losses[worst]:+.3f} ({worst}), largest gain {-losses[best]:+.3f} ({best})")
    return f"verdict: {'SHIP' if ok else 'do not ship'} (tolerance {TOLERANCE}): " + "; ".join(parts)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--copy", type=Path, default=None, help="also copy each run's benchmark.json there as <run>.json")
    a = ap.parse_args()
    print(table(a.out))
    print()
    print(verdict(a.out))
    if a.copy:
        a.copy.mkdir(parents=True, exist_ok=True)
        for p in sorted(a.out.glob("*/benchmark.json")):
            shutil.copy(p, a.copy / f"{p.parent.name}.json")


if __name__ == "__main__":
    main()
