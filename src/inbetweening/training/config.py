"""Configuration checks that run before any data is loaded: one clear line per problem."""
from __future__ import annotations

import importlib
import inspect
import types
from pathlib import Path

from omegaconf import DictConfig

from inbetweening.data.specs import DATASETS, DEFAULT_SPLIT
from inbetweening.data.windows import N_PAST
from inbetweening.predictor.masks import MASK_NAMES
from inbetweening.predictor.predictor import CENTRES
from inbetweening.representation import DEFAULT_REPRESENTATION, REPRESENTATIONS
from inbetweening.training.losses import LOSS_TERMS, REDUCTIONS


class ConfigError(ValueError):
    """A configuration value is invalid; the message names the key."""


def _get(cfg, key: str, default=None):
    node = cfg
    for part in key.split("."):
        if node is None or part not in node:
            return default
        node = node[part]
    return node


POSITIVE_INT_KEYS = (*(f"data.{k}" for k in (
    "batch_size", "eval_batch_size", "train_window", "train_offset", "max_train_windows", "max_eval_windows",
    "max_val_windows",
)), "calibrate_windows")


def _check_model(cfg, name: str) -> None:
    """The chosen model's settings, checked by the model class itself: every ``model.*`` key must be one of its
    constructor settings (baselines accept any), and the values must pass its constructor's checks."""
    from omegaconf import OmegaConf

    from inbetweening.models import MODELS

    model = MODELS[name]
    node = _get(cfg, "model")
    settings = OmegaConf.to_container(node, resolve=True) if isinstance(node, DictConfig) else dict(node)
    settings.pop("name", None)
    if not model.accepts_any_setting():
        allowed = set(model.settings())
        for k in settings:
            if k not in allowed:
                raise ConfigError(f"model.{k}: not a setting of model {name!r} (perhaps set by an experiment= for "
                                  f"another model); its settings are {sorted(allowed)}")
    try:
        model.check_config(settings, prefix="model.")
    except ValueError as e:
        raise ConfigError(str(e)) from None


def locate(path: str):
    """The object a dotted ``path`` names (``torch.optim.AdamW``, ``package.module.function``), found the way
    ``hydra.utils.instantiate`` finds a ``_target_``: import the first name, then take each further name as an
    attribute, or, of a module that has no such attribute, import it as a submodule; ImportError when that fails
    (ValueError for a path with an empty name, ``a..b``).
    (``hydra.utils.get_object`` does the same but logs an error first; here a failure is the caller's one line.)"""
    parts = str(path).split(".")
    if not path:
        raise ImportError("empty path")
    if not all(parts):
        raise ValueError(f"{path!r} is not a dotted path (relative imports are not supported)")
    try:
        obj = importlib.import_module(parts[0])
    except Exception as e:  # noqa: BLE001 - whatever the import raised
        raise ImportError(f"cannot import {parts[0]!r}: {e!r}") from e
    for i, name in enumerate(parts[1:], start=2):
        try:
            obj = getattr(obj, name)
        except AttributeError as e:
            if not isinstance(obj, types.ModuleType):
                raise ImportError(f"{'.'.join(parts[:i - 1])!r} has no attribute {name!r}") from e
            try:
                obj = importlib.import_module(".".join(parts[:i]))
            except Exception as e2:  # noqa: BLE001 - whatever the import raised
                raise ImportError(f"cannot import {'.'.join(parts[:i])!r}: {e2!r}") from e2
    return obj


def _resolve(cfg, key: str):
    """The object ``<key>._target_`` names (:func:`locate`)."""
    target = _get(cfg, f"{key}._target_")
    if target is None:
        raise ConfigError(f"{key}._target_: missing")
    try:
        return locate(str(target))
    except Exception as e:  # noqa: BLE001 - whatever the import raised, the key is the message
        raise ConfigError(f"{key}._target_: cannot import {target!r} ({type(e).__name__})") from None


