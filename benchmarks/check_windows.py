"""How the self-check judges a network on windows near the longest gap it trained on, measured on validation clips
(the training contents' held-out takes: ``training.datamodule.split_train_val``, never test clips), and the long
thresholds that follow from it (``fill.long_check``, ``fill.long_x_full``, ``fill.long_x_none``; RESULTS.md 3.5).

For each checkpoint (one per fold: ``--ckpt fold-1=<a.ckpt> fold-2=<b.ckpt> ...``; ``split=a.ckpt,b.ckpt,...``: their
ensemble), each schedule (a key every ``K``
frames; default 15 and 30) and each validation clip: the self-check's pooled error ratio ``x`` (the network's error at
the hidden keys over interpolation's) and the fill's own ratio with the check off (the calibrated blend, feet not
locked).  Where ``x`` overstates the fill's error more at one schedule than another, the check judges the network
unfairly there.  The rule, fixed before any test clip was scored: the long pair is the regular pair (``x_full``,
``x_none``) times ``bias(long) / bias(regular)``, ``bias = pooled x / pooled fill ratio`` over every fold's validation
clips; ``long_check`` sits between the two schedules' check windows as a share of the trained gap.

``--choose`` then applies the project's no-more-harm rule on the same validation clips: it fills them at the long
schedule with the check on and the long pair moved from the regular pair towards the rule's in ``--steps`` equal steps
(geometric), and chooses the furthest step whose fills harm no more clips (worse than interpolation by over 5 %) and
are no worse pooled than with the regular pair (step 0).  ``--rule-from <json>`` takes the measured rule from an earlier
run's ``--json`` instead of measuring it again.

    python -m benchmarks run check_windows --ckpt fold-1=<ckpt> ... [--keys 15 30] [--clips 30] [--json out.json]
        [--choose [--steps 3] [--rule-from earlier.json]]
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))

from inbetweening.datasets import load_dataset  # noqa: E402
from inbetweening.evaluation.keyframes import WORSE, keyed_clip, position_error  # noqa: E402
from inbetweening.evaluation.schedules import schedule_keyframes  # noqa: E402
from inbetweening.geometry.interp import interpolate_keyframes  # noqa: E402
from inbetweening.runtime.settings import DEFAULT_SETTINGS, FillSettings  # noqa: E402
from inbetweening.training.datamodule import split_train_val  # noqa: E402
from inbetweening.training.evaluate import animator_runtime  # noqa: E402


def validation_clips(split: str, n_clips: int, data_path: str, val_fraction: float):
    """``(skeleton, clips)``: ``n_clips`` evenly spaced validation clips of ``split`` (all with ``0``)."""
    data = load_dataset("bandai_namco", path=data_path, split=split)
    _, val = split_train_val(list(data.train), val_fraction)
    if n_clips and n_clips < len(val):
        val = [val[i] for i in np.linspace(0, len(val) - 1, n_clips).round().astype(int)]
    return data.skeleton, val


def model_of(ckpt: str):
    """A checkpoint path, or the list of an ensemble's (``a.ckpt,b.ckpt,...``, as the shipped fill)."""
    paths = ckpt.split(",")
    return paths[0] if len(paths) == 1 else paths


def scored_fill(runtime, skeleton, clip, keys_every: int):
    """``(fill result, fill cm, interpolation cm, frames)`` of ``runtime`` on ``clip`` keyed every ``keys_every``
    frames (the keys-only protocol's clip, :func:`keyed_clip`); ``None`` with under three keys."""
    keys = schedule_keyframes(keys_every, len(clip.root_pos), np.random.default_rng(0), None)
    if len(keys) < 3:
        return None
    (root, q), (root_in, q_in), gen = keyed_clip(clip.root_pos, clip.local_q, keys)
    filled = runtime.fill(root_in, q_in, keys)
    gt = skeleton.pose(root, q)[1]
    f_cm, n = position_error(skeleton.pose(filled.root, filled.local_q)[1], gt, gen)
    i_cm, _ = position_error(skeleton.pose(*interpolate_keyframes(root_in, q_in, keys))[1], gt, gen)
    return filled, f_cm, i_cm, n


