"""Issue 54's students against the ensemble they were distilled from (RESULTS.md 2.3), from the runs of
``benchmarks/students.sh``, and the ship rule's verdict per student.

    python benchmarks/students_table.py <out dir> [--copy results/students]

The rule (issue 54 item 1, written here before any student was scored): a student replaces the ensemble only if on the
standard split it is within 0.01 of the shipped ensemble at every LAFAN length and keys-only schedule with no larger
share of clips worse than interpolation by more than 5 % at any schedule, and on the content split its student (the
same recipe distilled from the content split's ensemble) is no worse than that ensemble at any figure.  The held-out
contents (the folds, RESULTS.md 3.3) need a teacher ensemble per fold and are not measured: a student passing both
splits is reported "undecided" until they are."""
from __future__ import annotations

from pathlib import Path

from never_worse_table import SCHEDULES, cell, copy_runs, out_and_copy  # benchmarks/ helpers
from nograph_ship_table import LENGTHS, figures, keyframes, lafan_ratios

TOLERANCE = {"standard": 0.01, "content": 0.0}


def students(out: Path) -> dict[str, list[str]]:
    """``{split: [student names]}`` found in ``out`` (runs named ``<split>_<name>_<protocol>``)."""
    found: dict[str, list[str]] = {}
    for p in sorted(out.glob("*_*_*")):
        if p.is_dir():
            split, name = p.name.split("_")[0], "_".join(p.name.split("_")[1:-1])
            if name != "interpolation" and name not in found.setdefault(split, []):
                found[split].append(name)
    return found


def table(out: Path) -> str:
    lines = ["| split | fill | LAFAN L2P ÷ interpolation @5 / 15 / 30 / 45 | keys only "
             + " / ".join(SCHEDULES) + " (clips worse by > 5 %, skating cm/s) |", "|---|---|---|---|"]
    for split, names in students(out).items():
        for fill in ["shipped", *names]:
            lr, kf = lafan_ratios(out, split, fill), keyframes(out, split, fill)
            lafan = " / ".join(f"{lr[n]:.3f}" for n in LENGTHS) if lr else "–"
            keys = " · ".join(f"{s}: {cell(kf.get(s))}" for s in SCHEDULES) if kf else "–"
            lines.append(f"| {split} | {fill} | {lafan} | {keys} |")
    return "\n".join(lines)


def verdict(out: Path, split: str, name: str) -> str:
    """The rule (module docstring) for one student on its split, in words."""
    wanted = [f"LAFAN@{n}" for n in LENGTHS] + [f"keys@{s}" for s in SCHEDULES]
    mine, ship = figures(out, split, name), figures(out, split, "shipped")
    losses = {k: mine[k] - ship[k] for k in wanted if k in mine and k in ship}
    missing = [k for k in wanted if k not in losses]
    worse = []
    if split == "standard":  # no more clips worse than interpolation
        kf_mine, kf_ship = keyframes(out, split, name), keyframes(out, split, "shipped")
        worse = [s for s in SCHEDULES if s in kf_mine and s in kf_ship
                 and kf_mine[s].get("worse_share", 0.0) > kf_ship[s].get("worse_share", 0.0)]
    if not losses:
        return f"{split} {name}: not measured"
    worst = max(losses, key=losses.get)
    ok = losses[worst] <= TOLERANCE[split] and not worse
    word = "fails" if not ok else ("passes" if not missing else "undecided")
    more = f"; more clips worse at {', '.join(worse)}" if worse else ""
    gaps = f" (not measured: {', '.join(missing)})" if missing else ""
    return (f"{split} {name}: {word} (tolerance {TOLERANCE[split]}): largest loss {losses[worst]:+.3f} ({worst})"
            f"{more}{gaps}")


def main() -> None:
    a = out_and_copy(__doc__.splitlines()[0])
    print(table(a.out))
    print()
    for split, names in students(a.out).items():
        for name in names:
            print(verdict(a.out, split, name))
    print("held-out contents (folds): not measured (a teacher ensemble per fold)")
    copy_runs(a.out, a.copy)


if __name__ == "__main__":
    main()