def _target_args(cfg, key: str, given_elsewhere: tuple[str, ...] = ()) -> None:
    """``<key>._target_`` must import, every other key of ``<key>`` must be one of its arguments (not one of
    ``given_elsewhere``, the arguments the code passes), and none of its required arguments may be missing."""
    node, target = _get(cfg, key), _get(cfg, f"{key}._target_")
    sig = inspect.signature(_resolve(cfg, key))
    params = {k: p for k, p in sig.parameters.items() if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)}
    allowed = set(params) - set(given_elsewhere)
    for k in node:
        if k not in allowed and k not in ("_target_", "_partial_"):
            raise ConfigError(f"{key}.{k}: not an argument of {target}; its settings are {sorted(allowed)}")
    for k in sorted(allowed - set(node)):
        if params[k].default is inspect.Parameter.empty:
            raise ConfigError(f"{key}.{k}: missing (a required argument of {target})")


def _check_adapters(node) -> None:
    if node is None:
        return
    if not hasattr(node, "keys"):
        raise ConfigError(f"optim.adapters: must be null or settings (rank, alpha, layers), got {node!r}")
    for k in node:
        if k not in ("rank", "alpha", "layers"):
            raise ConfigError(f"optim.adapters.{k}: not a setting of the adapters; set rank, alpha or layers")
    rank = node.get("rank")
    if isinstance(rank, bool) or not isinstance(rank, int) or rank < 0:
        raise ConfigError(f"optim.adapters.rank: must be an integer >= 0 (0: no adapters), got {rank!r}")
    alpha = node.get("alpha")
    if alpha is not None and (isinstance(alpha, bool) or not isinstance(alpha, (int, float)) or not alpha > 0):
        raise ConfigError(f"optim.adapters.alpha: must be a number > 0 (the change is scaled by alpha / rank), got {alpha!r}")
    layers = node.get("layers")
    if layers is not None and (isinstance(layers, str) or not all(isinstance(x, str) and x for x in layers)):
        raise ConfigError(f"optim.adapters.layers: must be a list of linear-layer name patterns (e.g. ['layers.*']), "
                          f"got {layers!r}")


def _check_optim(cfg) -> None:
    """``optim.optimizer``: a torch optimiser partial, ``lr > 0``; ``optim.scheduler``: null or a schedule partial
    (``warmup_steps >= 0``, ``decay``, ``min_lr_ratio`` in [0, 1]); ``optim.freeze``: a list of patterns (each is
    matched against the network when the module is built: :func:`~inbetweening.training.module.freeze`);
    ``optim.adapters``: null or ``rank`` (an integer >= 0), ``alpha`` (> 0) and ``layers`` (a list of patterns)."""
    import torch

    from inbetweening.training.schedules import DECAYS

    optim = _get(cfg, "optim")
    if optim is None:
        return
    for k in optim:
        if k not in ("optimizer", "scheduler", "freeze", "adapters"):
            raise ConfigError(f"optim.{k}: not a setting of optim; set optim.optimizer.* (e.g. optim.optimizer.lr), "
                              f"optim.scheduler.* (e.g. optim.scheduler.warmup_steps), optim.freeze or optim.adapters")
    _check_adapters(_get(cfg, "optim.adapters"))
    freeze = _get(cfg, "optim.freeze")
    if freeze is not None and (isinstance(freeze, str) or not all(isinstance(x, str) and x for x in freeze)):
        raise ConfigError(f"optim.freeze: must be a list of parameter-name patterns (e.g. ['layers.[0-2].*']), "
                          f"got {freeze!r}")
    cls = _resolve(cfg, "optim.optimizer")
    if not (isinstance(cls, type) and issubclass(cls, torch.optim.Optimizer)):
        raise ConfigError(f"optim.optimizer._target_: {_get(cfg, 'optim.optimizer._target_')} is not a torch optimiser "
                          "(a torch.optim.Optimizer)")
    _target_args(cfg, "optim.optimizer", ("params",))
    lr = _get(cfg, "optim.optimizer.lr")
    if lr is not None and float(lr) <= 0:
        raise ConfigError(f"optim.optimizer.lr: must be > 0, got {lr}")
    if _get(cfg, "optim.scheduler") is None:
        return
    _target_args(cfg, "optim.scheduler", ("optimizer", "total_steps"))
    decay, warmup, floor = (_get(cfg, f"optim.scheduler.{k}") for k in ("decay", "warmup_steps", "min_lr_ratio"))
    if decay is not None and decay not in DECAYS:
        raise ConfigError(f"optim.scheduler.decay: must be one of {list(DECAYS)}, got {decay!r}")
    if warmup is not None and (isinstance(warmup, bool) or not isinstance(warmup, int) or warmup < 0):
        raise ConfigError(f"optim.scheduler.warmup_steps: must be an integer >= 0, got {warmup!r}")
    if floor is not None and not 0.0 <= float(floor) <= 1.0:
        raise ConfigError(f"optim.scheduler.min_lr_ratio: must be in [0, 1], got {floor}")


