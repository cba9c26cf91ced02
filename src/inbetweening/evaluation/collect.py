"""Collect every run's ``benchmark.json`` of a sweep into one table (markdown + CSV).

    python -m inbetweening.collect <sweep dir> [--sort l2p@15] [--out results]

One row per configuration: the run's Hydra overrides (``.hydra/overrides.yaml``) name it, rows are
sorted by the chosen metric (ascending), and ``<out>.md`` / ``<out>.csv`` are written into the
sweep directory (or ``--out`` path).  Runs whose ``benchmark.json`` records the dataset's split (``data.split``)
get a ``split`` column; older files without it leave that cell empty.  Runs of ``eval.py protocol=keyframes`` (or
``train.py test_keyframes=[...]``) add their figures as columns ``kf_<figure>@<K>`` (``kf_model_cm@15``, ``kf_ratio@15``,
``kf_skate_model@15``, ...); files that record the interpolation baseline add ``l2p_ratio@<n>`` (model / interpolation).

``--seeds``: one row per configuration over its seeds (``seed=`` overrides), each figure as ``mean ± std`` (n runs).

``--folds``: the generalisation protocol (``experiment=folds``, ``data.split=fold-<i>``): per configuration one row per
fold and one pooled over the folds (errors summed over every clip's frames, clips worse than interpolation by more than
5 % counted over every clip, foot skating over the ground truth's), keys-only figures; with several seeds, the pooled
row per seed and their mean ± std.

``--contents``: keys-only results per motion content (every ``*.json`` under the folder, or one file, that records its
clips' ratios): the median clip ratio per schedule and the share of the content's clips worse than interpolation by
more than 5 %, so a pooled figure that hides one content's loss behind another's gain shows it.
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import numpy as np
import yaml

from inbetweening.data.specs import bandai_namco_content
from inbetweening.evaluation.keyframes import WORSE

METRIC_ORDER = ("l2q", "l2p", "l2p_ratio", "net_l2p", "net_l2p_ratio", "npss", "kf_model_cm", "kf_interp_cm", "kf_ratio",
                "kf_skate_model", "kf_skate_interp", "kf_skate_gt")
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


FOLD_SCHEDULES = ("5", "15", "30", "45", "random", "extremes")


def _kf_pool(parts: list[dict]) -> dict[str, float]:
    """Keys-only figures pooled over ``parts`` (``benchmark.json`` ``keyframes`` entries of one schedule): the ratio of
    summed errors (each part's mean weighted by its frames), the share of clips worse by > 5 % over all clips, the
    skating over the ground truth's (frame-weighted)."""
    fr = [p["n_frames"] for p in parts]
    model = sum(p["model_cm"] * f for p, f in zip(parts, fr))
    interp = sum(p["interp_cm"] * f for p, f in zip(parts, fr))
    clips = sum(p["n_clips"] for p in parts)
    out = {"ratio": model / interp, "worse": sum(p.get("worse_share", 0.0) * p["n_clips"] for p in parts) / clips}
    gt = sum(p["skate_gt"] * f for p, f in zip(parts, fr))
    if gt > 0:
        out["skate"] = sum(p["skate_model"] * f for p, f in zip(parts, fr)) / gt
    return out


def by_folds(sweep_dir: str | Path) -> list[dict]:
    """The folds table's rows (``--folds``): ``{"config", "fold", "seeds", "<K>", "worse@<K>", "skate@<K>"}`` for every
    fold of every configuration found under ``sweep_dir``, then its pooled row (``fold`` = ``"pooled"``; with several
    seeds each figure is the mean over the seeds' pooled figures and ``<figure>_std`` their spread)."""
    root = Path(sweep_dir)
    runs = []
    for f in sorted(root.rglob("benchmark.json")):
        res = json.loads(f.read_text())
        split = str(res.get("split") or "")
        if not split.startswith("fold-") or not res.get("keyframes"):
            continue
        cfg = f.parent / ".hydra" / "config.yaml"
        seed = (yaml.safe_load(cfg.read_text()) or {}).get("seed") if cfg.exists() else None
        label = " ".join(o for o in run_label(f.parent).split() if not o.startswith("data.split="))
        runs.append((label, split, seed, res["keyframes"]))
    if not runs:
        raise FileNotFoundError(f"no benchmark.json of a fold (data.split=fold-<i>) with keys-only figures under {root}")
    common = set.intersection(*(set(r[0].split()) for r in runs)) if len({r[0] for r in runs}) > 1 else set()
    groups: dict[str, list] = {}
    for label, split, seed, kf in runs:
        groups.setdefault(" ".join(o for o in label.split() if o not in common) or "(shared settings)", []).append(
            (split, seed, kf))

    def row(config, fold, parts_by_schedule, seeds):
        r = {"config": config, "fold": fold, "seeds": seeds}
        for k, parts in parts_by_schedule.items():
            pooled = _kf_pool(parts)
            r[k], r[f"worse@{k}"] = pooled["ratio"], pooled["worse"]
            if "skate" in pooled:
                r[f"skate@{k}"] = pooled["skate"]
        return r

    out = []
    for config in sorted(groups):
        items = groups[config]
        seeds = sorted({s for _, s, _ in items}, key=str)
        for fold in sorted({f for f, _, _ in items}, key=lambda f: int(f.split("-")[1])):
            sched = {k: [kf[k] for f, _, kf in items if f == fold and k in kf] for k in FOLD_SCHEDULES}
            out.append(row(config, fold, {k: v for k, v in sched.items() if v}, len(seeds)))
        per_seed = []
        for s in seeds:
            sched = {k: [kf[k] for _, ss, kf in items if ss == s and k in kf] for k in FOLD_SCHEDULES}
            per_seed.append(row(config, "pooled", {k: v for k, v in sched.items() if v}, 1))
        pooled = {"config": config, "fold": "pooled", "seeds": len(seeds),
                  "folds": len({f for f, _, _ in items})}
        for c in {c for r in per_seed for c in r if c not in ("config", "fold", "seeds")}:
            vals = [r[c] for r in per_seed if c in r]
            mean = sum(vals) / len(vals)
            pooled[c] = mean
            if len(vals) > 1:
                pooled[c + "_std"] = (sum((v - mean) ** 2 for v in vals) / (len(vals) - 1)) ** 0.5
        out.append(pooled)
    return out


def folds_markdown(rows: list[dict]) -> str:
    """The folds table: keys-only ratio per schedule (share of clips worse by > 5 %), skating over the ground truth's
    at keys every 15 / 30 / 45."""
    head = ("| config | fold | " + " | ".join(f"keys {k}" for k in FOLD_SCHEDULES)
            + " | skate / truth @15 / 30 / 45 |")
    lines = [head, "|---|---|" + "---:|" * len(FOLD_SCHEDULES) + "---|"]

    def cell(r, k):
        if k not in r:
            return "–"
        std = f" ± {r[k + '_std']:.3f}" if k + "_std" in r else ""
        return f"{r[k]:.3f}{std} ({100 * r.get(f'worse@{k}', 0.0):.1f} %)"

    for r in rows:
        fold = f"**pooled** ({r['seeds']} seed{'s' if r['seeds'] > 1 else ''})" if r["fold"] == "pooled" else r["fold"]
        sk = " / ".join(f"{r[f'skate@{k}']:.1f}" if f"skate@{k}" in r else "–" for k in ("15", "30", "45"))
        lines.append(f"| {r['config']} | {fold} | " + " | ".join(cell(r, k) for k in FOLD_SCHEDULES) + f" | {sk} |")
    return "\n".join(lines)


def write_rows_csv(rows: list[dict], path: Path) -> None:
    """A table's rows (:func:`by_folds`, :func:`by_contents`) as CSV, every figure a column."""
    cols = sorted({c for r in rows for c in r}, key=lambda c: (c not in ("config", "fold", "seeds", "folds"), c))
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=cols)
        w.writeheader()
        w.writerows(rows)


