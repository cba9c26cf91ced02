"""What one window costs per size of the graph transformer: the sizes a distilled student (issue 54, ``experiment=distil
model.d_model=... model.depth=...``) could take, against the shipped members' (d_model 64, depth 6, 4 heads).

    python benchmarks/network_sizes.py [--sizes 64x6x4 48x3x2 ...] [--repeats 20] [--write]

Each size is a freshly initialised network (the time does not depend on the weights) put in place of the shipped
``bn2_partial``'s, run as the fill runs a member: ``Predictor.network_forward`` on one canonical window of 10 context
frames, a 30-frame transition and the target key (41 frames), PyTorch eager, one thread, inference mode.  Reported per
size: parameters, multiply-adds per window (GFLOP, PyTorch's counter: 2 per multiply-add) and its share of the shipped
ensemble's (three members), and the median CPU milliseconds over ``--repeats`` calls after a warm-up (CPU time, so a
shared machine changes it less than the wall time).  ``--write`` puts the table into BENCHMARKS.md's
"## Network size and window time".
"""
from __future__ import annotations

import argparse
import datetime as _dt
import os
import statistics
import sys
import time

import _report  # noqa: E402  (benchmarks/ helper)
import numpy as np
import torch
from torch.utils.flop_counter import FlopCounterMode

from inbetweening.api.shipped import REPO
from inbetweening.models.graph_transformer import GraphTransformer
from inbetweening.runtime.torch_backend import TorchBackend

SECTION = "## Network size and window time"
SHIPPED_SIZE = (64, 6, 4)
DEFAULT_SIZES = ("64x6x4", "64x4x4", "64x3x2", "48x4x2", "48x3x2", "32x4x4", "32x3x2")
MEMBERS = 3  # the shipped ensemble's


def size(text: str) -> tuple[int, int, int]:
    """``"48x3x2"`` -> (d_model, depth, heads)."""
    try:
        d, depth, heads = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: a size is d_model x depth x heads, e.g. 48x3x2") from None
    if min(d, depth, heads) < 1 or d % heads:
        raise argparse.ArgumentTypeError(f"{text!r}: positive numbers, heads dividing d_model")
    return d, depth, heads


def window(joints: int, seed: int = 0):
    """One 41-frame canonical window (10 context frames, 30 generated, the target key): features and mask."""
    rng = np.random.default_rng(seed)
    t = 41
    root = rng.normal(size=(1, t, 3)) * 20
    q = rng.normal(size=(1, t, joints, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    known = np.zeros((1, t, joints), bool)
    known[:, :10] = known[:, -1] = True
    return root, q, torch.as_tensor(known)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", nargs="+", type=size, default=[size(s) for s in DEFAULT_SIZES])
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--write", action="store_true", help="rewrite BENCHMARKS.md's section")
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    load0 = os.getloadavg()[0]
    predictor = TorchBackend.from_checkpoint(REPO / "models" / "bn2_partial" / "model.ckpt").predictor
    shipped_net = predictor.net
    joints = shipped_net.adjacency.shape[0]
    root, q, known = window(joints)
    rows = []
    for d, depth, heads in args.sizes:
        torch.manual_seed(0)
        predictor.net = GraphTransformer(num_joints=joints, adjacency=shipped_net.adjacency.tolist(), d_model=d,
                                         depth=depth, heads=heads, checkpoint_layers=False,
                                         max_frames=shipped_net.max_frames).eval()
        with torch.inference_mode():
            feats = predictor.encode(root, q)
            with FlopCounterMode(display=False) as counter:
                predictor.network_forward(feats, known, blend=False)
            times = []
            for i in range(args.repeats + 1):
                t = time.process_time()
                predictor.network_forward(feats, known, blend=False)
                if i:
                    times.append(time.process_time() - t)
        rows.append(((d, depth, heads), sum(p.numel() for p in predictor.net.parameters()),
                     counter.get_total_flops() / 1e9, 1000 * statistics.median(times)))
    load1 = os.getloadavg()[0]
    shipped = next((r for r in rows if r[0] == SHIPPED_SIZE), None)
    lines = ["| d_model × depth × heads | parameters | GFLOP per window | of the ensemble's | CPU ms per window |",
             "|---|---:|---:|---:|---:|"]
    for (d, depth, heads), params, gflop, ms in rows:
        share = f"{gflop / (MEMBERS * shipped[2]):.2f}" if shipped else "—"
        mark = " (a shipped member)" if (d, depth, heads) == SHIPPED_SIZE else ""
        lines.append(f"| {d} × {depth} × {heads}{mark} | {params / 1e3:.0f} k | {gflop:.3f} | {share} | {ms:.1f} |")
    cmd = "python -m benchmarks run network_sizes " + " ".join(sys.argv[1:] if argv is None else argv)
    text = (f"`{cmd.strip()}` ({_dt.date.today()}, one thread, median of {args.repeats}; load average {load0:.1f} "
            f"before, {load1:.1f} after). One 41-frame window (10 context frames, 30 generated, the target key) "
            "through `Predictor.network_forward`, a fresh network of each size in place of `bn2_partial`'s; GFLOP "
            "counts 2 per multiply-add.\n\n" + "\n".join(lines))
    _report.publish(text, SECTION, args.write)


if __name__ == "__main__":
    main()
