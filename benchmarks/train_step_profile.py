"""Where a training step of the shipped model goes, and what the cheap levers buy (issue 36, item 3).

    python benchmarks/train_step_profile.py [--data bandai_namco|synthetic] [--steps 4] [--warmup 2] [--rounds 3]
        [--variants fp32 bf16 compile explicit bf16+explicit] [--profile-steps 3] [--set KEY=VALUE ...] [--write]

* config: ``python train.py experiment=bn2_best model.checkpoint_layers=false data=<--data>`` composed as
  ``train.py`` does (Hydra compose of ``conf/train.yaml``), built with
  :func:`~inbetweening.training.builders.make_datamodule` / :func:`~inbetweening.training.builders.make_module`;
  the optimiser and its LR schedule from ``configure_optimizers`` over the run's 3,600 steps;
* one torch thread (``torch.set_num_threads(1)``), seed 0, the same batches for every variant;
* phases of a step, timed with ``time.perf_counter``: ``collate`` (drawing the batch from the training loader:
  window gathering, task draw), ``encode`` (the predictor's canonical frame + FK features, part of forward),
  ``forward`` (``module.training_step``: encode, mask, network, loss), ``backward``, ``optimiser``
  (``step`` + scheduler + ``zero_grad``);
* operators: ``torch.profiler`` over ``--profile-steps`` steps of each ``--profile`` variant (default: the first),
  self CPU time per operator;
* FLOPs: ``FlopCounterMode`` (matrix products and the fused CPU attention, ``SDPA_CPU_FLOPS`` of
  ``train_throughput.py``) over the same batches; GFLOP/s in the matrix kernels = their FLOPs / their profiled self
  time; the reference peak is a 1024 x 1024 float32 matmul on the same thread;
* levers, interleaved A/B: ``--rounds`` rounds, each running every variant for ``--steps`` steps on the same batches
  (the order rotated every round); each variant trains its own copy of the same initial module, so the losses of the
  first round compare numerics step by step.  Variants: ``fp32`` (eager, the baseline), ``bf16`` (forward + loss under
  ``torch.autocast("cpu", bfloat16)``, as ``trainer.precision=bf16-mixed``), ``compile`` (``compile=true``:
  the network's forward through ``torch.compile``; its compile time is the first warm-up step's excess),
  ``explicit`` (``model.fused_attention=false``: the attention's explicit matmul-softmax-matmul path instead of the
  fused kernel, spatial and temporal); levers combine with ``+`` (``bf16+explicit``).
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
LEVERS = ("fp32", "bf16", "compile", "explicit")  # a variant: one of them, or several joined by "+"
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
        self.variant, levers = variant, set(variant.split("+"))
        if "explicit" in levers:  # model.fused_attention=false
            cfg = cfg.copy()
            with open_dict(cfg):
                cfg.model.fused_attention = False
        self.module = make_module(cfg, dm)
        self.module.train()
        self.module.compile_network("compile" in levers)
        self.bf16 = "bf16" in levers
        opt = build_optimizers(self.module.optim_cfg, [p for p in self.module.parameters() if p.requires_grad],
                               lambda: total_steps)
        self.opt, self.sched = (opt["optimizer"], opt["lr_scheduler"]["scheduler"]) if isinstance(opt, dict) \
            else (opt, None)
        self.times: dict[str, list[float]] = {p: [] for p in PHASES if p != "collate"}
        self.losses: list[float] = []

    def autocast(self):
        return torch.autocast("cpu", dtype=torch.bfloat16) if self.bf16 else contextlib.nullcontext()

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
        self.losses.append(float(loss.detach()))
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


def count_flops(runner: Runner, batches: list[dict]) -> dict[str, float]:
    """FLOPs of float32 training steps (forward + backward) on ``batches``, summed, per operator (``aten::<op>``)."""
    out: dict[str, float] = {}
    for batch in batches:
        with FlopCounterMode(display=False, custom_mapping=SDPA_CPU_FLOPS) as fc:
            runner.module.training_step(batch, 0).backward()
        runner.module.zero_grad(set_to_none=True)
        for op, v in fc.get_flop_counts().get("Global", {}).items():
            key = f"aten::{str(op).split('.')[1]}"
            out[key] = out.get(key, 0.0) + float(v)
    return out


def grad_diff(base: Runner, other: Runner, batch: dict) -> tuple[float, float]:
    """Numerics of one step: ``other`` takes ``base``'s weights; relative L2 difference of its loss and of its
    gradient (all parameters as one vector) against ``base``'s on ``batch``."""
    other.module.load_state_dict(base.module.state_dict())
    out = []
    for r in (base, other):
        r.opt.zero_grad(set_to_none=True)
        with r.autocast():
            loss = r.module.training_step(batch, 0)
        loss.backward()
        g = torch.cat([p.grad.flatten() for p in r.module.parameters() if p.grad is not None])
        out.append((float(loss.detach()), g))
        r.opt.zero_grad(set_to_none=True)
    (lb, gb), (lo, go) = out
    return abs(lo - lb) / abs(lb), float((go - gb).norm() / gb.norm())


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
    total = res["total_steps"] = int(cfg.trainer.max_steps)
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
            res["steps"][v].append(sum(ts) / len(ts))  # the mean over the same batches (their lengths differ)
            print(f"round {rnd + 1} {v}: {sum(ts) / len(ts) * 1e3:.0f} ms/step", file=sys.stderr)
        res["ref"].append(ref.sample())
    res["losses"] = {v: list(r.losses) for v, r in runners.items()}  # the same batches in the same order
    res["phases"] = {v: {p: med(ts) for p, ts in r.times.items()} for v, r in runners.items()}
    res["grad"] = {v: grad_diff(runners[order[0]], r, timed[0]) for v, r in runners.items()}
    res["flops_timed"] = sum(count_flops(runners[order[0]], timed).values()) / len(timed)
    res["profiled"] = args.profile or [order[0]]
    res["flops"] = {v: count_flops(runners[v], prof_b) for v in res["profiled"]}
    res["ops"], res["prof_wall"] = {}, {}
    for v in res["profiled"]:
        res["ops"][v], res["prof_wall"][v] = op_profile(runners[v], prof_b)
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