def by_contents(sweep_dir: str | Path) -> list[dict]:
    """The per-content rows (``--contents``) of every keys-only result (``*.json``) under ``sweep_dir``, or of that
    one file, that records its clips' ratios: ``{"run", "config", "content", "clips", "<K>", "worse@<K>"}``, ``<K>``
    the median clip ratio at that schedule and ``worse@<K>`` the share of the content's clips worse than interpolation
    by more than 5 % (Bandai-Namco contents by clip name; other clips under ``"(other)"``)."""
    root = Path(sweep_dir)
    if not root.exists():
        raise FileNotFoundError(f"{root} does not exist")
    files = [root] if root.is_file() else sorted(root.rglob("*.json"))
    rows = []
    for f in files:
        try:
            res = json.loads(f.read_text())
        except (OSError, ValueError):
            continue
        kf = res.get("keyframes") if isinstance(res, dict) else None
        if not isinstance(kf, dict) or not any(isinstance(v, dict) and v.get("clip_ratios") for v in kf.values()):
            continue
        groups: dict[str, dict[str, list[float]]] = {}
        for k, v in kf.items():
            for clip, r in (v.get("clip_ratios") or {}).items():
                groups.setdefault(bandai_namco_content(clip) or "(other)", {}).setdefault(k, []).append(r)
        run = f.parent if f.name == "benchmark.json" else f.with_suffix("")
        for content, per in sorted(groups.items()):
            row = {"run": str(run.relative_to(root)) if root.is_dir() and run != root else run.name,
                   "config": run_label(run) if run.is_dir() else run.name, "content": content,
                   "clips": max(len(v) for v in per.values())}
            for k, ratios in per.items():
                row[k] = float(np.median(ratios))
                row[f"worse@{k}"] = float(np.mean(np.asarray(ratios) > WORSE))
            rows.append(row)
    if not rows:
        raise FileNotFoundError(f"no keys-only benchmark with per-clip ratios (clip_ratios) under {root}")
    return rows


