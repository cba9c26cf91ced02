"""The table of the graph-free candidate against today's shipped fill (issue 51 item 4, RESULTS.md 3.3) from the runs
of ``benchmarks/nograph_ship.sh``, and the ship rule's verdict.

    python benchmarks/nograph_ship_table.py <out dir> [--copy results/nograph_ship]

Per split and fill: the LAFAN protocol's L2P over interpolation's at 5 / 15 / 30 / 45 frames, and keys only: the
pooled ratio per schedule (share of clips worse than interpolation by more than 5 %, foot skating in cm/s).  The
rule (nograph_ship.sh, fixed before any score): on the standard split and on the content split the candidate is
within 0.02 of the shipped fill at every LAFAN length and keys-only schedule (the recipe's gain on the folds is
RESULTS.md 3.3's)."""
from __future__ import annotations

import json
from pathlib import Path

from never_worse_table import SCHEDULES, cell, copy_runs, out_and_copy  # benchmarks/ helper

LENGTHS = ("5", "15", "30", "45")
FILLS = ("shipped", "candidate", "nograph")
TOLERANCE = 0.02


ROOT = Path(__file__).resolve().parents[1]
STORED = {  # the shipped fills' files of RESULTS.md 2.1, where this run did not score them again
    ("standard", "lafan"): "results/ensemble3/standard_lafan_partial3.json",
    ("standard", "keyframes"): "results/never_worse/standard_partial3.json",
    ("content", "lafan"): "results/ensemble3/content_lafan_ensemble3.json",
    ("content", "keyframes"): "results/never_worse/content_ensemble3.json",
}


def load(out: Path, split: str, fill: str, protocol: str) -> dict | None:
    """A run's ``benchmark.json``; for the shipped fill not scored again, RESULTS.md 2.1's file of it."""
    p = out / f"{split}_{fill}_{protocol}" / "benchmark.json"
    if not p.exists() and fill == "shipped":
        p = ROOT / STORED[(split, protocol)]
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


def figures(out: Path, split: str, fill: str) -> dict[str, float]:
    """``{"LAFAN@<n>": ratio, "keys@<schedule>": ratio}`` of the figures found for a fill on a split."""
    return ({f"LAFAN@{n}": v for n, v in lafan_ratios(out, split, fill).items()}
            | {f"keys@{s}": r["ratio"] for s, r in keyframes(out, split, fill).items()})


def verdict(out: Path) -> str:
    """The ship rule (module docstring) on the figures found, in words: a loss beyond the tolerance decides it even
    where some runs are missing; otherwise every figure must be there."""
    wanted = [f"LAFAN@{n}" for n in LENGTHS] + [f"keys@{s}" for s in SCHEDULES]
    parts, ok, missing = [], True, []
    for split in ("standard", "content"):
        cand, ship = figures(out, split, "candidate"), figures(out, split, "shipped")
        losses = {k: cand[k] - ship[k] for k in wanted if k in cand and k in ship}
        missing += [f"{split} {k}" for k in wanted if k not in losses]
        if losses:
            worst, best = max(losses, key=losses.get), min(losses, key=losses.get)
            ok &= losses[worst] <= TOLERANCE
            parts.append(f"{split}: largest loss {losses[worst]:+.3f} ({worst}), largest gain {-losses[best]:+.3f} ({best})")
    word = "do not ship" if not ok else ("SHIP" if not missing else "undecided")
    gaps = f" (not measured: {', '.join(missing)})" if missing else ""
    return f"verdict: {word} (tolerance {TOLERANCE}): " + "; ".join(parts) + gaps


def main() -> None:
    a = out_and_copy(__doc__.splitlines()[0])
    print(table(a.out))
    print()
    print(verdict(a.out))
    copy_runs(a.out, a.copy)


if __name__ == "__main__":
    main()
