"""Building a run's parts from its config: the data module, the LightningModule, the trainer (callbacks, loggers).

Every part is built from its own config group (``_target_`` + ``hydra.utils.instantiate``); what one part needs from
another at run time (the data's skeleton and statistics for the module) is asked of that part, never re-mapped here.
"""
from __future__ import annotations

from pathlib import Path

import lightning as L
from hydra.utils import instantiate
from omegaconf import DictConfig, OmegaConf

from inbetweening.predictor.checkpoint import predictor_state, some_layers
from inbetweening.predictor.predictor import upgrade_hparams
from inbetweening.training.callbacks import AtomicCheckpointIO, InterruptCheckpoint, NonFiniteGuard, ResumeState, TrimHeap
from inbetweening.training.datamodule import InbetweenDataModule
from inbetweening.training.module import InbetweenModule
from inbetweening.training.sampling import rank_world
from inbetweening.training.tb_logging import HParamsSession, TrainStats
from inbetweening.training.tb_runs import (
    curated_hparams,
    link_run,
    resumed_run,
    run_label,
    run_version,
    swept_keys,
    task_overrides,
    tensorboard_root,
)

__all__ = ["make_datamodule", "make_module", "make_trainer", "output_dir", "resume_command"]


def output_dir(cfg: DictConfig) -> Path:
    out = Path(cfg.paths.output_dir)
    out.mkdir(parents=True, exist_ok=True)
    return out


def _plain(node):
    return OmegaConf.to_container(node, resolve=True)


def make_datamodule(cfg: DictConfig) -> InbetweenDataModule:
    """``cfg.data``: ``_target_`` and the data module's arguments (the run's ``mask`` group and ``seed`` reach it by
    interpolation in ``conf/data/*.yaml``)."""
    return instantiate(cfg.data, _convert_="all")


def make_module(cfg: DictConfig, dm: InbetweenDataModule, init: dict | None = None) -> InbetweenModule:
    """The LightningModule from the ``model``, ``mask``, ``loss``, ``optim`` and ``teacher`` groups, ``centre``,
    ``representation``, and what the (set up) data module knows: skeleton, statistics, benchmark lengths.

    ``init``: a checkpoint (:func:`~inbetweening.predictor.checkpoint.read_checkpoint`) to start from
    (``init_from``): its network (``model``, ``representation``, ``centre``, ``mask``: the settings its weights belong
    to, whatever the config's groups say) with its weights; the normalisation statistics are the data's, estimated as
    for a new run, unless ``init_stats: checkpoint`` keeps the checkpoint's; the loss, optimiser and data come from
    the config; ``init_layers`` keeps some of its layers (:func:`~inbetweening.predictor.checkpoint.some_layers`)."""
    kw = dm.model_kwargs()
    teacher = _plain(cfg.teacher) if cfg.get("teacher") else None  # distillation (conf/teacher/)
    if init is None:
        return InbetweenModule(model=_plain(cfg.model), loss=_plain(cfg.loss), optim=_plain(cfg.optim),
                               centre=cfg.centre, representation=cfg.representation, mask=_plain(cfg.mask),
                               teacher=teacher, **kw)
    hp = upgrade_hparams(init["hyper_parameters"])
    network = {k: hp[k] for k in ("model", "representation", "centre", "mask", "joint_mask") if hp.get(k) is not None}
    state = predictor_state(init["state_dict"])
    if cfg.get("init_layers") is not None:  # a shallower network from some of its layers
        state, network["model"] = some_layers(state, dict(network["model"]), list(cfg.init_layers))
    if cfg.get("init_stats", "data") == "checkpoint":
        kw.update(pos_mean=list(hp["pos_mean"]), pos_std=list(hp["pos_std"]))
    module = InbetweenModule(loss=_plain(cfg.loss), optim=_plain(cfg.optim), teacher=teacher, **network, **kw)
    module.predictor.load_state_dict(state)
    return module


def make_logger(cfg: DictConfig, node: DictConfig):
    """A logger from its config.  A :class:`RunLogger` without a ``name`` writes under
    :func:`~inbetweening.training.tb_runs.tensorboard_root` (``save_dir: null``) to
    ``<label>/<start time>`` (:func:`~inbetweening.training.tb_runs.run_label`, ``run_version``), or continues
    the run a resumed fit was logging to; the run directory gets a ``tensorboard`` link to it."""
    if not str(node.get("_target_", "")).endswith("RunLogger") or node.get("name") is not None:
        return instantiate(node)
    run = resumed_run(cfg)
    if run is None:
        root = Path(node.get("save_dir") or tensorboard_root(cfg))
        label = run_label(cfg, task_overrides(), swept_keys())
        run = root / label / (node.get("version") or run_version(root, label))
    if rank_world()[0] == 0:
        link_run(cfg.paths.output_dir, run)
    return instantiate(node, save_dir=str(run.parent.parent), name=run.parent.name, version=run.name)


def enabled_nodes(group) -> list:
    """The nodes of a ``callbacks`` / ``logger`` group that build something: those with a ``_target_``.  A node
    without one holds an experiment's settings for a callback this run turned off (``experiment=... callbacks=none``:
    the experiment's ``callbacks.skeleton_figure.every_n_epochs`` alone), so there is nothing to build."""
    return [c for c in (group or {}).values() if isinstance(c, DictConfig) and "_target_" in c]


def make_trainer(cfg: DictConfig, callbacks=True, loggers=True) -> L.Trainer:
    cbs = [instantiate(c) for c in enabled_nodes(cfg.get("callbacks"))] if callbacks else []
    lgs = [make_logger(cfg, c) for c in enabled_nodes(cfg.get("logger"))] if loggers else []
    if not lgs:  # logger=none: callbacks that need a logger are dropped instead of failing
        cbs = [c for c in cbs if not isinstance(c, L.pytorch.callbacks.LearningRateMonitor)]
    elif callbacks:  # TensorBoard: throughput, epoch time, gradient norm; the HParams session from the fit's start
        swept = swept_keys()
        hp, shown = curated_hparams(cfg, task_overrides(), swept)
        cbs += [TrainStats(), HParamsSession(hp, shown, cfg.data.val_lengths, cfg.data.test_lengths,
                                             end_at_fit_end=not cfg.get("run_test", True))]
    if callbacks:  # always on while fitting: NaN stop, RNG state in checkpoints, a checkpoint at Ctrl-C / SIGTERM
        cbs += [NonFiniteGuard(), ResumeState(), TrimHeap(),  # freed heap returned when it has grown
                InterruptCheckpoint(str(Path(cfg.paths.output_dir) / "checkpoints"), resume_command(cfg))]
    return instantiate(cfg.trainer, callbacks=cbs, logger=lgs or False, plugins=[AtomicCheckpointIO()])


def resume_command(cfg: DictConfig) -> str:
    """The command line of this run (when launched through Hydra), for the printed resume hint."""
    try:
        from hydra.core.hydra_config import HydraConfig

        overrides = [o for o in HydraConfig.get().overrides.task if not o.startswith("ckpt_path=")]
        out = Path(cfg.paths.output_dir)
        return " ".join(["python", f"{cfg.get('task_name', 'train')}.py", *overrides, f"hydra.run.dir={out}"])
    except ValueError:  # not launched by Hydra (compose API, tests)
        return "python train.py <same overrides>"