def measure(ckpt: str, split: str, keys_every: list[int], n_clips: int, data_path: str, val_fraction: float) -> dict:
    """``{K: {"x": [per clip], "check_net", "check_interp", "fill_cm", "interp_cm", "trained_gap"}}`` on ``n_clips``
    evenly spaced validation clips of ``split``."""
    sk, val = validation_clips(split, n_clips, data_path, val_fraction)
    model = model_of(ckpt)
    checking, _ = animator_runtime(model, foot_lock=False, self_check=True)
    plain, _ = animator_runtime(model, foot_lock=False, self_check=False)
    out = {}
    for k in keys_every:
        row = {"x": [], "fill_ratio": [], "check_net": 0.0, "check_interp": 0.0, "fill_cm": 0.0, "interp_cm": 0.0,
               "frames": 0, "trained_gap": checking.info.trained_gap, "clips": 0}
        for clip in val:
            checked = scored_fill(checking, sk, clip, k)
            checks = [c for c in checked[0].checks if c.interp > 0] if checked else []
            if not checks:
                continue
            _, f_cm, i_cm, f_n = scored_fill(plain, sk, clip, k)
            net, itp = sum(c.net for c in checks), sum(c.interp for c in checks)
            row["x"].append(net / itp)
            row["fill_ratio"].append(f_cm / i_cm)
            row["check_net"] += net
            row["check_interp"] += itp
            row["fill_cm"] += f_cm * f_n
            row["interp_cm"] += i_cm * f_n
            row["frames"] += f_n
            row["clips"] += 1
        out[k] = row
    return out


def candidate_pairs(rule: dict, steps: int) -> list[dict]:
    """The long pairs from the regular one (step 0: the defaults, ``long_check`` unused) to ``rule``'s, in ``steps``
    equal geometric steps, each with ``rule``'s ``long_check``."""
    s = DEFAULT_SETTINGS
    out = [{}]
    for i in range(1, steps + 1):
        f = i / steps
        out.append({"long_check": rule["long_check"],
                    "long_x_full": round(s.x_full * (rule["long_x_full"] / s.x_full) ** f, 3),
                    "long_x_none": round(s.x_none * (rule["long_x_none"] / s.x_none) ** f, 3)})
    return out


def fill_ratios(ckpt: str, split: str, keys_every: int, pairs: list[dict], n_clips: int, data_path: str,
                val_fraction: float) -> list[dict]:
    """Per pair: the checked fill's error over interpolation's on each validation clip of ``split`` (key every
    ``keys_every``), with the frame-weighted sums for the pooled ratio."""
    sk, val = validation_clips(split, n_clips, data_path, val_fraction)
    out = []
    for pair in pairs:
        runtime, _ = animator_runtime(model_of(ckpt), foot_lock=False, self_check=True,
                                      settings=FillSettings.from_mapping(pair))
        row = {"pair": pair, "ratios": [], "fill_cm": 0.0, "interp_cm": 0.0}
        for clip in val:
            scored = scored_fill(runtime, sk, clip, keys_every)
            if scored is None:
                continue
            _, f_cm, i_cm, n = scored
            row["ratios"].append(f_cm / i_cm)
            row["fill_cm"] += f_cm * n
            row["interp_cm"] += i_cm * n
        out.append(row)
    return out


def chosen(rows: list[dict]) -> int:
    """The furthest step whose fills harm no more validation clips than step 0's and are no worse pooled."""
    harmed = [sum(r > WORSE for r in row["ratios"]) for row in rows]
    pooled = [row["fill_cm"] / row["interp_cm"] for row in rows]
    ok = [i for i in range(len(rows)) if harmed[i] <= harmed[0] and pooled[i] <= pooled[0]]
    return max(ok)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ckpt", nargs="+", required=True,
                    help="split=checkpoint[,checkpoint...], e.g. fold-1=runs/0/checkpoints/calibrated.ckpt")
    ap.add_argument("--keys", type=int, nargs="+", default=[15, 30],
                    help="schedules: a key every K frames; the last is the long one")
    ap.add_argument("--clips", type=int, default=30, help="validation clips per checkpoint, evenly spaced")
    ap.add_argument("--val-fraction", type=float, default=0.1, help="the trainings' data.val_fraction")
    ap.add_argument("--data", default=str(ROOT.parent / "shared" / "datasets" / "bandai-namco-2.zip"))
    ap.add_argument("--json", default=None, help="write the per-checkpoint figures here")
    ap.add_argument("--choose", action="store_true",
                    help="then choose the long pair on the validation clips under the no-more-harm rule")
    ap.add_argument("--steps", type=int, default=3, help="--choose: steps from the regular pair to the rule's")
    ap.add_argument("--rule-from", default=None, help="--choose: the rule of an earlier run's --json (not measured again)")
    args = ap.parse_args(argv)
    if args.rule_from:
        report = json.loads(Path(args.rule_from).read_text())
    else:
        report = measure_all(args)
    if args.choose:
        report["choice"] = choose(args, report["rule"])
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=1))
    return 0


