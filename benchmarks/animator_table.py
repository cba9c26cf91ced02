"""The table of model v2's lever ablation (RESULTS.md section 6.1) from the runs of ``benchmarks/animator_ablation.sh``.

    python benchmarks/animator_table.py <out dir of animator_ablation.sh> [--copy results/animator_ablation]

Reads ``<out>/<variant>_s<seed>/benchmark.json`` (and ``<variant>_s<seed>_unlocked/benchmark.json``, the keyframes
protocol of the same checkpoint with ``foot_lock=false``, where present) and prints one markdown row per run and one
per variant (the mean over seeds): the LAFAN protocol's L2P ratios to interpolation on the same windows, and the
keyframes protocol's error ratios and foot skating per schedule.  ``--copy``: also copy the JSON files there.
"""
from __future__ import annotations

import argparse
import json
import shutil
import sys
from pathlib import Path

VARIANTS = ("base", "task", "gate", "contacts")
LENGTHS = (5, 15, 30, 45)


def load(run: Path) -> dict | None:
    path = run / "benchmark.json"
    return json.loads(path.read_text()) if path.is_file() else None


def row(bench: dict, unlocked: dict | None) -> dict[str, float]:
    """The figures of one run: ``l2p@L`` ratios, ``kf<S>`` error ratios, ``skate<S>`` (model, locked where the
    model has contacts), ``skate<S>_unlocked`` / ``kf<S>_unlocked`` where measured, ``skate<S>_interp``."""
    out = {}
    for n in LENGTHS:
        out[f"l2p@{n}"] = bench["metrics"][f"l2p@{n}"] / bench["interpolation"][f"l2p@{n}"]
    for s, r in bench.get("keyframes", {}).items():
        out[f"kf{s}"], out[f"skate{s}"], out[f"skate{s}_interp"] = r["ratio"], r["skate_model"], r["skate_interp"]
        out[f"cm{s}"] = r["model_cm"]
        if unlocked and s in unlocked.get("keyframes", {}):
            u = unlocked["keyframes"][s]
            out[f"kf{s}_unlocked"], out[f"skate{s}_unlocked"], out[f"cm{s}_unlocked"] = \
                u["ratio"], u["skate_model"], u["model_cm"]
    return out


def fmt(v: float | None, digits: int = 3) -> str:
    return "–" if v is None else f"{v:.{digits}f}"


def table(rows: dict[str, dict], schedules: list[str]) -> str:
    head = ["run"] + [f"L2P ratio @{n}" for n in LENGTHS] + [f"keys {s}: ratio" for s in schedules] + \
           [f"keys {s}: skate (unlocked)" for s in schedules]
    lines = ["| " + " | ".join(head) + " |", "|---" + "|---:" * (len(head) - 1) + "|"]
    for name, r in rows.items():
        cells = [name] + [fmt(r.get(f"l2p@{n}")) for n in LENGTHS] + [fmt(r.get(f"kf{s}")) for s in schedules]
        for s in schedules:
            skate = fmt(r.get(f"skate{s}"), 1)
            if f"skate{s}_unlocked" in r:
                skate += f" ({fmt(r[f'skate{s}_unlocked'], 1)})"
            cells.append(skate)
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--copy", type=Path, default=None)
    args = ap.parse_args(argv)
    per_run, per_variant, schedules = {}, {}, []
    for variant in VARIANTS:
        runs = sorted(args.out.glob(f"{variant}_s[0-9]*"))
        runs = [r for r in runs if r.is_dir() and not r.name.endswith("_unlocked")]
        got = []
        for run in runs:
            bench = load(run)
            if bench is None:
                continue
            r = row(bench, load(run.with_name(run.name + "_unlocked")))
            per_run[run.name], got = r, got + [r]
            schedules = schedules or list(bench.get("keyframes", {}))
            if args.copy:
                args.copy.mkdir(parents=True, exist_ok=True)
                shutil.copy(run / "benchmark.json", args.copy / f"{run.name}.json")
                unlocked = run.with_name(run.name + "_unlocked") / "benchmark.json"
                if unlocked.is_file():
                    shutil.copy(unlocked, args.copy / f"{run.name}_unlocked.json")
        if got:
            keys = set.intersection(*(set(g) for g in got))
            per_variant[f"{variant} (mean of {len(got)})"] = {k: sum(g[k] for g in got) / len(got) for k in keys}
    if not per_run:
        print(f"error: no <variant>_s<seed>/benchmark.json under {args.out}", file=sys.stderr)
        return 2
    print(table(per_variant, schedules))
    print()
    print(table(per_run, schedules))
    interp = {s: [r[f"skate{s}_interp"] for r in per_run.values() if f"skate{s}_interp" in r] for s in schedules}
    print("\ninterpolation's skate: " + ", ".join(f"{s}: {sum(v) / len(v):.1f}" for s, v in interp.items() if v))
    for name, r in per_run.items():
        for s in schedules:
            if f"cm{s}_unlocked" in r:
                print(f"{name} keys {s}: error {r[f'cm{s}']:.3f} cm locked, {r[f'cm{s}_unlocked']:.3f} unlocked "
                      f"({100 * (r[f'cm{s}'] / r[f'cm{s}_unlocked'] - 1):+.1f} %)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
