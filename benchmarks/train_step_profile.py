"""Where a training step of the shipped model goes, and what the cheap levers buy (issue 36, item 3).

    python benchmarks/train_step_profile.py [--data bandai_namco|synthetic] [--steps 4] [--warmup 2] [--rounds 3]
        [--variants fp32 bf16 compile explicit] [--profile-steps 3] [--set KEY=VALUE ...] [--write]

* config: ``python train.py experiment=bn2_best model.checkpoint_layers=false data=<--data>`` composed as
  ``train.py`` does (Hydra compose of ``conf/train.yaml``), built with
  :func:`~inbetweening.training.builders.make_datamodule` / :func:`~inbetweening.training.builders.make_module`;
  the optimiser and its LR schedule from ``configure_optimizers`` over the run's 3,600 steps;
* one torch thread (``torch.set_num_threads(1)``), seed 0, the same batches for every variant;
* phases of a step, timed with ``time.perf_counter``: ``collate`` (drawing the batch from the training loader:
  window gathering, task draw), ``encode`` (the predictor's canonical frame + FK features, part of forward),
  ``forward`` (``module.training_step``: encode, mask, network, loss), ``backward``, ``optimiser``
  (``step`` + scheduler + ``zero_grad``);
* operators: ``torch.profiler`` over ``--profile-steps`` float32 steps, self CPU time per operator;
* FLOPs: ``FlopCounterMode`` (matrix products and the fused CPU attention, ``SDPA_CPU_FLOPS`` of
  ``train_throughput.py``) over one step; GFLOP/s in the matrix kernels = their FLOPs / their profiled self time;
  the reference peak is a 1024 x 1024 float32 matmul on the same thread;
* levers, interleaved A/B: ``--rounds`` rounds, each running every variant for ``--steps`` steps on the same batches
  (the order rotated every round); each variant trains its own copy of the same initial module, so the losses of the
  first round compare numerics step by step.  Variants: ``fp32`` (eager, the baseline), ``bf16`` (forward + loss under
  ``torch.autocast("cpu", bfloat16)``, as ``trainer.precision=bf16-mixed``), ``compile`` (``compile=true``:
  the network's forward through ``torch.compile``; its compile time is the first warm-up step's excess),
  ``explicit`` (the attention's explicit matmul-softmax-matmul path instead of the fused kernel).
"""
from __future__ import annotations

import argparse
import contextlib
import datetime as _dt
import os
import platform
import shlex
import statistics
import sys
import tempfile
import time
import warnings
from pathlib import Path

import _report
import lightning as L
import torch
from hydra import compose, initialize_config_dir
from hydra.core.global_hydra import GlobalHydra
from omegaconf import open_dict
from torch.profiler import ProfilerActivity, profile
from torch.utils.flop_counter import FlopCounterMode
from train_throughput import SDPA_CPU_FLOPS, MatmulReference

from inbetweening.training.builders import make_datamodule, make_module
from inbetweening.training.schedules import build_optimizers

ROOT = Path(__file__).resolve().parents[1]
SECTION = "## Training step: where the time goes"
VARIANTS = ("fp32", "bf16", "compile", "explicit")
PHASES = ("collate", "encode", "forward", "backward", "optimiser")
MATMUL_OPS = ("aten::mm", "aten::addmm", "aten::bmm", "aten::baddbmm", "aten::addbmm")
ATTN_OPS = ("aten::_scaled_dot_product_flash_attention_for_cpu",
            "aten::_scaled_dot_product_flash_attention_for_cpu_backward")


def compose_cfg(data: str, out: str, extra: list[str]):
    """The config of ``python train.py experiment=bn2_best model.checkpoint_layers=false data=<data> [extra]``."""
    overrides = ["experiment=bn2_best", "model.checkpoint_layers=false", f"data={data}", "threads=1", *extra]
    if data == "synthetic":  # the experiment's window, batch and gap lengths on the synthetic clips
        overrides += ["data.batch_size=32", "data.train_window=65"]
    GlobalHydra.instance().clear()
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        cfg = compose("train", overrides=overrides)
    with open_dict(cfg):
        cfg.paths.output_dir = out
        cfg.paths.log_dir = str(Path(out) / "logs")
    return cfg, overrides


def draw_batches(dm, n: int) -> tuple[list[dict], list[float]]:
    """``n`` training batches from the data module's training loader, and the seconds each took to draw."""
    batches, times = [], []
    while len(batches) < n:
        it = iter(dm.train_dataloader())
        while len(batches) < n:
            t = time.perf_counter()
            try:
                b = next(it)
            except StopIteration:
                break
            times.append(time.perf_counter() - t)
            batches.append(b)
    return batches, times


