"""The tables of model v2 (RESULTS.md section 2.2) from the files of ``benchmarks/model_v2.sh``, next to the
shipped v1 models with and without the do-no-harm blend (``results/do_no_harm/``), and issue 25's targets.

    python benchmarks/model_v2_table.py <out dir of model_v2.sh> [--copy results/model_v2]

Reads ``<out>/<split>_run_benchmark.json`` (the run's own test: the calibrated checkpoint, feet locked),
``<out>/<split>_blended_unlocked``, ``<out>/<split>_plain_lafan`` and ``<out>/<split>_plain_keyframes`` (each
``benchmark.json``).  LAFAN ratios are to interpolation on the same windows (the run's ``interpolation`` figures, or
``results/do_no_harm/<split>_interpolation_lafan.json``); keyframes ratios and skating are the protocol's own.
``--copy``: also copy the JSON files there (``<split>_<name>.json``).
"""
from __future__ import annotations

import argparse
import shutil
from pathlib import Path

from do_no_harm_table import LENGTHS, SCHEDULES, SPLITS, load  # the same splits, lengths, schedules and reader

ROOT = Path(__file__).resolve().parents[1]
# issue 25's targets (v2, test splits)
LAFAN_TARGET = {"standard": (0.45, 0.40, 0.45, 0.50), "content": (0.90, 0.70, 0.75, 0.85)}
K30_TARGET = {"standard": 0.50, "content": 0.75}
SKATE_MAX_STANDARD, LOCK_COST_MAX = 5.0, 0.02


def rows(out: Path, split: str) -> dict[str, dict]:
    """name -> {"lafan": metrics or None, "interp": metrics, "keyframes": {schedule: row} or None}."""
    dnh = ROOT / "results" / "do_no_harm"
    run = load(out / f"{split}_run_benchmark.json") or {}
    interp = run.get("interpolation") or (load(dnh / f"{split}_interpolation_lafan.json") or {}).get("metrics")

    def bench(name: str) -> dict:
        return load(out / name / "benchmark.json") or {}

    def v1(variant: str, proto: str) -> dict:
        return load(dnh / f"{split}_{variant}_{proto}.json") or {}

    return {
        "v1": {"lafan": v1("plain", "lafan").get("metrics"), "keyframes": v1("plain", "keyframes").get("keyframes")},
        "v1 + blend": {"lafan": v1("blended", "lafan").get("metrics"),
                       "keyframes": v1("blended", "keyframes").get("keyframes")},
        "v2": {"lafan": bench(f"{split}_plain_lafan").get("metrics"),
               "keyframes": bench(f"{split}_plain_keyframes").get("keyframes")},
        "v2 + blend": {"lafan": run.get("metrics"), "keyframes": run.get("keyframes")},
        "v2 + blend, feet not locked": {"lafan": None, "keyframes": bench(f"{split}_blended_unlocked").get("keyframes")},
        "_interp": {"lafan": interp, "keyframes": None},
    }


def ratio(lafan: dict | None, interp: dict | None, n: int) -> float | None:
    return lafan[f"l2p@{n}"] / interp[f"l2p@{n}"] if lafan and interp else None


def fmt(v: float | None, spec: str = ".3f") -> str:
    return "–" if v is None else format(v, spec)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("out", type=Path)
    ap.add_argument("--copy", type=Path)
    a = ap.parse_args()
    head = (["split", "model"] + [f"L2P ratio @{n}" for n in LENGTHS] + [f"keys {s}: ratio" for s in SCHEDULES])
    lines = ["| " + " | ".join(head) + " |", "|---|---" + "|---:" * (len(head) - 2) + "|"]
    skate = ["| split | model | " + " | ".join(f"keys {s}: skate" for s in SCHEDULES) + " |",
             "|---|---" + "|---:" * len(SCHEDULES) + "|"]
    checks: list[str] = []
    for split in SPLITS:
        r = rows(a.out, split)
        interp = r.pop("_interp")["lafan"]
        for name, row in r.items():
            kf = row["keyframes"] or {}
            lines.append("| " + " | ".join([split, name] + [fmt(ratio(row["lafan"], interp, n)) for n in LENGTHS]
                                           + [fmt((kf.get(s) or {}).get("ratio")) for s in SCHEDULES]) + " |")
            skate.append("| " + " | ".join([split, name] + [fmt((kf.get(s) or {}).get("skate_model"), ".2f")
                                                             for s in SCHEDULES]) + " |")
        ref = r["v2 + blend"]["keyframes"] or {}
        skate.append("| " + " | ".join([split, "interpolation"] + [fmt((ref.get(s) or {}).get("skate_interp"), ".2f")
                                                                   for s in SCHEDULES]) + " |")
        skate.append("| " + " | ".join([split, "ground truth"] + [fmt((ref.get(s) or {}).get("skate_gt"), ".2f")
                                                                  for s in SCHEDULES]) + " |")
        checks += targets(split, r, interp)
    print("\n".join(lines) + "\n\nFoot skating (cm/s where the real foot is planted):\n\n" + "\n".join(skate))
    print("\nIssue 25's targets (v2 + blend, feet locked):\n" + "\n".join(checks))
    if a.copy:
        a.copy.mkdir(parents=True, exist_ok=True)
        for p in sorted(a.out.glob("*_run_benchmark.json")):
            shutil.copy(p, a.copy / p.name)
        for p in sorted(a.out.glob("*_*/benchmark.json")):
            shutil.copy(p, a.copy / f"{p.parent.name}.json")


