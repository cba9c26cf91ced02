"""The tables of "never worse than interpolation, planted feet" (RESULTS.md section 5) from the runs of
``benchmarks/never_worse.sh`` and ``benchmarks/loco_eval.sh``.

    python benchmarks/never_worse_table.py <out dir> [--copy results/never_worse]

Reads every ``<out>/<run>/benchmark.json`` (``protocol=keyframes``) and prints one row per run: per schedule the
pooled ratio to interpolation, the share of clips worse than interpolation by more than 5 % and the foot skating
(cm/s; interpolation's and the ground truth's in the last rows of each run), then the worst clips by name.  With
several runs named ``<content>_<variant>`` (leave-one-content-out) it adds the pooled row of each variant: every
content's clips together (ratios of summed errors are not available from the files; the pooled ratio is the
clip-weighted mean of the contents' ratios) and the share of all clips worse by more than 5 %.  ``--copy``: also copy
the JSON files there as ``<run>.json``.
"""
from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

from inbetweening.data.specs import BN_CONTENTS

SCHEDULES = ("5", "15", "30", "45", "random", "extremes")
WORSE = 1.05


def out_and_copy(description: str) -> argparse.Namespace:
    """The tables' command line: ``out`` (the runs' folder) and ``--copy`` (:func:`copy_runs`)."""
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("out", type=Path)
    ap.add_argument("--copy", type=Path, default=None, help="also copy each run's benchmark.json there as <run>.json")
    return ap.parse_args()


def copy_runs(out: Path, dest: Path | None) -> None:
    """``--copy``: each ``<out>/<run>/benchmark.json`` copied to ``<dest>/<run>.json`` (nothing when ``dest`` is None)."""
    if dest is None:
        return
    dest.mkdir(parents=True, exist_ok=True)
    for p in sorted(out.glob("*/benchmark.json")):
        shutil.copy(p, dest / f"{p.parent.name}.json")


def rows(out: Path) -> dict[str, dict]:
    found = {}
    for p in sorted(out.glob("*/benchmark.json")):
        res = json.loads(p.read_text())
        if res.get("keyframes"):
            found[p.parent.name] = res["keyframes"]
    return found


def cell(r: dict | None) -> str:
    if not r:
        return "–"
    skate = f", {r['skate_model']:.1f}" if "skate_model" in r else ""
    return f"{r['ratio']:.3f} ({100 * r.get('worse_share', 0.0):.1f} %{skate})"


def pooled(runs: dict[str, dict], variant: str) -> dict[str, dict]:
    """Every content's clips of one variant together: clip-weighted ratio, share worse, clip-weighted skating."""
    out = {}
    for s in SCHEDULES:
        parts = [kf[s] for name, kf in runs.items() if name.rsplit("_", 1)[0] in BN_CONTENTS
                 and name.endswith(f"_{variant}") and s in kf]
        if not parts:
            continue
        n = sum(p["n_clips"] for p in parts)
        ratios = [v for p in parts for v in p.get("clip_ratios", {}).values()]
        out[s] = {"ratio": sum(p["ratio"] * p["n_clips"] for p in parts) / n,
                  "worse_share": sum(v > WORSE for v in ratios) / max(len(ratios), 1),
                  "skate_model": sum(p.get("skate_model", 0.0) * p["n_clips"] for p in parts) / n,
                  "worst": ", ".join(f"{k} {v:.2f}" for k, v in sorted(
                      ((k, v) for p in parts for k, v in p.get("clip_ratios", {}).items()), key=lambda kv: -kv[1])[:3])}
    return out


def main() -> None:
    a = out_and_copy(__doc__.splitlines()[0])
    runs = rows(a.out)
    variants = sorted({n.rsplit("_", 1)[1] for n in runs if n.rsplit("_", 1)[0] in BN_CONTENTS})
    table = dict(runs)
    for v in variants:
        table[f"all contents ({v})"] = pooled(runs, v)
    head = ["run"] + [f"keys {s}: ratio (worse > 5 %, skate cm/s)" for s in SCHEDULES]
    lines = ["| " + " | ".join(head) + " |", "|---" + "|---:" * len(SCHEDULES) + "|"]
    for name, kf in table.items():
        lines.append("| " + " | ".join([name] + [cell(kf.get(s)) for s in SCHEDULES]) + " |")
    first = next(iter(runs.values()), {})
    if first and "skate_interp" in next(iter(first.values())):
        for who in ("interp", "gt"):
            label = {"interp": "interpolation skate", "gt": "ground-truth skate"}[who]
            for name, kf in runs.items():
                cells = [f"{kf[s][f'skate_{who}']:.1f}" if s in kf else "–" for s in SCHEDULES]
                lines.append(f"| {name}: {label} | " + " | ".join(cells) + " |")
    print("\n".join(lines))
    print("\nWorst clips (ratio):")
    for name, kf in table.items():
        for s in SCHEDULES:
            if s in kf and kf[s].get("worst"):
                print(f"- {name}, keys {s}: {kf[s]['worst']}")
    copy_runs(a.out, a.copy)


if __name__ == "__main__":
    main()