class Runner:
    """One variant: its own module (same seed, so the same initial weights), optimiser and schedule."""

    def __init__(self, cfg, dm, variant: str, total_steps: int):
        L.seed_everything(0, verbose=False)
        self.variant = variant
        self.module = make_module(cfg, dm)
        self.module.train()
        if variant == "explicit":
            self.module.net._fused = False
        self.module.compile_network(variant == "compile")
        opt = build_optimizers(self.module.optim_cfg, [p for p in self.module.parameters() if p.requires_grad],
                               lambda: total_steps)
        self.opt, self.sched = (opt["optimizer"], opt["lr_scheduler"]["scheduler"]) if isinstance(opt, dict) \
            else (opt, None)
        self.times: dict[str, list[float]] = {p: [] for p in PHASES if p != "collate"}
        self.losses: list[float] = []

    def autocast(self):
        return torch.autocast("cpu", dtype=torch.bfloat16) if self.variant == "bf16" else contextlib.nullcontext()

    def step(self, batch: dict, record: bool = True) -> float:
        t0 = time.perf_counter()
        with self.autocast():
            loss = self.module.training_step(batch, 0)
        t1 = time.perf_counter()
        loss.backward()
        t2 = time.perf_counter()
        self.opt.step()
        if self.sched is not None:
            self.sched.step()
        self.opt.zero_grad(set_to_none=True)
        t3 = time.perf_counter()
        if record:
            with torch.no_grad():  # the encode part of forward, timed apart (its inputs carry no gradient)
                te = time.perf_counter()
                self.module.predictor.canonical_features(batch["root"], batch["q"], batch["known"])
                self.times["encode"].append(time.perf_counter() - te)
            for p, dt in (("forward", t1 - t0), ("backward", t2 - t1), ("optimiser", t3 - t2)):
                self.times[p].append(dt)
        self.losses.append(float(loss))
        return t3 - t0


def op_profile(runner: Runner, batches: list[dict]) -> tuple[dict[str, float], float]:
    """Self CPU seconds per operator over the ``batches`` steps, and the profiled wall seconds."""
    with profile(activities=[ProfilerActivity.CPU]) as prof:
        t = time.perf_counter()
        for b in batches:
            runner.step(b, record=False)
        wall = time.perf_counter() - t
    self_s: dict[str, float] = {}
    for ev in prof.key_averages():
        self_s[ev.key] = self_s.get(ev.key, 0.0) + ev.self_cpu_time_total / 1e6
    return self_s, wall


def count_flops(runner: Runner, batch: dict) -> dict[str, float]:
    """FLOPs of one float32 training step (forward + backward) per operator (``aten::<op>`` keys)."""
    with FlopCounterMode(display=False, custom_mapping=SDPA_CPU_FLOPS) as fc:
        loss = runner.module.training_step(batch, 0)
        loss.backward()
    runner.module.zero_grad(set_to_none=True)
    return {f"aten::{str(op).split('.')[1]}": float(v) for op, v in fc.get_flop_counts().get("Global", {}).items()}


def med(xs: list[float]) -> float:
    return statistics.median(xs) if xs else float("nan")


