"""Where the fill's time goes: one 30-frame transition filled by the shipped fill (the ensemble, the self-check, the
feet locked, as ``predict`` fills), with two keys and with the ten frames before the gap keyed too, split into the
runtime's stages and, inside them, the networks.

    python benchmarks/fill_profile.py [--ckpt A.ckpt ...] [--repeats 20] [--write]

One thread, through ``Inbetweener.fill_arrays`` as the API and ``predict`` call it, with ``predict``'s default models
(the shipped ensemble's window graphs on ONNX Runtime; ``--ckpt`` takes ``.onnx`` or ``.ckpt`` files, the latter on
PyTorch eager).  Stages are timed by wrapping the runtime's own methods on this process's objects (nothing of the
package is changed): ``checks`` the self-check (:meth:`FillRuntime._weigh`: its hidden-key windows, scoring and the
weights), ``windows`` generating the gaps (:meth:`FillRuntime._generate`), ``feet`` foot locking
(:meth:`FillRuntime._feet`), ``other`` the rest (input checks, plan, the keys copied back); ``network`` is the time
inside the backends' ``predict`` (every member's forward pass, canonical windows in and out), counted in whichever
stage called it, and ``calls`` the members' forward passes per fill.  Medians over ``--repeats`` rounds after three
warm-ups; the machine should be quiet.  ``--write`` puts the table into BENCHMARKS.md's "## Where the fill's time goes".
"""
from __future__ import annotations

import argparse
import datetime as _dt
import os
import statistics
import sys
import time
from collections import defaultdict
from pathlib import Path

import _report  # noqa: E402  (benchmarks/ helper)
import numpy as np
import torch

from inbetweening.api.inbetweener import Inbetweener
from inbetweening.api.shipped import REPO, SHIPPED_ONNX
from inbetweening.runtime.fill import FillRuntime

SECTION = "## Where the fill's time goes"
GAP = 30
STAGES = ("checks", "windows", "feet")


def clip(joints: int, before: int, seed: int = 0):
    """``before`` context frames keyed one by one, then a ``GAP``-frame gap and its target key (unknown frames
    NaN): ``(root, local_q, keys)``."""
    rng = np.random.default_rng(seed)
    f = before + GAP + 1
    t = np.arange(f)[:, None]
    root = np.concatenate([3.0 * t, 90 + 2 * np.sin(t / 7.0), 0.5 * t], axis=1)
    q = np.cumsum(rng.normal(size=(f, joints, 4)) * 0.05, axis=0) + np.array([1.0, 0, 0, 0])
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    keys = list(range(before)) + [f - 1]
    root[before : f - 1], q[before : f - 1] = np.nan, np.nan
    return root, q, keys


class Clock:
    """Seconds spent in wrapped callables, by name; a name already running is not counted twice."""

    def __init__(self):
        self.spent, self.running = defaultdict(float), set()

    def wrap(self, obj, name: str, label: str) -> None:
        fn = getattr(obj, name)

        def timed(*a, **k):
            if label in self.running:
                return fn(*a, **k)
            self.running.add(label)
            t = time.perf_counter()
            try:
                return fn(*a, **k)
            finally:
                self.spent[label] += time.perf_counter() - t
                self.running.discard(label)

        setattr(obj, name, timed)


def profile(ib: Inbetweener, case, repeats: int) -> dict[str, float]:
    """Median milliseconds per stage of ``ib.fill_arrays(*case)`` over ``repeats`` rounds."""
    clock = Clock()
    runtime: FillRuntime = ib.runtime
    for stage, method in zip(STAGES, ("_weigh", "_generate", "_feet")):
        clock.wrap(runtime, method, stage)
    members = getattr(ib.backend, "members", [ib.backend])
    for m in members:
        clock.wrap(m, "predict", "network")
    calls = sum(m.calls for m in members)
    rows = defaultdict(list)
    with torch.inference_mode():
        for _ in range(3):
            ib.fill_arrays(*case)
        for _ in range(repeats):
            clock.spent.clear()
            t = time.perf_counter()
            ib.fill_arrays(*case)
            total = time.perf_counter() - t
            rows["total"].append(total)
            for stage in (*STAGES, "network"):
                rows[stage].append(clock.spent[stage])
            rows["other"].append(total - sum(clock.spent[s] for s in STAGES))
    out = {k: 1000 * statistics.median(v) for k, v in rows.items()}
    out["calls"] = (sum(m.calls for m in members) - calls) / (3 + repeats)
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ckpt", nargs="+", default=[str(REPO / p) for p in SHIPPED_ONNX],
                    help="models, .onnx or .ckpt (several: their ensemble); default the shipped fill's graphs")
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--write", action="store_true", help="rewrite BENCHMARKS.md's section")
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    load0 = os.getloadavg()[0]
    ib = Inbetweener.from_checkpoint(args.ckpt if len(args.ckpt) > 1 else args.ckpt[0], threads=1)
    j = ib.skeleton.num_joints
    cases = {"two keys": clip(j, 1), "ten more keys before": clip(j, 11)}
    results = {name: profile(ib, case, args.repeats) for name, case in cases.items()}
    load1 = os.getloadavg()[0]
    cols = ("total", "checks", "windows", "feet", "other", "network")
    lines = ["| case | " + " | ".join(f"{c} ms" for c in cols) + " | calls |", "|---|" + "---:|" * (len(cols) + 1)]
    for name, r in results.items():
        lines.append(f"| {name} | " + " | ".join(f"{r[c]:.1f}" for c in cols) + f" | {r['calls']:g} |")
    models = ", ".join(f"{Path(p).parent.name} ({Path(p).suffix[1:]})" for p in args.ckpt)
    text = (f"`python -m benchmarks run fill_profile {' '.join(sys.argv[1:] if argv is None else argv)}`".replace(" `", "`")
            + f" ({_dt.date.today()}, {models}, one thread, median of {args.repeats}; load average {load0:.1f} before, "
            f"{load1:.1f} after). One 30-frame transition through `Inbetweener.fill_arrays` with the fill's defaults; "
            "`network` is the time inside the backends (counted within the stage that called it).\n\n"
            + "\n".join(lines))
    _report.publish(text, SECTION, args.write)


if __name__ == "__main__":
    main()
