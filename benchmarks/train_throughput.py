"""Training throughput (windows/s), FLOPs and share of the matmul rate of every model of the zoo on this CPU.

    python benchmarks/train_throughput.py [--models graph_transformer frame_transformer] [--variants fp32 bf16 compile]
        [--depths 6 12] [--set "" "model.checkpoint_layers=false"] [--steps 20] [--warmup 3] [--threads 2]
        [--write [--out BENCHMARKS.md]]

* models: ``--models`` (default: every trainable model of ``inbetweening.models.MODELS``), each with its
  ``conf/model/<name>.yaml`` defaults and the lerp mask; ``--depths`` also runs each depth of the models that have a
  ``depth`` setting (default: the config's depth only);
* variants: ``fp32`` (eager float32), ``bf16`` (``torch.autocast("cpu", dtype=torch.bfloat16)`` around forward + loss,
  as ``trainer.precision=bf16-mixed`` does; backward and optimiser outside it, weights float32) and ``compile``
  (the network's forward through ``torch.compile``, as ``compile=true`` does: :meth:`InbetweenModule.compile_network`;
  compiled during the warm-up steps, the first step's time is reported);
* data: the synthetic dataset through :class:`InbetweenDataModule` (cache in ``$INBETWEENING_CACHE`` or a temporary
  directory), batch size 32, transition length fixed at 30 frames, so every batch is ``gt (32, 41, 22, 7)``;
* throughput: full optimisation steps, ``zero_grad -> module.training_step(batch) (mask + network + L1 loss) ->
  backward -> AdamW step (+ LR scheduler step)``, driven by a plain loop: no Lightning ``Trainer``.  Batches are
  gathered before timing.  ``--warmup`` untimed steps, then the median over ``--steps`` timed steps;
* FLOPs: ``torch.utils.flop_counter.FlopCounterMode`` over one eager float32 training step's forward and over
  forward + backward, divided by the batch size (matrix products, the fused CPU attention kernel's included, which
  torch's own table lacks: ``SDPA_CPU_FLOPS``; element-wise work is not counted);
* reference: a 1024 x 1024 float32 ``torch.matmul`` on the same threads, sampled between the timed steps (so it sees
  the same load), and the achieved rate ``fwd+bwd FLOPs/window x windows/s`` as a share of it.

Prints a markdown table; with ``--write`` it also (re)writes the "## Training throughput and FLOPs" section of
``--out`` (default ``BENCHMARKS.md``; every other section is kept).
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
from torch.utils.flop_counter import FlopCounterMode, sdpa_backward_flop_count, sdpa_flop_count

from inbetweening.models import MODELS
from inbetweening.training.builders import make_datamodule, make_module

ROOT = Path(__file__).resolve().parents[1]
CONF_DIR = str(ROOT / "conf")
SECTION = "## Training throughput and FLOPs"
N_TRANS = 30
BATCH = 32
VARIANTS = ("fp32", "bf16", "compile")
TRAINABLE = [name for name, cls in MODELS.items() if cls.trainable]


def compose_cfg(model: str, depth: int | None, cache: str, out: str, extra: tuple[str, ...] = ()):
    """The training config as ``python train.py model=<model> [model.depth=<depth>] [extra ...]`` would compose it."""
    overrides = [
        f"model={model}", "mask=lerp", "optim=adamw", f"data.batch_size={BATCH}",
        f"data.transition_min={N_TRANS}", f"data.transition_max={N_TRANS}",
        *([f"model.depth={depth}"] if depth is not None else []), *extra,
    ]
    GlobalHydra.instance().clear()
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose("train", overrides=overrides)
    with open_dict(cfg):
        cfg.paths.output_dir = out
        cfg.paths.cache_dir = cache
        cfg.paths.log_dir = str(Path(out) / "logs")
    return cfg


def median_time(fn, repeats: int, warmup: int) -> tuple[float, list[float]]:
    for _ in range(warmup):
        fn()
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return statistics.median(ts), ts


def matmul_gflops(m: int, k: int, n: int, repeats: int, batch: int = 1) -> float:
    """Median GFLOP/s of a float32 ``(batch, m, k) @ (batch, k, n)`` product (``2 m k n`` FLOPs per item)."""
    g = torch.Generator().manual_seed(0)
    a = torch.randn(batch, m, k, generator=g).squeeze(0)
    b = torch.randn(batch, k, n, generator=g).squeeze(0)
    med, _ = median_time(lambda: torch.matmul(a, b), repeats, warmup=2)
    return 2.0 * batch * m * k * n / med / 1e9


def _sdpa_cpu(query, key, value, *args, out_shape=None, **kwargs) -> int:
    return sdpa_flop_count(query, key, value)


def _sdpa_cpu_backward(grad_out, query, key, value, *args, out_shape=None, **kwargs) -> int:
    return sdpa_backward_flop_count(grad_out, query, key, value)


# torch's FlopCounterMode counts the CUDA fused-attention kernels but not the CPU one that
# scaled_dot_product_attention dispatches to here: the same formulas (QKᵀ and PV products) for the CPU ops
SDPA_CPU_FLOPS = {
    torch.ops.aten._scaled_dot_product_flash_attention_for_cpu: _sdpa_cpu,
    torch.ops.aten._scaled_dot_product_flash_attention_for_cpu_backward: _sdpa_cpu_backward,
}


def count_flops(module, batch: dict) -> tuple[float, float, dict]:
    """FLOPs of one training step's forward, and of forward + backward, for the whole batch (matrix products,
    fused attention included)."""
    module.zero_grad(set_to_none=True)
    with FlopCounterMode(display=False, custom_mapping=SDPA_CPU_FLOPS) as fc:
        module.training_step(batch, 0)
    fwd = fc.get_total_flops()
    with FlopCounterMode(display=False, custom_mapping=SDPA_CPU_FLOPS) as fc:
        loss = module.training_step(batch, 0)
        loss.backward()
    both = fc.get_total_flops()
    ops = {str(op).split(".")[1] if str(op).startswith("aten.") else str(op): int(v)
           for op, v in fc.get_flop_counts().get("Global", {}).items()}
    module.zero_grad(set_to_none=True)
    return float(fwd), float(both), ops


# self-CPU-time groups of one profiled step
PROFILE_GROUPS = (
    ("matrix products (mm/addmm/bmm)", ("aten::mm", "aten::addmm", "aten::bmm", "aten::baddbmm", "aten::addbmm")),
    ("layout copies (copy_)", ("aten::copy_",)),
    ("fused attention (SDPA)", ("aten::_scaled_dot_product_flash_attention_for_cpu",
                                "aten::_scaled_dot_product_flash_attention_for_cpu_backward")),
    ("AdamW (_foreach_*)", ()),
)


def profile_step(step, batch: dict) -> list[tuple[str, float]]:
    """Share of self CPU time per op group in one training step (``torch.profiler``)."""
    from torch.profiler import ProfilerActivity, profile

    with profile(activities=[ProfilerActivity.CPU]) as prof:
        step(batch)
    self_us: dict[str, float] = {}
    for ev in prof.key_averages():
        self_us[ev.key] = self_us.get(ev.key, 0.0) + ev.self_cpu_time_total
    total = sum(self_us.values()) or 1.0
    out, used = [], set()
    for label, names in PROFILE_GROUPS:
        keys = [k for k in self_us if k in names or (not names and k.startswith("aten::_foreach_"))]
        used.update(keys)
        out.append((label, sum(self_us[k] for k in keys) / total))
    out.append(("other element-wise / reductions (mul, sum, add, softmax, norms, GELU, masks...)",
                sum(v for k, v in self_us.items() if k not in used) / total))
    return out


class MatmulReference:
    """The 1024 x 1024 float32 matmul, sampled between training steps so it sees the same machine load."""

    def __init__(self, n: int = 1024):
        g = torch.Generator().manual_seed(0)
        self.a, self.b = torch.randn(n, n, generator=g), torch.randn(n, n, generator=g)
        self.flops = 2.0 * n**3
        torch.matmul(self.a, self.b)

    def sample(self, repeats: int = 3) -> float:
        med, _ = median_time(lambda: torch.matmul(self.a, self.b), repeats, warmup=1)
        return self.flops / med / 1e9


def gather(model: str, depth: int | None, cache: str, n: int, extra: tuple[str, ...] = ()):
    """The composed config, the set-up data module and ``n`` full training batches."""
    with tempfile.TemporaryDirectory() as out:
        cfg = compose_cfg(model, depth, cache, out, extra)
        L.seed_everything(0, workers=True, verbose=False)
        dm = make_datamodule(cfg)
        dm.prepare_data()
        dm.setup("fit")
    batches: list[dict] = []
    while len(batches) < n:  # full batches only (drop a short last batch)
        batches += [b for b in dm.train_dataloader() if b["q"].shape[0] == BATCH]
    return cfg, dm, batches[:n]


def bench(cfg, dm, batches: list[dict], variant: str, steps: int, warmup: int, ref: MatmulReference,
          profile: bool, extra: tuple[str, ...] = ()) -> dict:
    """One (model, variant): a fresh module (same seed), FLOPs of an eager float32 step, then the timed steps."""
    L.seed_everything(0, workers=True, verbose=False)
    module = make_module(cfg, dm)
    module.train()
    shape = tuple(batches[0]["q"].shape)
    if shape[1] != module.n_past + N_TRANS + 1:
        raise RuntimeError(f"expected {module.n_past + N_TRANS + 1} frames per window, got batch shape {shape}")
    fwd, both, ops = count_flops(module, batches[0])
    module.compile_network(variant == "compile")
    opt_cfg = module.configure_optimizers()
    opt = opt_cfg["optimizer"] if isinstance(opt_cfg, dict) else opt_cfg
    sched = opt_cfg["lr_scheduler"]["scheduler"] if isinstance(opt_cfg, dict) else None

    def autocast():
        return torch.autocast("cpu", dtype=torch.bfloat16) if variant == "bf16" else contextlib.nullcontext()

    def step(batch: dict) -> None:
        opt.zero_grad(set_to_none=True)
        with autocast():
            loss = module.training_step(batch, 0)
        loss.backward()
        opt.step()
        if sched is not None:
            sched.step()

    first = None
    for b in batches[:warmup]:
        t = time.perf_counter()
        step(b)
        first = first if first is not None else time.perf_counter() - t
    ts, refs = [], [ref.sample()]
    for b in batches[warmup:warmup + steps]:
        t = time.perf_counter()
        step(b)
        ts.append(time.perf_counter() - t)
        refs.append(ref.sample())
    prof = profile_step(step, batches[warmup + steps]) if profile else None
    med = statistics.median(ts)
    module.compile_network(False)
    if variant == "compile":
        torch._dynamo.reset()  # the next model compiles from scratch
    return {
        "model": cfg.model.name, "depth": cfg.model.get("depth"), "variant": variant, "cfg": cfg.model,
        "extra": " ".join(extra),
        "params": sum(p.numel() for p in module.net.parameters() if p.requires_grad), "shape": shape,
        "n_windows": len(dm.clip_windows), "fwd": fwd / BATCH, "both": both / BATCH, "ops": ops, "first_s": first,
        "step_s": med, "step_min": min(ts), "step_max": max(ts), "wps": BATCH / med,
        "ref": statistics.median(refs), "ref_min": min(refs), "ref_max": max(refs), "profile": prof,
    }


def fmt_flops(x: float) -> str:
    return f"{x / 1e9:.2f} G" if x >= 1e9 else f"{x / 1e6:.0f} M"


def load() -> str:
    return ", ".join(f"{v:.2f}" for v in os.getloadavg())


def label(r: dict, with_depth: bool) -> str:
    name = f"{r['model']} (depth {r['depth']})" if with_depth and r["depth"] is not None else r["model"]
    return f"{name} `{r['extra']}`" if r.get("extra") else name


def table(results: list[dict], with_depth: bool) -> str:
    """The markdown table: one row per (model, depth, --set, variant); speed-up against the same model's (and depth's)
    first fp32 row, i.e. its default settings when ``--set`` lists ``""`` first."""
    base: dict = {}
    for r in results:
        if r["variant"] == "fp32":
            base.setdefault((r["model"], r["depth"]), r["wps"])
    lines = ["| model | variant | params | FLOPs/window fwd+bwd | first step (s) | median step (ms) | windows/s "
             "| vs fp32 | achieved GFLOP/s | matmul GFLOP/s | % of matmul |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in results:
        ach = r["both"] * r["wps"] / 1e9
        fp32 = base.get((r["model"], r["depth"]))
        first = f"{r['first_s']:.1f}" if r["first_s"] is not None else "-"
        speed = f"{r['wps'] / fp32:.2f}×" if fp32 else "-"
        lines.append(f"| {label(r, with_depth)} | {r['variant']} | {r['params']:,} | {fmt_flops(r['both'])} | {first} "
                     f"| {r['step_s'] * 1e3:,.0f} | {r['wps']:.2f} | {speed} "
                     f"| {ach:.1f} | {r['ref']:.0f} | {100 * ach / r['ref']:.1f}% |")
    return "\n".join(lines)


def shapes_line(results: list[dict], ref: MatmulReference, repeats: int) -> str:
    """The graph_transformer's own matrix shapes against the reference, measured back to back (if it was run)."""
    r = next((r for r in results if r["model"] == "graph_transformer"), None)
    if r is None:
        return ""
    b, t, j, _ = r["shape"]
    d, heads = int(r["cfg"].d_model), int(r["cfg"].heads)
    dh = d // heads
    big = ref.sample(repeats)
    lin = matmul_gflops(b * t * j, d, d, repeats)
    sp = matmul_gflops(j, dh, j, repeats, batch=b * t * heads)
    tp = matmul_gflops(t, dh, t, repeats, batch=b * j * heads)
    big = statistics.median([big, ref.sample(repeats)])
    return (f"Shapes of the graph_transformer, float32, measured back to back afterwards (1024 matmul then {big:.0f} "
            f"GFLOP/s): token linear ({b * t * j:,} x {d}) @ ({d} x {d}) {lin:.0f} GFLOP/s; spatial attention scores, "
            f"{b * t * heads:,} batched ({j} x {dh}) @ ({dh} x {j}) {sp:.1f} GFLOP/s; temporal, {b * j * heads:,} "
            f"batched ({t} x {dh}) @ ({dh} x {t}) {tp:.1f} GFLOP/s.")


