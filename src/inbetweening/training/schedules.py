"""The optimiser and learning-rate schedule of a run, from the ``optim`` config (``conf/optim/*.yaml``).

``optim`` holds two Hydra partials, kept as plain dicts in the module's ``hparams``::

    optimizer: {_target_: torch.optim.AdamW, _partial_: true, lr: 1.0e-3, weight_decay: 1.0e-4, betas: [0.9, 0.999]}
    scheduler: {_target_: inbetweening.training.schedules.warmup_decay, _partial_: true,
                warmup_steps: 100, decay: cosine, min_lr_ratio: 0.05}      # or null: a constant learning rate

:func:`build_optimizers` instantiates them (only when training: inference never imports Hydra).  Checkpoints
made before this format carry ``optim: {name: adamw|adam|sgd, lr, ..., scheduler, warmup_steps, min_lr_ratio}``;
:func:`upgrade_optim` maps such a dict to the same optimiser and schedule in the new form.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Iterable

import torch

DECAYS = ("cosine", "linear", "constant")
SCHEDULE_TARGET = f"{__name__}.warmup_decay"
_OPTIMIZERS = {"adamw": "torch.optim.AdamW", "adam": "torch.optim.Adam", "sgd": "torch.optim.SGD"}


def lr_factor(step: int, total_steps: int, warmup_steps: int = 0, decay: str = "cosine",
              min_lr_ratio: float = 0.0) -> float:
    """Learning-rate multiplier at optimiser step ``step`` (0-based) of ``total_steps``: linear warm-up
    ``(step + 1) / warmup_steps``, then ``decay`` (``cosine`` | ``linear`` | ``constant``) from 1 down to
    ``min_lr_ratio`` at the last step (and held there)."""
    if warmup_steps and step < warmup_steps:
        return (step + 1) / warmup_steps
    if decay == "constant":
        return 1.0
    progress = min(1.0, (step - warmup_steps) / max(total_steps - warmup_steps, 1))
    if decay == "linear":
        return min_lr_ratio + (1 - min_lr_ratio) * (1 - progress)
    return min_lr_ratio + (1 - min_lr_ratio) * 0.5 * (1 + math.cos(math.pi * progress))


def warmup_decay(optimizer: torch.optim.Optimizer, total_steps: int, warmup_steps: int, decay: str,
                 min_lr_ratio: float) -> torch.optim.lr_scheduler.LambdaLR:
    """A per-step :class:`~torch.optim.lr_scheduler.LambdaLR` following :func:`lr_factor`."""
    if decay not in DECAYS:
        raise ValueError(f"optim.scheduler.decay: must be one of {list(DECAYS)}, got {decay!r}")
    total, warmup, floor = int(total_steps), int(warmup_steps), float(min_lr_ratio)
    return torch.optim.lr_scheduler.LambdaLR(optimizer, lambda step: lr_factor(step, total, warmup, decay, floor))


def upgrade_optim(optim: dict | None) -> dict:
    """``optim`` in the current form (``optimizer`` and ``scheduler`` partials); a dict of the old form
    (``name``, ``lr``, ``weight_decay``, ``betas`` | ``momentum``/``nesterov``, ``scheduler``, ``warmup_steps``,
    ``min_lr_ratio``, with that code's defaults for missing keys) becomes the same optimiser and schedule."""
    if optim is None:
        optim = {"name": "adamw", "lr": 1e-3}  # what a module built without ``optim`` always trained with
    if "optimizer" in optim or isinstance(optim.get("scheduler"), dict):
        return dict(optim)
    name = optim.get("name", "adamw")
    if name not in _OPTIMIZERS:
        raise ValueError(f"optim.name: unknown optimiser {name!r}; choose adam, adamw or sgd")
    opt = {"_target_": _OPTIMIZERS[name], "_partial_": True, "lr": float(optim.get("lr", 1e-3)),
           "weight_decay": float(optim.get("weight_decay", 0.0))}
    if name == "sgd":
        opt.update(momentum=float(optim.get("momentum", 0.9)), nesterov=bool(optim.get("nesterov", False)))
    else:
        opt["betas"] = [float(b) for b in optim.get("betas", (0.9, 0.999))]
    sched, warmup = optim.get("scheduler", "cosine"), int(optim.get("warmup_steps", 0))
    constant = sched in (None, "none", "constant")
    scheduler = None if constant and not warmup else {
        "_target_": SCHEDULE_TARGET, "_partial_": True, "warmup_steps": warmup,
        "decay": "constant" if constant else "linear" if sched == "linear" else "cosine",  # (any other: cosine)
        "min_lr_ratio": float(optim.get("min_lr_ratio", 0.0))}
    return {"optimizer": opt, "scheduler": scheduler, "freeze": [], "adapters": {"rank": 0, "alpha": None, "layers": ["*"]}}


def build_optimizers(optim: dict, params: Iterable[torch.nn.Parameter], total_steps: Callable[[], int]):
    """What ``LightningModule.configure_optimizers`` returns for ``optim`` (see :func:`upgrade_optim`):
    the optimiser alone, or with its per-step schedule; ``total_steps()`` is called only for a schedule."""
    from hydra.utils import instantiate

    optim = upgrade_optim(optim)
    opt = instantiate(optim["optimizer"], _convert_="all")(params)
    if optim.get("scheduler") is None:
        return opt
    scheduler = instantiate(optim["scheduler"], _convert_="all")(opt, total_steps=total_steps())
    return {"optimizer": opt, "lr_scheduler": {"scheduler": scheduler, "interval": "step", "name": "lr"}}