def profile_lines(args, res: dict, v: str, ref: float) -> list[str]:
    """The top-operator table and the matrix-product rates of profiled variant ``v``."""
    ops, fl, n = res["ops"][v], res["flops"][v], res["prof_steps"]
    kind, peak = ("bf16", res["bf16_ref"]) if "bf16" in v.split("+") else ("fp32", ref)
    tot = sum(ops.values()) or 1.0
    top = sorted(ops.items(), key=lambda kv: -kv[1])[:args.top]
    lines = ["", f"**Top operators by self CPU time, {v}** (`torch.profiler`, {n} steps, "
             f"{res['prof_wall'][v] / n * 1e3:,.0f} ms/step under the profiler):", "",
             "| operator | ms/step | share |", "|---|---:|---:|"]
    lines += [f"| `{k}` | {t / n * 1e3:,.1f} | {100 * t / tot:.1f}% |" for k, t in top]
    lines += ["", f"**Matrix products, {v}** (FLOPs counted on the same {n} batches with `FlopCounterMode`; "
              "`linear`, `matmul` and `einsum` dispatch to `mm/addmm/bmm`):", "",
              f"| kernels | share of self CPU | GFLOP/step | GFLOP/s | % of the 1024² {kind} matmul |",
              "|---|---:|---:|---:|---:|"]
    other = tot
    for name, keys in (("mm / addmm / bmm", MATMUL_OPS), ("fused attention (SDPA fwd + bwd)", ATTN_OPS)):
        secs, flops = sum(ops.get(k, 0.0) for k in keys), sum(fl.get(k, 0.0) for k in keys)
        other -= secs
        if secs:
            rate = flops / secs / 1e9
            lines.append(f"| {name} | {100 * secs / tot:.1f}% | {flops / n / 1e9:.1f} | {rate:.0f} | "
                         f"{100 * rate / peak:.0f}% |")
    lines.append(f"| everything else (element-wise, softmax, norms, copies, casts, FK, Adam) | {100 * other / tot:.1f}% "
                 f"| - | - | - |")
    return lines


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
        f"**Phases of a float32 step** (medians over {args.rounds} rounds x {args.steps} steps; the optimiser's "
        f"schedule is the run's {res['total_steps']:,} steps):",
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
    for v in res["profiled"]:
        lines += profile_lines(args, res, v, ref)
    step_f = res["flops_timed"]
    lines += ["", f"Whole step, {base}, the timed steps unprofiled: {step_f / 1e9:.1f} GFLOP/step (matrix products and "
              f"attention) in {step * 1e3:,.0f} ms = {step_f / step / 1e9:.0f} GFLOP/s, "
              f"{100 * step_f / step / 1e9 / ref:.0f}% of the 1024² float32 matmul.  Reference: 1024 x 1024 float32 "
              f"matmul, 1 thread, median {ref:.0f} GFLOP/s (range {min(res['ref']):.0f}-{max(res['ref']):.0f}, sampled "
              f"between rounds); bfloat16 {res['bf16_ref']:.0f} GFLOP/s."]
    lines += ["", f"**Levers, interleaved** ({args.rounds} rounds, each variant {args.steps} steps per round on the "
              f"same batches, order rotated; ratio = variant's step time / {base}'s in the same round):", "",
              "| variant | first step (s) | ms/step | forward | backward | optimiser | ratio median (min-max) "
              f"| loss after {args.warmup + args.rounds * args.steps} steps | max rel. loss diff "
              "| one step: rel. loss diff | one step: rel. gradient diff |",
              "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for v in args.variants:
        ratios = [a / c for a, c in zip(res["steps"][v], res["steps"][base])]
        p = res["phases"][v]
        lb, lv = res["losses"][base], res["losses"][v]
        diff = max(abs(x - y) / abs(y) for x, y in zip(lv, lb))
        lines.append(f"| {v} | {res['first_step'][v]:.1f} | {med(res['steps'][v]) * 1e3:,.0f} | {p['forward'] * 1e3:,.0f} "
                     f"| {p['backward'] * 1e3:,.0f} | {p['optimiser'] * 1e3:,.0f} | {med(ratios):.2f} "
                     f"({min(ratios):.2f}-{max(ratios):.2f}) | {lv[-1]:.5f} | {diff:.1e} | {res['grad'][v][0]:.1e} "
                     f"| {res['grad'][v][1]:.1e} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default="bandai_namco", choices=("bandai_namco", "synthetic"))
    ap.add_argument("--variants", nargs="+", default=["fp32", "bf16", "explicit", "bf16+explicit"],
                    help=f"levers {LEVERS}, or several joined by '+'; the first is the baseline of the ratios")
    ap.add_argument("--steps", type=int, default=4, help="timed steps per variant per round")
    ap.add_argument("--warmup", type=int, default=2, help="untimed steps per variant first (compile happens there)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--profile-steps", type=int, default=3)
    ap.add_argument("--profile", nargs="+", default=None, help="the variants profiled (default: the first)")
    ap.add_argument("--top", type=int, default=15, help="operators listed")
    ap.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE", help="more config overrides")
    ap.add_argument("--write", action="store_true", help="write the section of BENCHMARKS.md")
    args = ap.parse_args(argv)
    if any(lv not in LEVERS for v in args.variants for lv in v.split("+")):
        ap.error(f"--variants: levers are {LEVERS}, joined by '+'")
    if args.profile and not set(args.profile) <= set(args.variants):
        ap.error("--profile must be one of --variants")
    if min(args.steps, args.warmup, args.rounds, args.profile_steps) < 1:
        ap.error("--steps, --warmup, --rounds and --profile-steps must be >= 1")
    cmd = "python benchmarks/train_step_profile.py " + " ".join(shlex.quote(a) for a in (argv or sys.argv[1:])
                                                                 if a != "--write")
    res = run(args)
    _report.publish(report(args, res, cmd.strip()), SECTION, args.write)


if __name__ == "__main__":
    main()