def run(args) -> dict:
    torch.set_num_threads(1)
    warnings.filterwarnings("ignore", message=".*self.log.*")
    warnings.filterwarnings("ignore", category=UserWarning, module="lightning")
    res: dict = {"load_start": ", ".join(f"{v:.2f}" for v in os.getloadavg())}
    n_batches = args.warmup + args.steps + args.profile_steps
    with tempfile.TemporaryDirectory() as out:
        cfg, res["overrides"] = compose_cfg(args.data, out, args.set)
        L.seed_everything(0, verbose=False)
        dm = make_datamodule(cfg)
        dm.prepare_data()
        dm.setup("fit")
        draw_batches(dm, 1)  # the loader's first batch (sampler set-up) is not a step's
        batches, collate = draw_batches(dm, n_batches)
    res["collate"], res["shape"], res["windows"] = collate, tuple(batches[0]["q"].shape), len(dm.clip_windows)
    total = int(cfg.trainer.max_steps)
    ref = MatmulReference()
    res["ref"] = [ref.sample()]
    runners = {v: Runner(cfg, dm, v, total) for v in args.variants}
    warm, timed, prof_b = batches[:args.warmup], batches[args.warmup:args.warmup + args.steps], batches[-args.profile_steps:]
    res["first_step"] = {}
    for v, r in runners.items():
        t = time.perf_counter()
        r.step(warm[0], record=False)
        res["first_step"][v] = time.perf_counter() - t
        for b in warm[1:]:
            r.step(b, record=False)
        r.losses.clear()
    res["steps"] = {v: [] for v in runners}  # (round, step seconds) per variant
    order = list(runners)
    for rnd in range(args.rounds):
        for v in order[rnd % len(order):] + order[:rnd % len(order)]:
            ts = [runners[v].step(b) for b in timed]
            res["steps"][v].append(med(ts))
            print(f"round {rnd + 1} {v}: {med(ts) * 1e3:.0f} ms/step", file=sys.stderr)
        res["ref"].append(ref.sample())
    res["losses"] = {v: r.losses[:len(timed)] for v, r in runners.items()}
    res["phases"] = {v: {p: med(ts) for p, ts in r.times.items()} for v, r in runners.items()}
    res["flops"] = count_flops(runners[order[0]], timed[0])
    res["ops"], res["prof_wall"] = op_profile(runners[args.profile or order[0]], prof_b)
    res["prof_steps"] = len(prof_b)
    res["ref"].append(ref.sample())
    res["bf16_ref"] = bf16_matmul()
    res["load_end"] = ", ".join(f"{v:.2f}" for v in os.getloadavg())
    return res


def bf16_matmul(n: int = 1024, repeats: int = 5) -> float:
    """GFLOP/s of a 1024 x 1024 bfloat16 matmul on this thread (what the CPU's BF16 units give)."""
    a, b = torch.randn(n, n).bfloat16(), torch.randn(n, n).bfloat16()
    torch.matmul(a, b)
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        torch.matmul(a, b)
        ts.append(time.perf_counter() - t)
    return 2.0 * n**3 / min(ts) / 1e9


