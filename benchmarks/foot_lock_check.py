"""Foot locking on or off with the fill's defaults (RESULTS.md section 5.3): the keyframes-only protocol on ``clips``
evenly spaced test clips of a split, K = 5/15/30/45, the ratio to interpolation, the share of clips worse than it by
more than 5 % and the foot skating, for a checkpoint (or an ensemble: checkpoints joined by commas) filled with
``foot_lock`` false, then true.

    python benchmarks/foot_lock_check.py <checkpoint>[,<checkpoint>...] <split> [--clips 60]
"""
from __future__ import annotations

import argparse
import json

import torch

from inbetweening.data.datasets import load_dataset
from inbetweening.predictor.checkpoint import load_predictor
from inbetweening.training.evaluate import animator_fill, score_keyframes

FIGURES = ("ratio", "worse_share", "skate_model", "skate_interp", "skate_gt")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("model", help="a checkpoint, or an ensemble: checkpoints joined by commas")
    ap.add_argument("split", help="the Bandai-Namco-2 split whose test clips are scored (standard, content, fold-1, ...)")
    ap.add_argument("--clips", type=int, default=60, help="test clips, evenly spaced")
    args = ap.parse_args()
    model, split, clips = args.model, args.split, args.clips
    torch.set_num_threads(1)
    data = load_dataset("bandai_namco", split=split)
    paths = model.split(",")
    predictor = load_predictor(paths[0], "cpu") if len(paths) == 1 else None
    for lock in (False, True):
        filled = predictor if predictor is not None else animator_fill(paths, foot_lock=lock)[0]
        res = score_keyframes(filled, data, [5, 15, 30, 45], 0, foot_lock=lock, max_clips=clips)
        rows = {k: {m: round(float(r[m]), 4) for m in FIGURES if m in r} for k, r in res.items()}
        print(f"foot_lock={lock}", json.dumps(rows), flush=True)


if __name__ == "__main__":
    main()