def _check_data(cfg, mask) -> None:
    """The data module's arguments, numeric ranges of the data settings and what the windows need from the model."""
    if _get(cfg, "data") is not None:
        _target_args(cfg, "data", ())
    nw = _get(cfg, "data.num_workers")
    if nw is not None and (not isinstance(nw, int) or nw < 0):
        raise ConfigError(f"data.num_workers: must be an integer >= 0, got {nw!r}")
    vf = _get(cfg, "data.val_fraction")
    if vf is not None and not 0.0 <= float(vf) < 1.0:
        raise ConfigError(f"data.val_fraction: must be in [0, 1), got {vf}")
    for key in ("data.val_lengths", "data.test_lengths"):
        for n in _get(cfg, key) or []:
            if not isinstance(n, int) or not 1 <= n <= 45:
                raise ConfigError(f"{key}: lengths must be integers in 1..45 (65-frame benchmark windows), got {n!r}")
    name = _get(cfg, "data.name")
    split = _get(cfg, "data.split", DEFAULT_SPLIT)
    if name in DATASETS and (not isinstance(split, str) or split not in DATASETS[name].splits):
        raise ConfigError(f"data.split: dataset {name!r} has no split {split!r}; its splits are "
                          f"{DATASETS[name].split_names()}")
    syn = _get(cfg, "data.synthetic")
    if name == "synthetic":
        if _get(cfg, "data.path") is not None:
            raise ConfigError(f"data.path: data=synthetic generates its clips and reads no path (got "
                              f"{_get(cfg, 'data.path')!r}); remove it, or choose data=lafan1 or data=bandai_namco")
        syn = syn or {}
        clips, lo, hi = syn.get("num_clips", 40), syn.get("min_frames", 240), syn.get("max_frames", 360)
        if not isinstance(clips, int) or clips < 5:
            raise ConfigError(f"data.synthetic.num_clips: need at least 5 clips (clip i is subject i % 5 + 1 and "
                              f"subject5 is the test split), got {clips!r}")
        if not isinstance(lo, int) or not isinstance(hi, int) or not 66 <= lo <= hi:
            raise ConfigError(f"data.synthetic.min_frames/max_frames: need 66 <= min <= max (a 65-frame test window "
                              f"plus one), got {lo!r}..{hi!r}")
    max_frames = _get(cfg, "model.max_frames")
    if max_frames is not None:
        lengths = [int(_get(cfg, "data.transition_max", 30))]
        lengths += [int(n) for k in ("data.val_lengths", "data.test_lengths") for n in (_get(cfg, k) or [])]
        need = N_PAST + max(lengths) + 1
        if mask == "joints":
            need = max(need, int(_get(cfg, "data.train_window", 50)), 65)
        if need > int(max_frames):
            raise ConfigError(f"model.max_frames: {max_frames} is shorter than the {need}-frame windows this "
                              f"configuration feeds the network ({N_PAST} context + longest transition + target)")


