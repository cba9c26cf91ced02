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

    python -m benchmarks run check_windows --ckpt fold-1=<ckpt> ... [--keys 15 30] [--clips 30] [--json out.json]
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
from inbetweening.evaluation.keyframes import keyed_clip, position_error  # noqa: E402
from inbetweening.evaluation.schedules import schedule_keyframes  # noqa: E402
from inbetweening.geometry.interp import interpolate_keyframes  # noqa: E402
from inbetweening.runtime.settings import DEFAULT_SETTINGS  # noqa: E402
from inbetweening.training.datamodule import split_train_val  # noqa: E402
from inbetweening.training.evaluate import animator_runtime  # noqa: E402


def measure(ckpt: str, split: str, keys_every: list[int], n_clips: int, data_path: str, val_fraction: float) -> dict:
    """``{K: {"x": [per clip], "check_net", "check_interp", "fill_cm", "interp_cm", "trained_gap"}}`` on ``n_clips``
    evenly spaced validation clips of ``split``."""
    data = load_dataset("bandai_namco", path=data_path, split=split)
    _, val = split_train_val(list(data.train), val_fraction)
    if n_clips and n_clips < len(val):
        val = [val[i] for i in np.linspace(0, len(val) - 1, n_clips).round().astype(int)]
    paths = ckpt.split(",")  # several: their ensemble, as the shipped fill
    model = paths[0] if len(paths) == 1 else paths
    checking, _ = animator_runtime(model, foot_lock=False, self_check=True)
    plain, _ = animator_runtime(model, foot_lock=False, self_check=False)
    sk, out = data.skeleton, {}
    for k in keys_every:
        row = {"x": [], "fill_ratio": [], "check_net": 0.0, "check_interp": 0.0, "fill_cm": 0.0, "interp_cm": 0.0,
               "frames": 0, "trained_gap": checking.info.trained_gap, "clips": 0}
        for clip in val:
            keys = schedule_keyframes(k, len(clip.root_pos), np.random.default_rng(0), None)
            if len(keys) < 3:
                continue
            (root, q), (root_in, q_in), gen = keyed_clip(clip.root_pos, clip.local_q, keys)
            checks = [c for c in checking.fill(root_in, q_in, keys).checks if c.interp > 0]
            if not checks:
                continue
            filled = plain.fill(root_in, q_in, keys)
            interp = interpolate_keyframes(root_in, q_in, keys)
            gt = sk.pose(root, q)[1]
            f_cm, f_n = position_error(sk.pose(filled.root, filled.local_q)[1], gt, gen)
            i_cm, _ = position_error(sk.pose(*interp)[1], gt, gen)
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
    args = ap.parse_args(argv)
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
    if args.json:
        Path(args.json).write_text(json.dumps({"per_split": report, "bias": {str(k): v for k, v in bias.items()},
                                               "rule": rule}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