def targets(split: str, r: dict, interp: dict | None) -> list[str]:
    """One line per target: the figures and met / MISSED."""
    out = []
    v2, unlocked = r["v2 + blend"], r["v2 + blend, feet not locked"]
    kf, kf_free = v2["keyframes"] or {}, unlocked["keyframes"] or {}

    def line(what: str, ok: bool | None, figures: str) -> None:
        out.append(f"- {split}: {what}: {figures} -> {'–' if ok is None else 'met' if ok else 'MISSED'}")

    got = {s: kf[s]["ratio"] for s in SCHEDULES if s in kf}
    line("keys only <= 1.00 at every schedule", max(got.values()) <= 1.0 if got else None,
         ", ".join(f"{s}: {v:.3f}" for s, v in got.items()))
    line(f"keys every 30 <= {K30_TARGET[split]:.2f}", kf["30"]["ratio"] <= K30_TARGET[split] if "30" in kf else None,
         fmt(kf.get("30", {}).get("ratio")))
    sk = {s: (kf[s]["skate_model"], kf[s]["skate_interp"]) for s in SCHEDULES if s in kf}
    line("skating with locking <= interpolation's at every schedule",
         all(m <= i for m, i in sk.values()) if sk else None,
         ", ".join(f"{s}: {m:.2f} vs {i:.2f}" for s, (m, i) in sk.items()))
    if split == "standard":
        line(f"skating with locking <= {SKATE_MAX_STANDARD:g} cm/s at every schedule",
             all(m <= SKATE_MAX_STANDARD for m, _ in sk.values()) if sk else None,
             f"worst {max(m for m, _ in sk.values()):.2f}" if sk else "–")
    cost = {s: kf[s]["model_cm"] / kf_free[s]["model_cm"] - 1 for s in SCHEDULES if s in kf and s in kf_free}
    line(f"joint error with locking <= {LOCK_COST_MAX:.0%} above without",
         all(c <= LOCK_COST_MAX for c in cost.values()) if cost else None,
         ", ".join(f"{s}: {c:+.1%}" for s, c in cost.items()))
    lafan = [ratio(v2["lafan"], interp, n) for n in LENGTHS]
    line("LAFAN L2P ratios <= " + " / ".join(f"{t:.2f}" for t in LAFAN_TARGET[split]),
         all(v is not None and v <= t for v, t in zip(lafan, LAFAN_TARGET[split])) if None not in lafan else None,
         " / ".join(fmt(v) for v in lafan))
    if split == "standard":  # the ship rule: LAFAN within 0.01 of v1 at every length and better on the keyframes
        for base in ("v1", "v1 + blend"):
            old = [ratio(r[base]["lafan"], interp, n) for n in LENGTHS]
            okf = r[base]["keyframes"] or {}
            if None in lafan or None in old:
                continue
            better = {s: kf[s]["ratio"] < okf[s]["ratio"] for s in SCHEDULES if s in kf and s in okf}
            line(f"ship rule against {base}: LAFAN within 0.01 at every length",
                 all(n <= o + 0.01 for n, o in zip(lafan, old)),
                 " / ".join(f"{n:.3f} vs {o:.3f}" for n, o in zip(lafan, old)))
            line(f"ship rule against {base}: better on the keyframes tables", all(better.values()) if better else None,
                 ", ".join(f"{s}: {kf[s]['ratio']:.3f} vs {okf[s]['ratio']:.3f}" for s in better))
    return out


if __name__ == "__main__":
    main()