PROTOCOLS = ("lafan", "keyframes")


def _check_protocol(cfg) -> None:
    """``protocol`` (eval.py): ``lafan`` or ``keyframes``; ``keyframe_intervals``: distinct schedules
    (:func:`check_schedules`)."""
    protocol = _get(cfg, "protocol")
    if protocol is not None and protocol not in PROTOCOLS:
        raise ConfigError(f"protocol: must be one of {list(PROTOCOLS)}, got {protocol!r}")
    ks = _get(cfg, "keyframe_intervals")
    if ks is not None:
        check_schedules("keyframe_intervals", ks, allow_empty=False)


def check_schedules(key: str, ks, allow_empty: bool) -> None:
    """Keyframes-protocol schedules: distinct entries, each one :func:`inbetweening.evaluation.schedules.
    check_schedule` accepts (an interval ``K >= 2``, a key every ``K`` frames, or a keypose schedule's name)."""
    from inbetweening.evaluation.schedules import MIN_INTERVAL, SCHEDULES, check_schedule

    if isinstance(ks, (str, bytes)) or not hasattr(ks, "__len__") or (len(ks) == 0 and not allow_empty):
        raise ConfigError(f"{key}: must be a non-empty list of intervals >= {MIN_INTERVAL} and schedules "
                          f"{list(SCHEDULES)} (e.g. [5, 15, 30, 45, random, extremes]), got {ks!r}")
    for k in ks:
        try:
            check_schedule(k)
        except ValueError as e:
            raise ConfigError(f"{key}: {e}") from None
    if len(set(ks)) != len(ks):
        raise ConfigError(f"{key}: an interval is listed twice in {list(ks)}")


def _precisions() -> list[str]:
    """The ``trainer.precision`` values Lightning accepts (``32-true``, ``bf16-mixed``, ... and their aliases)."""
    from typing import get_args

    from lightning.fabric.plugins.precision import precision as P

    return list(dict.fromkeys(str(v) for lit in get_args(P._PRECISION_INPUT) for v in get_args(lit)))


def _check_train_extras(cfg) -> None:
    """``threads`` (>= 1 or null), ``compile`` (true/false) and ``test_keyframes`` (train.py: schedules)."""
    compile_ = _get(cfg, "compile", False)
    if not isinstance(compile_, bool):
        raise ConfigError(f"compile: must be true or false, got {compile_!r}")
    precision = _get(cfg, "trainer.precision")
    if precision is not None and str(precision) not in _precisions():
        raise ConfigError(f"trainer.precision: must be one of {_precisions()}, got {precision!r}")
    threads = _get(cfg, "threads")
    if threads is not None and (isinstance(threads, bool) or not isinstance(threads, int) or threads < 1):
        raise ConfigError(f"threads: must be an integer >= 1 or null, got {threads!r}")
    check_schedules("test_keyframes", list(_get(cfg, "test_keyframes") or []), allow_empty=True)
    _check_teacher(cfg)


def _check_teacher(cfg) -> None:
    """``teacher`` (distillation): existing checkpoint files and a positive weight; the skeleton is checked against
    the data's when fitting starts."""
    node = _get(cfg, "teacher")
    if not node:
        return
    check_teacher_settings(_get(cfg, "teacher.checkpoints"), _get(cfg, "teacher.weight", 1.0))


def check_teacher_settings(checkpoints, weight) -> list[str]:
    """The ``teacher`` group's values checked before any work (:class:`ConfigError` naming the key): existing
    checkpoint files (one path or a list; returned as a list) and a positive weight."""
    paths = [checkpoints] if isinstance(checkpoints, str) else [str(p) for p in (checkpoints or [])]
    if not paths:
        raise ConfigError("teacher.checkpoints: give at least one checkpoint")
    for p in paths:
        if not Path(p).is_file():
            raise ConfigError(f"teacher.checkpoints: no checkpoint file {p}")
    if isinstance(weight, bool) or not isinstance(weight, (int, float)) or not weight > 0:
        raise ConfigError(f"teacher.weight: must be a positive number, got {weight!r}")
    return paths


