"""Configuration checks that run before any data is loaded: one clear line per problem."""
from __future__ import annotations

from omegaconf import DictConfig

from .benchmark import N_PAST
from .losses import LOSS_TERMS
from .masks import MASK_NAMES


class ConfigError(ValueError):
    """A configuration value is invalid; the message names the key."""


def _get(cfg, key: str, default=None):
    node = cfg
    for part in key.split("."):
        if node is None or part not in node:
            return default
        node = node[part]
    return node


def validate(cfg: DictConfig) -> None:
    """Raise :class:`ConfigError` naming the first invalid key."""
    mask = _get(cfg, "mask.name")
    if mask not in MASK_NAMES:
        raise ConfigError(f"mask.name: unknown mask {mask!r}; choose one of {list(MASK_NAMES)}")
    from .models import MODELS

    name = _get(cfg, "model.name")
    if name not in MODELS:
        raise ConfigError(f"model.name: unknown model {name!r}; choose one of {sorted(MODELS)}")
    depth = _get(cfg, "model.depth")
    if depth is not None and int(depth) < 1:
        raise ConfigError(f"model.depth: must be >= 1, got {depth}")
    heads, d_model = _get(cfg, "model.heads"), _get(cfg, "model.d_model")
    if heads is not None and d_model is not None and (int(heads) < 1 or int(d_model) % int(heads)):
        raise ConfigError(f"model.heads: {heads} must divide model.d_model={d_model}")
    for key in ("model.dropout",):
        v = _get(cfg, key)
        if v is not None and not 0.0 <= float(v) < 1.0:
            raise ConfigError(f"{key}: must be in [0, 1), got {v}")
    for key, allowed in (("model.norm", ("layer", "batch")), ("model.graph", ("multiply", "multiply_full", "none"))):
        v = _get(cfg, key)
        if v is not None and v not in allowed:
            raise ConfigError(f"{key}: must be one of {list(allowed)}, got {v!r}")
    lo, hi = _get(cfg, "data.transition_min"), _get(cfg, "data.transition_max")
    window = int(_get(cfg, "data.train_window", 50))
    if lo is not None and hi is not None:
        lo, hi = int(lo), int(hi)
        if lo < 1 or hi < lo:
            raise ConfigError(f"data.transition_min/max: need 1 <= min <= max, got {lo}..{hi}")
        if N_PAST + hi + 1 > window:
            raise ConfigError(
                f"data.transition_max: {hi} + {N_PAST} context + 1 target exceeds data.train_window={window}"
            )
        max_frames = _get(cfg, "model.max_frames")
        if max_frames is not None and window > int(max_frames) and mask == "joints":
            raise ConfigError(f"model.max_frames={max_frames} is shorter than data.train_window={window}")
    centre = _get(cfg, "centre", "known")
    if centre not in ("known", "window"):
        raise ConfigError(f"centre: must be 'known' or 'window', got {centre!r}")
    per = _get(cfg, "data.transition_per", "batch")
    if per not in ("batch", "sample"):
        raise ConfigError(f"data.transition_per: must be 'batch' or 'sample', got {per!r}")
    bs = _get(cfg, "data.batch_size")
    if bs is not None and int(bs) < 1:
        raise ConfigError(f"data.batch_size: must be >= 1, got {bs}")
    for k, v in (_get(cfg, "loss") or {}).items():
        if k not in LOSS_TERMS:
            raise ConfigError(f"loss.{k}: unknown loss term; known: {list(LOSS_TERMS)}")
        if float(v) < 0:
            raise ConfigError(f"loss.{k}: weight must be >= 0, got {v}")
    opt = _get(cfg, "optim.name")
    if opt is not None and opt not in ("adam", "adamw", "sgd"):
        raise ConfigError(f"optim.name: unknown optimiser {opt!r}; choose adam, adamw or sgd")
    lr = _get(cfg, "optim.lr")
    if lr is not None and float(lr) <= 0:
        raise ConfigError(f"optim.lr: must be > 0, got {lr}")
