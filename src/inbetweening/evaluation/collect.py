"""Collect every run's ``benchmark.json`` of a sweep into one table (markdown + CSV).

    python -m inbetweening.collect <sweep dir> [--sort l2p@15] [--out results]

One row per configuration: the run's Hydra overrides (``.hydra/overrides.yaml``) name it, rows are
sorted by the chosen metric (ascending), and ``<out>.md`` / ``<out>.csv`` are written into the
sweep directory (or ``--out`` path).  Runs whose ``benchmark.json`` records the dataset's split (``data.split``)
get a ``split`` column; older files without it leave that cell empty.  Runs of ``eval.py protocol=keyframes`` (or
``train.py test_keyframes=[...]``) add their figures as columns ``kf_<figure>@<K>`` (``kf_model_cm@15``, ``kf_ratio@15``,
``kf_skate_model@15``, ...); files that record the interpolation baseline add ``l2p_ratio@<n>`` (model / interpolation).

``--seeds``: one row per configuration over its seeds (``seed=`` overrides), each figure as ``mean ± std`` (n runs).
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import yaml

METRIC_ORDER = ("l2q", "l2p", "l2p_ratio", "npss", "kf_model_cm", "kf_interp_cm", "kf_ratio", "kf_skate_model", "kf_skate_interp",
                "kf_skate_gt")
KEYFRAME_FIGURES = tuple(m[3:] for m in METRIC_ORDER if m.startswith("kf_"))
IGNORED = ("hydra.", "paths.", "seed=", "ckpt_path=", "trainer.max_steps=", "trainer.max_epochs=", "ablation=",
           "trainer.val_check_interval=", "model.checkpoint_layers=", "model.fused_attention=")


def run_label(run_dir: Path) -> str:
    """The run's overrides (minus bookkeeping ones), e.g. ``mask=zero model.depth=6``."""
    f = run_dir / ".hydra" / "overrides.yaml"
    if f.exists():
        items = [o for o in (yaml.safe_load(f.read_text()) or []) if not o.startswith(IGNORED)]
        if items:
            return " ".join(items)
    return run_dir.name


def collect(sweep_dir: str | Path, sort: str = "l2p@15") -> list[dict]:
    """Rows ``{"run", "config", "dataset", "split", "model", "n_windows", <metrics>...}`` sorted by ``sort``
    (``split`` is ``None`` for a file that does not record it)."""
    root = Path(sweep_dir)
    if not root.exists():
        raise FileNotFoundError(f"{root} does not exist")
    rows = []
    for f in sorted(root.rglob("benchmark.json")):
        res = json.loads(f.read_text())
        run = f.parent
        rows.append({"run": str(run.relative_to(root)) if run != root else ".", "config": run_label(run),
                     "dataset": res.get("dataset"), "split": res.get("split"), "model": res.get("model"),
                     "n_windows": res.get("n_windows"),
                     **res.get("metrics", {}), **ratio_columns(res), **keyframe_columns(res)})
    if not rows:
        raise FileNotFoundError(f"no benchmark.json under {root}")
    # overrides shared by every run say nothing about a row: drop them from the labels
    common = set.intersection(*(set(r["config"].split()) for r in rows)) if len(rows) > 1 else set()
    for r in rows:
        r["config"] = " ".join(o for o in r["config"].split() if o not in common) or "(shared settings)"
    rows.sort(key=lambda r: (r.get(sort) is None, r.get(sort, 0.0)))
    return rows


def ratio_columns(res: dict) -> dict[str, float]:
    """``{"l2p_ratio@<n>": model / interpolation}`` where the file records the interpolation baseline."""
    ref, met = res.get("interpolation") or {}, res.get("metrics") or {}
    return {f"l2p_ratio@{k[4:]}": met[k] / ref[k] for k in met if k.startswith("l2p@") and ref.get(k)}