def applies(model: str, overrides: str) -> bool:
    """Whether every ``model.<key>=`` of a ``--set`` group is a setting of ``model`` (other groups skip it)."""
    keys = [o.split("=", 1)[0].split(".", 1)[1] for o in overrides.split() if o.startswith("model.")]
    return all(k in MODELS[model].settings() for k in keys)


def run(args) -> tuple[list[dict], str, str, str]:
    torch.set_num_threads(args.threads)
    warnings.filterwarnings("ignore", message=".*self.log.*")
    warnings.filterwarnings("ignore", category=UserWarning, module="lightning")
    cache = os.environ.get("INBETWEENING_CACHE")
    tmp = None
    if not cache:
        tmp = tempfile.TemporaryDirectory()
        cache = tmp.name
    load_start = load()
    ref = MatmulReference()
    results = []
    for model in args.models:
        depths = args.depths if args.depths and "depth" in MODELS[model].settings() else [None]
        for depth, extra in [(d, tuple(e.split())) for d in depths for e in args.set if applies(model, e)]:
            cfg, dm, batches = gather(model, depth, cache, args.warmup + args.steps + 1, extra)
            for variant in args.variants:
                profile = not args.no_profile and not results
                r = bench(cfg, dm, batches, variant, args.steps, args.warmup, ref, profile, extra)
                print(f"{label(r, True)} {variant}: median step {r['step_s'] * 1e3:.0f} ms (min "
                      f"{r['step_min'] * 1e3:.0f}, max {r['step_max'] * 1e3:.0f}) -> {r['wps']:.2f} windows/s; "
                      f"matmul {r['ref']:.1f} GFLOP/s ({r['ref_min']:.1f}-{r['ref_max']:.1f}); load {load()}",
                      file=sys.stderr)
                results.append(r)
    shapes = shapes_line(results, ref, args.matmul_repeats)
    load_end = load()
    if tmp is not None:
        tmp.cleanup()
    return results, shapes, load_start, load_end