def contents_markdown(rows: list[dict]) -> str:
    """The per-content table: the median clip ratio per schedule (share of clips worse by > 5 %)."""
    ks = [k for k in FOLD_SCHEDULES if any(k in r for r in rows)]
    lines = ["| run | content | clips | " + " | ".join(f"keys {k}" for k in ks) + " |",
             "|---|---|---:|" + "---:|" * len(ks)]
    for r in rows:
        cells = [f"{r[k]:.3f} ({100 * r[f'worse@{k}']:.1f} %)" if k in r else "–" for k in ks]
        lines.append(f"| {r['run']} | {r['content']} | {r['clips']} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def ratio_columns(res: dict) -> dict[str, float]:
    """``{"l2p_ratio@<n>": model / interpolation}`` where the file records the interpolation baseline; for a run
    whose figures are a blended fill's and that records the network alone too (``network``), ``net_l2p@<n>`` and
    ``net_l2p_ratio@<n>``."""
    ref, met, net = res.get("interpolation") or {}, res.get("metrics") or {}, res.get("network") or {}
    out = {f"l2p_ratio@{k[4:]}": met[k] / ref[k] for k in met if k.startswith("l2p@") and ref.get(k)}
    out.update({f"net_l2p@{k[4:]}": v for k, v in net.items() if k.startswith("l2p@")})
    out.update({f"net_l2p_ratio@{k[4:]}": net[k] / ref[k] for k in net if k.startswith("l2p@") and ref.get(k)})
    return out


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
    ap.add_argument("--folds", action="store_true", help="the generalisation folds: per fold and pooled")
    ap.add_argument("--contents", action="store_true",
                    help="keys-only results per content: the median clip ratio and the share of clips worse")
    args = ap.parse_args(argv)
    try:
        if args.folds:
            rows, name, markdown, table = by_folds(args.sweep_dir), "folds", folds_markdown, write_rows_csv
        elif args.contents:
            rows, name, markdown, table = by_contents(args.sweep_dir), "contents", contents_markdown, write_rows_csv
        else:
            rows, name, markdown, table = collect(args.sweep_dir, args.sort), "results", to_markdown, write_csv
            if args.seeds:
                rows = by_seeds(rows)
                rows.sort(key=lambda r: (r.get(args.sort) is None, r.get(args.sort, 0.0)))
    except FileNotFoundError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    src = Path(args.sweep_dir)
    out = Path(args.out) if args.out else (src.parent if src.is_file() else src) / name
    md = markdown(rows)
    out.with_suffix(".md").write_text(md + "\n")
    table(rows, out.with_suffix(".csv"))
    print(md)
    print(f"\n{len(rows)} rows -> {out.with_suffix('.md')}, {out.with_suffix('.csv')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