def by_seeds(rows: list[dict]) -> list[dict]:
    """One row per (config, model, split): every figure's mean and sample std over the rows (seeds), ``n`` runs."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault((r["config"], r["model"], r.get("split")), []).append(r)
    out = []
    for (config, model, split), rs in groups.items():
        row = {"config": config, "model": model, "split": split, "dataset": rs[0].get("dataset"), "n": len(rs),
               "n_windows": rs[0].get("n_windows"), "run": " ".join(r["run"] for r in rs)}
        for c in metric_columns(rs):
            vals = [r[c] for r in rs if r.get(c) is not None]
            if vals:
                mean = sum(vals) / len(vals)
                std = (sum((v - mean) ** 2 for v in vals) / (len(vals) - 1)) ** 0.5 if len(vals) > 1 else 0.0
                row[c], row[c + "_std"] = mean, std
        out.append(row)
    return out


def keyframe_columns(res: dict) -> dict[str, float]:
    """The ``keyframes`` figures of a ``benchmark.json`` (``protocol=keyframes``) as ``{"kf_<figure>@<K>": value}``."""
    return {f"kf_{m}@{k}": v for k, row in (res.get("keyframes") or {}).items() for m, v in row.items()
            if m in KEYFRAME_FIGURES}


def metric_columns(rows: list[dict]) -> list[str]:
    keys = {k for r in rows for k in r if ("@" in k or k == "recovery_rmse") and not k.endswith("_std")}
    def order(k: str):
        m, _, n = k.partition("@")
        return (METRIC_ORDER.index(m) if m in METRIC_ORDER else 9, int(n) if n.isdigit() else 10**6, n)  # schedules last

    return sorted(keys, key=order)


def has_split(rows: list[dict]) -> bool:
    """Whether any run recorded its dataset split (then the tables get a ``split`` column)."""
    return any(r.get("split") is not None for r in rows)


def to_markdown(rows: list[dict]) -> str:
    cols = metric_columns(rows)
    split = has_split(rows)
    head = "| config | model | " + ("split | " if split else "") + " | ".join(c.upper() for c in cols) + " |"
    lines = [head, "|---|---|" + ("---|" if split else "") + "---:|" * len(cols)]
    for r in rows:
        cells = [_cell(r, c) for c in cols]
        if split:
            cells.insert(0, r.get("split") or "")
        lines.append(f"| {r['config']} | {r['model']} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _cell(r: dict, c: str) -> str:
    if r.get(c) is None:
        return ""
    fmt = ".4f" if c.startswith("npss") else ".3f"
    if c + "_std" in r:
        return f"{r[c]:{fmt}} ± {r[c + '_std']:{fmt}} ({r['n']})"
    return f"{r[c]:{fmt}}"


def write_csv(rows: list[dict], path: Path) -> None:
    metrics = metric_columns(rows)
    stds = [c + "_std" for c in metrics if any(c + "_std" in r for r in rows)]
    cols = ["config", "model", "dataset", *(["split"] if has_split(rows) else []), "n_windows",
            *(["n"] if stds else []), *metrics, *stds, "run"]
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=cols, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("sweep_dir")
    ap.add_argument("--sort", default="l2p@15", help="metric to sort by (ascending), default l2p@15")
    ap.add_argument("--out", default=None, help="output path without extension (default <sweep_dir>/results)")
    ap.add_argument("--seeds", action="store_true", help="one row per configuration: mean ± std over its seeds")
    args = ap.parse_args(argv)
    try:
        rows = collect(args.sweep_dir, args.sort)
        if args.seeds:
            rows = by_seeds(rows)
            rows.sort(key=lambda r: (r.get(args.sort) is None, r.get(args.sort, 0.0)))
    except FileNotFoundError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    out = Path(args.out) if args.out else Path(args.sweep_dir) / "results"
    md = to_markdown(rows)
    out.with_suffix(".md").write_text(md + "\n")
    write_csv(rows, out.with_suffix(".csv"))
    print(md)
    print(f"\n{len(rows)} runs -> {out.with_suffix('.md')}, {out.with_suffix('.csv')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