def report(args, results: list[dict], shapes: str, load_start: str, load_end: str, cmd: str) -> str:
    """The BENCHMARKS.md section: header, setup, table, reference and profile notes."""
    r0 = results[0]
    b, t, j, f = r0["shape"]
    header = (
        f"- Date: {_dt.date.today().isoformat()}\n"
        f"- Machine: 2-core CPU dev machine ({platform.processor() or platform.machine()}, shared with other work), "
        f"Python {platform.python_version()}, torch {torch.__version__}, {args.threads} torch threads\n"
        f"- Load average (1, 5, 15 min): {load_start} at the start, {load_end} at the end\n"
        f"- Command (from the repository root):\n\n```\n{cmd}\n```"
    )
    ops = r0["ops"]
    tot = sum(ops.values()) or 1
    op_share = ", ".join(f"{k} {100 * v / tot:.0f}%" for k, v in sorted(ops.items(), key=lambda kv: -kv[1]))
    setup = (
        f"Each model with its `conf/model/<name>.yaml` defaults and the lerp mask, synthetic dataset ({r0['n_windows']} "
        f"training windows), batch {b}, transition fixed at {N_TRANS} frames: `gt ({b}, {t}, {j}, {f})`.  A step is "
        f"`zero_grad -> module.training_step(batch)` (mask, network, L1 loss) `-> backward -> AdamW.step -> "
        f"scheduler.step` in a plain loop, without the Lightning `Trainer` (batches gathered first), so `trainer.fit` "
        f"is somewhat slower.  Variants: `fp32` eager; `bf16` = `torch.autocast(\"cpu\", dtype=torch.bfloat16)` around "
        f"forward + loss (what `trainer.precision=bf16-mixed` does; weights and optimiser float32); `compile` = the "
        f"network's forward through `torch.compile` (what `compile=true` does; compiled in the first warm-up step, "
        f"whose time is the \"first step\" column).  {args.warmup} warm-up steps, then the median of {args.steps} "
        f"steps.  FLOPs from `torch.utils.flop_counter.FlopCounterMode` over an eager float32 step (matrix products "
        f"and the fused attention's QKᵀ and PV products; element-wise work is not counted), per window = per batch / "
        f"{b}; fwd+bwd FLOPs by op of {label(r0, True)}: {op_share}.  Achieved GFLOP/s "
        f"= fwd+bwd FLOPs/window x windows/s, the same count for every variant."
    )
    spread = "; ".join(f"{label(r, True)} {r['variant']}: steps {r['step_min'] * 1e3:,.0f}-{r['step_max'] * 1e3:,.0f}"
                       f" ms, matmul {r['ref_min']:.0f}-{r['ref_max']:.0f}" for r in results)
    ref_line = (f"matmul GFLOP/s = 1024 x 1024 float32 `torch.matmul` on the same {args.threads} threads, sampled "
                f"(median of 3) before and after every timed step of that row, so it sees the same load; the column "
                f"is the median of those samples.  Ranges over the timed steps: {spread}.  {shapes}")
    prof = r0["profile"]
    prof_line = ""
    if prof:
        prof_line = (f"Where one step's time goes (`torch.profiler`, self CPU time, {label(r0, True)} {r0['variant']}): "
                     + "; ".join(f"{lab} {100 * share:.0f}%" if share >= 0.01 else f"{lab} <1%" for lab, share in prof)
                     + ".")
    with_depth = len({(r["model"], r["depth"]) for r in results}) > len({r["model"] for r in results})
    return "\n\n".join(p for p in (header, setup, table(results, with_depth), ref_line, prof_line) if p)


