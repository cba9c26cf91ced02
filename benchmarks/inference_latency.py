"""Inference latency and throughput of the default graph_transformer: PyTorch eager vs ONNX Runtime (CPU).

    python benchmarks/inference_latency.py [--repeats 50] [--batch 64] [--threads 1] [--no-write]

* latency: one 30-frame transition (batch 1, T = 10 context + 30 + 1 target = 41 frames), single-threaded
  (``torch.set_num_threads(1)``, ONNX Runtime ``intra_op_num_threads=1``); the network alone, plus the whole
  :meth:`Inbetweener.fill_arrays` path (window normalisation, FK features, mask, network, decoding);
* throughput: batches of 64 such windows, transitions per second (single-threaded by default: on the shared
  2-core dev machine 2-thread runs were dominated by contention with other jobs; try `--threads 1,2`).

The network is the default ``conf/model/graph_transformer.yaml`` (depth 6, d_model 64) with untrained weights
(timing does not depend on the weights) on the 22-joint synthetic skeleton.  Results are printed as a markdown
table and written as the "## Inference latency" section of ``BENCHMARKS.md`` (other sections are kept).
"""
from __future__ import annotations

import argparse
import datetime as _dt
import os
import platform
import statistics
import tempfile
import time
from pathlib import Path

import _report  # noqa: E402  (benchmarks/ helper; scripts run as python benchmarks/<name>.py)
import numpy as np
import torch
from omegaconf import OmegaConf

from inbetweening.data.synthetic import NAMES, OFFSETS, PARENTS, generate_clip
from inbetweening.geometry.skeleton import Skeleton
from inbetweening.tools.export import export_onnx, random_window
from inbetweening.tools.inbetweener import Inbetweener
from inbetweening.training.module import InbetweenModule

ROOT = Path(__file__).resolve().parents[1]
SECTION = "## Inference latency"
GAP = 30


def build_module() -> InbetweenModule:
    model = OmegaConf.to_container(OmegaConf.load(ROOT / "conf" / "model" / "graph_transformer.yaml"))
    skel = Skeleton(NAMES, PARENTS, OFFSETS)
    j = skel.num_joints
    return InbetweenModule(model=model, skeleton=skel.to_dict(), pos_mean=[0.0] * (3 * j), pos_std=[50.0] * (3 * j),
                           forward_axis=(0.0, 0.0, 1.0)).eval()


def timeit(fn, repeats: int, warmup: int = 3) -> list[float]:
    for _ in range(warmup):
        fn()
    out = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return out


def ort_session(path: Path, threads: int):
    import onnxruntime as ort

    opts = ort.SessionOptions()
    opts.intra_op_num_threads = threads
    opts.inter_op_num_threads = 1
    opts.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    return ort.InferenceSession(str(path), sess_options=opts, providers=["CPUExecutionProvider"])


def ort_feeds(session, x, known, interp) -> dict:
    feeds = {"x": x.numpy(), "known": known.numpy(), "interp": interp.numpy()}
    names = {i.name for i in session.get_inputs()}
    return {k: v for k, v in feeds.items() if k in names}


def run(repeats: int, batch: int, threads: list[int]) -> tuple[list[tuple], str]:
    module = build_module()
    net = module.net
    n_params = sum(p.numel() for p in net.parameters())
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "gt.onnx"
        info = export_onnx(module, path, check=True)
        for b, th in [(1, 1)] + [(batch, t) for t in threads]:
            torch.set_num_threads(th)
            session = ort_session(path, th)
            x, known, interp = random_window(module, b, GAP, seed=b)
            feeds = ort_feeds(session, x, known, interp)
            n_rep = repeats if b == 1 else max(repeats // 5, 5)
            with torch.inference_mode():
                t_torch = timeit(lambda x=x, known=known, interp=interp: net(x, known, interp), n_rep)
            t_ort = timeit(lambda session=session, feeds=feeds: session.run(None, feeds), n_rep)
            rows.append(("PyTorch eager", b, th, t_torch))
            rows.append(("ONNX Runtime", b, th, t_ort))
        # the whole animator path for one transition (PyTorch): Inbetweener.fill_arrays
        torch.set_num_threads(1)
        ib = Inbetweener(module, max_gap=GAP)
        q, root = generate_clip(np.random.default_rng(0), GAP + 2)
        rows.append(("Inbetweener.fill_arrays (PyTorch, end to end)", 1, 1,
                     timeit(lambda: ib.fill_arrays(root, q, [0, GAP + 1]), repeats)))
    lines = [
        "| path | batch | threads | median latency (ms) | p90 (ms) | transitions/s |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for name, b, th, ts in rows:
        med = statistics.median(ts)
        p90 = float(np.percentile(ts, 90))
        lines.append(f"| {name} | {b} | {th} | {med * 1e3:.2f} | {p90 * 1e3:.2f} | {b / med:,.0f} |")
    table = "\n".join(lines)
    per = {(name, b, th): statistics.median(ts) / b for name, b, th, ts in rows}
    batch_note = " ".join(
        f"{name}: {per[(name, batch, 1)] * 1e3:.1f} ms per transition at batch {batch} vs "
        f"{per[(name, 1, 1)] * 1e3:.1f} ms at batch 1 (1 thread)."
        for name in ("PyTorch eager", "ONNX Runtime") if (name, batch, 1) in per)
    note = (f"graph_transformer, default config (depth 6, d_model 64, heads 4; {n_params:,} parameters), 22 joints, "
            f"one {GAP}-frame transition = {module.n_past + GAP + 1}-frame window; ONNX opset 17 "
            f"(ORT vs PyTorch max abs diff {info['max_abs_diff']:.1e}).  {batch_note}")
    return rows, table + "\n\n" + note


def write_section(path: Path, body: str) -> None:
    """Add or replace this script's section of ``path``, keeping every other section."""
    _report.write_section(path, SECTION, body)


def cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=50, help="timed runs for batch 1 (batch runs: a fifth)")
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--threads", default="1", help="comma-separated thread counts for the batch throughput runs")
    ap.add_argument("--no-write", action="store_true", help="print only, leave BENCHMARKS.md alone")
    args = ap.parse_args()
    import onnxruntime

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    _, body = run(args.repeats, args.batch, [int(t) for t in args.threads.split(",")])
    cmd = "python benchmarks/inference_latency.py" + "".join(
        f" --{k} {v}" for k, v in (("repeats", args.repeats), ("batch", args.batch), ("threads", args.threads))
        if v != ap.get_default(k))
    header = (f"Command: `{cmd}` ({_dt.date.today().isoformat()}, 2-core CPU dev machine, "
              f"{cpu_name()}; torch {torch.__version__}, "
              f"onnxruntime {onnxruntime.__version__}).  Untrained weights: timing does not depend on them.  "
              f"The dev machine is shared (1-min load average {load:.1f} when started), so expect noise; medians of "
              "repeated runs.")
    text = header + "\n\n" + body
    print(text)
    if not args.no_write:
        write_section(ROOT / "BENCHMARKS.md", text)
        print(f"\nwrote the '{SECTION}' section of {ROOT / 'BENCHMARKS.md'}")


if __name__ == "__main__":
    main()