def choose(args, rule: dict) -> dict:
    """``--choose``: every candidate pair's harmed clips and pooled ratio over every checkpoint's validation clips at
    the long schedule, and the chosen pair."""
    pairs = candidate_pairs(rule, args.steps)
    rows = [{"pair": p, "ratios": [], "fill_cm": 0.0, "interp_cm": 0.0} for p in pairs]
    for item in args.ckpt:
        split, _, ckpt = item.partition("=")
        for row, r in zip(rows, fill_ratios(ckpt, split, args.keys[-1], pairs, args.clips, args.data, args.val_fraction)):
            row["ratios"] += r["ratios"]
            row["fill_cm"] += r["fill_cm"]
            row["interp_cm"] += r["interp_cm"]
    print(f"\nkeys {args.keys[-1]}, {len(rows[0]['ratios'])} validation clips, the check on:")
    print(f"{'step':>4} {'pair':<70} {'pooled':>7} {'harmed':>6}")
    for i, row in enumerate(rows):
        pair = " ".join(f"fill.{k}={v}" for k, v in row["pair"].items()) or "(regular)"
        print(f"{i:>4} {pair:<70} {row['fill_cm'] / row['interp_cm']:>7.3f} {sum(r > WORSE for r in row['ratios']):>6}")
    best = chosen(rows)
    print(f"chosen: step {best}: " + (" ".join(f"fill.{k}={v}" for k, v in rows[best]["pair"].items()) or "the regular pair"))
    return {"keys": args.keys[-1], "steps": rows, "chosen": best, "pair": rows[best]["pair"]}


def measure_all(args) -> dict:
    """The bias at each schedule over every checkpoint's validation clips, printed: ``{"per_split", "bias", "rule"}``
    (``rule``: the long pair that follows)."""
    pooled: dict[int, dict[str, float]] = {k: {"check_net": 0.0, "check_interp": 0.0, "fill_cm": 0.0, "interp_cm": 0.0}
                                           for k in args.keys}
    report, gaps = {}, set()
    print(f"{'split':<8} {'keys':>4} {'clips':>5} {'x pooled':>9} {'x median':>9} {'fill ratio':>10} {'bias':>6}")
    for item in args.ckpt:
        split, _, ckpt = item.partition("=")
        res = measure(ckpt, split, args.keys, args.clips, args.data, args.val_fraction)
        report[split] = {str(k): v for k, v in res.items()}
        for k, row in res.items():
            gaps.add(row["trained_gap"])
            for f in pooled[k]:
                pooled[k][f] += row[f]
            x, fr = row["check_net"] / row["check_interp"], row["fill_cm"] / row["interp_cm"]
            print(f"{split:<8} {k:>4} {row['clips']:>5} {x:>9.3f} {float(np.median(row['x'])):>9.3f} {fr:>10.3f} "
                  f"{x / fr:>6.3f}")
    bias = {k: (p["check_net"] / p["check_interp"]) / (p["fill_cm"] / p["interp_cm"]) for k, p in pooled.items()}
    for k in args.keys:
        p = pooled[k]
        print(f"{'pooled':<8} {k:>4} {'':>5} {p['check_net'] / p['check_interp']:>9.3f} {'':>9} "
              f"{p['fill_cm'] / p['interp_cm']:>10.3f} {bias[k]:>6.3f}")
    short, long_ = args.keys[0], args.keys[-1]
    scale = bias[long_] / bias[short]
    s = DEFAULT_SETTINGS
    share = ((2 * short - 1) + (2 * long_ - 1)) / 2 / min(gaps)  # between the two schedules' check windows
    rule = {"long_check": round(share, 3), "long_x_full": round(s.x_full * scale, 3), "long_x_none": round(s.x_none * scale, 3)}
    print(f"\nbias at keys {long_} over keys {short}: {scale:.3f} -> " + " ".join(f"fill.{k}={v}" for k, v in rule.items()))
    return {"per_split": report, "bias": {str(k): v for k, v in bias.items()}, "rule": rule}


if __name__ == "__main__":
    raise SystemExit(main())