def fill_settings(cfg: DictConfig):
    """The fill's tuned numbers of a config (``fill``, ``conf/fill/default.yaml``: ``_target_`` a
    :class:`~inbetweening.runtime.settings.FillSettings`, instantiated); the defaults where it has no ``fill``.  A bad
    value or an unknown name is a :class:`ConfigError` naming its key."""
    from hydra.errors import InstantiationException
    from hydra.utils import instantiate

    from inbetweening.runtime.model import InbetweenError
    from inbetweening.runtime.settings import DEFAULT_SETTINGS, FillSettings

    node = _get(cfg, "fill")
    if node is None:
        return DEFAULT_SETTINGS
    try:
        settings = instantiate(node)
    except InstantiationException as e:  # Hydra wraps what the constructor raised
        if isinstance(e.__cause__, InbetweenError):
            raise ConfigError(str(e.__cause__)) from None
        raise ConfigError(f"fill: {' '.join(str(e).split())}") from None
    if not isinstance(settings, FillSettings):
        raise ConfigError(f"fill._target_: must be inbetweening.runtime.settings.FillSettings, got {type(settings)}")
    return settings


def validate(cfg: DictConfig) -> None:
    """Raise :class:`ConfigError` naming the first invalid key."""
    fill_settings(cfg)
    mask = _get(cfg, "mask.name")
    if mask not in MASK_NAMES:
        raise ConfigError(f"mask.name: unknown mask {mask!r}; choose one of {list(MASK_NAMES)}")
    from inbetweening.models import MODELS, RETARGETERS

    name = _get(cfg, "model.name")
    if name not in MODELS:
        hint = " (a retargeting network: use it with task=retarget)" if name in RETARGETERS else ""
        raise ConfigError(f"model.name: unknown model {name!r}{hint}; choose one of {sorted(MODELS)}")
    _check_model(cfg, name)
    for key in POSITIVE_INT_KEYS:
        v = _get(cfg, key)
        if v is not None and (isinstance(v, bool) or not isinstance(v, int) or v < 1):
            raise ConfigError(f"{key}: must be an integer >= 1, got {v!r}")
    _check_data(cfg, mask)
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
    _check_task(cfg)
    _check_train_extras(cfg)
    centre = _get(cfg, "centre", "known")
    if centre not in CENTRES:
        raise ConfigError(f"centre: must be one of {list(CENTRES)}, got {centre!r}")
    if _get(cfg, "init_from") and _get(cfg, "ckpt_path"):
        raise ConfigError("init_from: starts a new run from a checkpoint's weights, ckpt_path resumes a run: give one")
    if _get(cfg, "init_stats", "data") not in ("checkpoint", "data"):
        raise ConfigError(f"init_stats: must be 'checkpoint' or 'data', got {_get(cfg, 'init_stats')!r}")
    keep = _get(cfg, "init_keep", 0.0)
    if isinstance(keep, bool) or not isinstance(keep, (int, float)) or not 0.0 <= keep <= 1.0:
        raise ConfigError(f"init_keep: must be a number from 0 to 1 (the share of init_from's weights kept), got {keep!r}")
    if keep > 0 and not _get(cfg, "init_from"):
        raise ConfigError("init_keep: mixes the trained weights with init_from's: give init_from")
    if keep > 0 and _get(cfg, "init_stats", "data") != "checkpoint":
        raise ConfigError("init_keep: the weights of two networks mix only under the same normalisation statistics: "
                          "set init_stats=checkpoint")
    layers = _get(cfg, "init_layers")
    if layers is not None:
        if not _get(cfg, "init_from"):
            raise ConfigError("init_layers: takes layers of init_from's network: give init_from")
        if (isinstance(layers, (str, bytes)) or not hasattr(layers, "__len__") or not len(layers)
                or any(isinstance(i, bool) or not isinstance(i, int) or i < 0 for i in layers)
                or len(set(layers)) != len(layers)):
            raise ConfigError(f"init_layers: must be a list of distinct layer numbers of init_from's network (0 = its "
                              f"first), e.g. [0,2,4], got {layers!r}")
    rep = _get(cfg, "representation", DEFAULT_REPRESENTATION)
    if rep not in REPRESENTATIONS:
        raise ConfigError(f"representation: unknown representation {rep!r}; choose one of {sorted(REPRESENTATIONS)}")
    per = _get(cfg, "data.transition_per", "batch")
    if per not in ("batch", "sample"):
        raise ConfigError(f"data.transition_per: must be 'batch' or 'sample', got {per!r}")
    for k, v in (_get(cfg, "loss") or {}).items():
        if k == "reduce":
            if v not in REDUCTIONS:
                raise ConfigError(f"loss.reduce: must be one of {list(REDUCTIONS)}, got {v!r}")
            continue
        if k not in LOSS_TERMS:
            raise ConfigError(f"loss.{k}: unknown loss term; known: {list(LOSS_TERMS)}")
        if float(v) < 0:
            raise ConfigError(f"loss.{k}: weight must be >= 0, got {v}")
    if not isinstance(_get(cfg, "calibrate", True), bool):
        raise ConfigError(f"calibrate: must be true or false, got {_get(cfg, 'calibrate')!r}")
    _check_optim(cfg)
    _check_protocol(cfg)


