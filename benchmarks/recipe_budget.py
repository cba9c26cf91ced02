"""Optimiser steps that fit a wall-clock budget, per recipe of ``ablation=recipe`` (so the ablation's budget is equal
wall-clock time, yet every run has a step count its learning-rate schedule can follow and a resume reproduces).

    python benchmarks/recipe_budget.py [--minutes 10] [--threads 1] [--steps 40] [--recipes base dense ...]

Each recipe's training config (``ablation=recipe``'s settings, Bandai-Namco-2) is built as ``train.py`` builds it;
``--steps`` full optimisation steps are timed **including the batch's collation** (cutting windows from clips,
mirroring, masks): ``collate -> forward -> L1 loss -> backward -> AdamW``, after 5 warm-up steps, at ``--threads``
torch threads.  Prints the mean seconds per step (transition lengths are drawn per batch, so the mean is what a run
spends) and ``budget = minutes * 60 / step``.  Timings need a quiet
machine (or the same load for every recipe: they run back to back).
"""
from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

import lightning as L
import torch
from hydra import compose, initialize_config_dir
from hydra.core.global_hydra import GlobalHydra
from omegaconf import open_dict

from inbetweening.training.builders import make_datamodule, make_module

ROOT = Path(__file__).resolve().parents[1]
RECIPES = ("base", "task", "dense", "mirror", "last")


def compose_recipe(recipe: str, out: str, extra: list[str]):
    GlobalHydra.instance().clear()
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        cfg = compose("train", overrides=["ablation=recipe", f"+recipe={recipe}", *extra])
    with open_dict(cfg):
        cfg.paths.output_dir = out
    return cfg


def time_recipe(recipe: str, steps: int, extra: list[str]) -> float:
    with tempfile.TemporaryDirectory() as out:
        cfg = compose_recipe(recipe, out, extra)
        L.seed_everything(0, verbose=False)
        dm = make_datamodule(cfg)
        dm.prepare_data()
        dm.setup("fit")
        module = make_module(cfg, dm)
    module.train()
    opt = torch.optim.AdamW(module.parameters(), lr=1e-3)
    loader = dm.train_dataloader()
    sampler = loader.batch_sampler
    items = iter(sampler)
    ts = []
    for i in range(5 + steps):
        t = time.perf_counter()
        batch = dm.collate_train(next(items))
        opt.zero_grad(set_to_none=True)
        module.training_step(batch, i).backward()
        opt.step()
        if i >= 5:
            ts.append(time.perf_counter() - t)
    return statistics.fmean(ts)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--minutes", type=float, default=10.0)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--steps", type=int, default=40)
    p.add_argument("--recipes", nargs="*", default=list(RECIPES))
    p.add_argument("overrides", nargs="*", help="extra config overrides (e.g. model=frame_transformer)")
    a = p.parse_args()
    # `--recipes a b model=x` would swallow the override as a recipe name: anything with "=" is an override
    a.overrides += [r for r in a.recipes if "=" in r]
    a.recipes = [r for r in a.recipes if "=" not in r]
    torch.set_num_threads(a.threads)
    print(f"| recipe | s/step ({a.threads} thread) | steps in {a.minutes:g} min |\n|---|---:|---:|")
    for r in a.recipes:
        s = time_recipe(r, a.steps, a.overrides)
        print(f"| {r} | {s:.3f} | {int(a.minutes * 60 / s)} |", flush=True)
    print(f"load average {', '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