def write_section(path: Path, body: str, section: str = SECTION) -> None:
    """Add or replace this script's section (``--section``) of ``path``, keeping every other section."""
    _report.write_section(path, section, body)


def command(ap: argparse.ArgumentParser, args) -> str:
    """The command line that reproduces this run (options at their defaults left out)."""
    opts = []
    for k, v in vars(args).items():
        if k in ("write", "no_profile", "out") or v == ap.get_default(k):
            continue
        if k == "section":
            opts.append(f"--section {shlex.quote(v)}")
            continue
        opts.append(f"--{k.replace('_', '-')} {' '.join(shlex.quote(str(x)) for x in v) if isinstance(v, list) else v}")
    opts += [f for f, on in (("--no-profile", args.no_profile), ("--write", args.write)) if on]
    return " ".join(["python benchmarks/train_throughput.py", *opts])


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--models", nargs="+", default=TRAINABLE, choices=TRAINABLE, metavar="MODEL",
                    help=f"models of the registry (default: every trainable one: {' '.join(TRAINABLE)})")
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=VARIANTS)
    ap.add_argument("--depths", type=int, nargs="+", default=None,
                    help="also run these depths of the models with a depth setting (default: the config's)")
    ap.add_argument("--set", nargs="+", default=[""], metavar="OVERRIDES",
                    help='one group of rows per string of space-separated config overrides, e.g. --set "" '
                         '"model.checkpoint_layers=false" (default: the config as it is); a group naming a model.* '
                         'key that a model lacks skips that model')
    ap.add_argument("--steps", type=int, default=20, help="timed optimisation steps per row (median reported)")
    ap.add_argument("--warmup", type=int, default=3, help="untimed steps first (>= 1: compile happens there)")
    ap.add_argument("--threads", type=int, default=2, help="torch.set_num_threads")
    ap.add_argument("--matmul-repeats", type=int, default=20, help="repeats of the per-shape matmul measurements")
    ap.add_argument("--no-profile", action="store_true", help="skip the one profiled step (time breakdown)")
    ap.add_argument("--write", action="store_true", help="write the section of --out")
    ap.add_argument("--out", type=Path, default=ROOT / "BENCHMARKS.md", help="the file --write updates")
    ap.add_argument("--section", default=SECTION,
                    help=f"the heading --write adds or replaces (default {SECTION!r}; e.g. a subset of models)")
    args = ap.parse_args(argv)
    if args.steps < 1 or args.warmup < 1:
        ap.error("--steps and --warmup must be >= 1")

    results, shapes, load_start, load_end = run(args)
    text = report(args, results, shapes, load_start, load_end, command(ap, args))
    print(text)
    if args.write:
        write_section(args.out, text, args.section)
        print(f"\nwrote the '{args.section}' section of {args.out}")


if __name__ == "__main__":
    main()