def _check_task(cfg: DictConfig) -> None:
    """The training task's options: context range, intermediate keyframes, time warp, other rigs' takes."""
    cmin, cmax = int(_get(cfg, "data.context_min", N_PAST)), int(_get(cfg, "data.context_max", N_PAST))
    if not 1 <= cmin <= cmax <= N_PAST:
        raise ConfigError(f"data.context_min/max: need 1 <= min <= max <= {N_PAST}, got {cmin}..{cmax}")
    if int(_get(cfg, "data.keyframes_max", 0)) < 0:
        raise ConfigError(f"data.keyframes_max: must be >= 0, got {_get(cfg, 'data.keyframes_max')}")
    prob = float(_get(cfg, "data.keyframe_prob", 0.0))
    if not 0.0 <= prob <= 1.0:
        raise ConfigError(f"data.keyframe_prob: must be in [0, 1], got {prob}")
    partial = float(_get(cfg, "data.partial_prob", 0.0))
    if not 0.0 <= partial <= 1.0:
        raise ConfigError(f"data.partial_prob: must be in [0, 1], got {partial}")
    repeat = _get(cfg, "data.extra_repeat", 1)
    if not (isinstance(repeat, int) and not isinstance(repeat, bool) and repeat >= 1):
        raise ConfigError(f"data.extra_repeat: must be an integer >= 1, got {repeat!r}")
    if not isinstance(_get(cfg, "data.speed_vary", False), bool):
        raise ConfigError(f"data.speed_vary: must be true or false, got {_get(cfg, 'data.speed_vary')!r}")
    mix = _get(cfg, "data.mix_parts", False)
    if not (isinstance(mix, bool) or mix in ("upper", "limbs")):
        raise ConfigError(f"data.mix_parts: must be false, true (the upper body), upper or limbs, got {mix!r}")
    speed = _get(cfg, "data.speed", None)
    if speed is not None:
        try:
            lo, hi = (float(v) for v in speed)
        except (TypeError, ValueError):
            raise ConfigError(f"data.speed: must be null or [lo, hi] with 0.25 <= lo <= hi <= 4, got {speed!r}") from None
        if not 0.25 <= lo <= hi <= 4.0:
            raise ConfigError(f"data.speed: need 0.25 <= lo <= hi <= 4 (play-back speeds), got {[lo, hi]}")