def report(args, res: dict, cmd: str) -> str:
    b, t, j, _ = res["shape"]
    base = args.variants[0]
    ph = res["phases"][base]
    col = med(res["collate"])
    step = med(res["steps"][base])
    ref = med(res["ref"])
    lines = [
        f"- Date: {_dt.date.today().isoformat()}; machine: 2-core CPU ({platform.machine()}, AVX512-BF16), **shared "
        f"with evaluation jobs while measured**; Python {platform.python_version()}, torch {torch.__version__}, "
        f"1 torch thread; load average {res['load_start']} at the start, {res['load_end']} at the end",
        f"- Config: `python train.py {' '.join(res['overrides'])}`, batch `q ({b}, {t}, {j}, 4)`, "
        f"{res['windows']:,} training windows",
        f"- Command:\n\n```\n{cmd}\n```",
        "",
        f"**Phases of a float32 step** (median over {args.rounds} rounds x {args.steps} steps; the optimiser's "
        f"schedule is the run's {3600} steps):",
        "",
        "| phase | ms | share of collate + step |",
        "|---|---:|---:|",
    ]
    whole = col + ph["forward"] + ph["backward"] + ph["optimiser"]
    rows = [("collate (draw the batch)", col), ("forward (training_step)", ph["forward"]),
            ("  of which encode (canonical frame + FK features)", ph["encode"]),
            ("backward", ph["backward"]), ("optimiser (AdamW + schedule + zero_grad)", ph["optimiser"])]
    lines += [f"| {name} | {s * 1e3:,.0f} | {100 * s / whole:.1f}% |" for name, s in rows]
    lines.append(f"| total | {whole * 1e3:,.0f} | 100% |")
    ops, wall = res["ops"], res["prof_wall"]
    tot = sum(ops.values()) or 1.0
    top = sorted(ops.items(), key=lambda kv: -kv[1])[:args.top]
    lines += ["", f"**Top operators by self CPU time** (`torch.profiler`, {res['prof_steps']} {args.profile or base} steps, "
              f"{wall / res['prof_steps'] * 1e3:,.0f} ms/step under the profiler):", "",
              "| operator | ms/step | share |", "|---|---:|---:|"]
    lines += [f"| `{k}` | {v / res['prof_steps'] * 1e3:,.1f} | {100 * v / tot:.1f}% |" for k, v in top]
    mm_s, at_s = sum(ops.get(k, 0.0) for k in MATMUL_OPS), sum(ops.get(k, 0.0) for k in ATTN_OPS)
    fl = res["flops"]
    mm_f, at_f, all_f = sum(fl.get(k, 0.0) for k in MATMUL_OPS), sum(fl.get(k, 0.0) for k in ATTN_OPS), sum(fl.values())
    n = res["prof_steps"]
    mm_rate = mm_f * n / mm_s / 1e9 if mm_s else float("nan")
    at_rate = at_f * n / at_s / 1e9 if at_s else float("nan")
    lines += ["", "**Matrix products and FLOPs** (one float32 step; `mm/addmm/bmm` are what `linear`, `matmul` and "
              "`einsum` dispatch to):", "",
              "| | share of self CPU | GFLOP/step | GFLOP/s | % of the 1024² fp32 matmul |", "|---|---:|---:|---:|---:|",
              f"| mm / addmm / bmm kernels | {100 * mm_s / tot:.1f}% | {mm_f / 1e9:.1f} | {mm_rate:.0f} "
              f"| {100 * mm_rate / ref:.0f}% |",
              f"| fused attention (SDPA fwd + bwd) | {100 * at_s / tot:.1f}% | {at_f / 1e9:.1f} | {at_rate:.0f} "
              f"| {100 * at_rate / ref:.0f}% |",
              f"| everything else (element-wise, norms, copies, FK, Adam) | {100 * (tot - mm_s - at_s) / tot:.1f}% | - "
              f"| - | - |",
              f"| whole step (unprofiled median {step * 1e3:,.0f} ms) | 100% | {all_f / 1e9:.1f} "
              f"| {all_f / step / 1e9:.0f} | {100 * all_f / step / 1e9 / ref:.0f}% |",
              "", f"Reference: 1024 x 1024 float32 matmul, 1 thread, median {ref:.0f} GFLOP/s (range "
              f"{min(res['ref']):.0f}-{max(res['ref']):.0f}, sampled between rounds); bfloat16 {res['bf16_ref']:.0f} "
              f"GFLOP/s.  FLOPs by op: " + ", ".join(f"`{k[6:]}` {v / 1e9:.2f} G" for k, v in
                                                     sorted(fl.items(), key=lambda kv: -kv[1])) + "."]
    lines += ["", f"**Levers, interleaved** ({args.rounds} rounds, each variant {args.steps} steps per round on the "
              f"same batches, order rotated; ratio = variant's step time / {base}'s in the same round):", "",
              "| variant | first step (s) | median ms/step | forward | backward | optimiser | ratio median (min-max) "
              f"| loss after {args.steps} steps | max rel. loss diff |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for v in args.variants:
        ratios = [a / c for a, c in zip(res["steps"][v], res["steps"][base])]
        p = res["phases"][v]
        lb, lv = res["losses"][base], res["losses"][v]
        diff = max(abs(x - y) / abs(y) for x, y in zip(lv, lb))
        lines.append(f"| {v} | {res['first_step'][v]:.1f} | {med(res['steps'][v]) * 1e3:,.0f} | {p['forward'] * 1e3:,.0f} "
                     f"| {p['backward'] * 1e3:,.0f} | {p['optimiser'] * 1e3:,.0f} | {med(ratios):.2f} "
                     f"({min(ratios):.2f}-{max(ratios):.2f}) | {lv[-1]:.5f} | {diff:.1e} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default="bandai_namco", choices=("bandai_namco", "synthetic"))
    ap.add_argument("--variants", nargs="+", default=["fp32", "bf16", "explicit"], choices=VARIANTS,
                    help="the first is the baseline of the ratios and the profiled one")
    ap.add_argument("--steps", type=int, default=4, help="timed steps per variant per round")
    ap.add_argument("--warmup", type=int, default=2, help="untimed steps per variant first (compile happens there)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--profile-steps", type=int, default=3)
    ap.add_argument("--profile", default=None, choices=VARIANTS, help="the variant profiled (default: the first)")
    ap.add_argument("--top", type=int, default=15, help="operators listed")
    ap.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE", help="more config overrides")
    ap.add_argument("--write", action="store_true", help="write the section of BENCHMARKS.md")
    args = ap.parse_args(argv)
    if args.profile and args.profile not in args.variants:
        ap.error("--profile must be one of --variants")
    if min(args.steps, args.warmup, args.rounds, args.profile_steps) < 1:
        ap.error("--steps, --warmup, --rounds and --profile-steps must be >= 1")
    cmd = "python benchmarks/train_step_profile.py " + " ".join(shlex.quote(a) for a in (argv or sys.argv[1:])
                                                                 if a != "--write")
    res = run(args)
    _report.publish(report(args, res, cmd.strip()), SECTION, args.write)


if __name__ == "__main__":
    main()
