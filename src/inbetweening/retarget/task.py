"""``task=retarget``: the jobs behind ``python train.py task=retarget ...`` (:func:`train_retarget`) and
``python eval.py task=retarget ckpt_path=...`` (:func:`eval_retarget`).

Source clips come from the ``data`` group (its skeleton is the source, e.g. Bandai-Namco-2's); each is paired with its
analytic retarget onto ``target_rig`` (a BVH file whose hierarchy is the target; its first frame is the reference
pose); ``retarget.contents`` selects the clips (the seed's walking and running), ``retarget.train_fraction`` of them
train (a stable hash of the name), the rest are held out.  After fitting, the held-out clips of the selection and of
all contents are scored (:mod:`.evaluate`); ``retarget.json`` and ``retarget.png`` go into the run directory, the
scalars and the figure into TensorBoard.
"""
from __future__ import annotations

import json
from pathlib import Path

import lightning as L
from hydra.utils import instantiate
from omegaconf import DictConfig, OmegaConf

from inbetweening.atomic import write_text
from inbetweening.data.bvh import BVH, read_bvh
from inbetweening.data.bvh_writer import format_bvh
from inbetweening.predictor.checkpoint import CheckpointError
from inbetweening.runtime.model import InbetweenError
from inbetweening.training.builders import enabled_nodes, make_datamodule, make_logger, output_dir
from inbetweening.training.callbacks import AtomicCheckpointIO, NonFiniteGuard
from inbetweening.training.config import ConfigError
from inbetweening.training.job import use_threads

from .data import make_pairs, select, split_clips, stats, window_loader
from .evaluate import clip_figure, format_table, score_sets
from .learned import LearnedRetarget, check_target
from .module import RetargetModule
from .rig import TargetRig

__all__ = ["eval_retarget", "is_retarget", "train_retarget"]


def is_retarget(cfg: DictConfig) -> bool:
    return cfg.get("task") == "retarget"


def _rig_file(cfg: DictConfig) -> BVH | None:
    path = cfg.get("target_rig")
    if not path:
        return None
    if not Path(path).is_file():
        raise ConfigError(f"target_rig: {path} is not a file (a BVH file whose hierarchy is the target)")
    return read_bvh(path)


def _sets(cfg: DictConfig, data, contents, fraction: float) -> tuple[list, dict]:
    """``(training clips, {held-out set name: clips})``: the selection's split and all contents' held-out clips."""
    clips = sorted(data.train + data.test, key=lambda c: c.name)
    train, test = split_clips(select(clips, contents), fraction)
    sets = {"+".join(contents) if contents else "all": test}
    if contents:
        sets["all"] = split_clips(clips, fraction)[1]
    return train, sets


def _trainer(cfg: DictConfig) -> L.Trainer:
    """The ``trainer`` group with the ``callbacks`` and ``logger`` groups (the in-betweening figure callback left
    out, the checkpoint callback keeping the last weights: the task has no validation split)."""
    cbs = []
    for node in enabled_nodes(cfg.get("callbacks")):
        target = str(node["_target_"])
        if target.endswith("SkeletonFigure"):
            continue
        cbs.append(instantiate(node, monitor=None) if target.endswith(".ModelCheckpoint") else instantiate(node))
    lgs = [make_logger(cfg, c) for c in enabled_nodes(cfg.get("logger"))]
    if not lgs:
        cbs = [c for c in cbs if not isinstance(c, L.pytorch.callbacks.LearningRateMonitor)]
    return instantiate(cfg.trainer, callbacks=[*cbs, NonFiniteGuard()], logger=lgs or False,
                       plugins=[AtomicCheckpointIO()], num_sanity_val_steps=0, limit_val_batches=0)


def _target(bvh: BVH, data, where: str) -> TargetRig:
    try:
        return TargetRig(bvh, data.skeleton, data.forward_axis, where=where)
    except InbetweenError as e:
        raise ConfigError(str(e)) from None


def _report(out: Path, results: dict, learned: LearnedRetarget, sets: dict, header: str) -> str:
    write_text(out / "retarget.json", json.dumps(results, indent=2, allow_nan=False))
    clips = next(iter(sets.values()))
    fig = clip_figure(learned, clips[0]) if clips else None
    if fig is not None:
        fig.savefig(out / "retarget.png")
    table = format_table(results["sets"])
    print(f"\n{header}\n{table}")
    return fig


def train_retarget(cfg: DictConfig) -> dict[str, float]:
    """Fit the retargeting network on (source, analytic target) pairs, score the held-out clips (module docstring)."""
    from inbetweening.models import RETARGETERS

    if cfg.model.get("name") not in RETARGETERS:
        raise ConfigError(f"model.name: {cfg.model.get('name')!r} is an in-betweening network; task=retarget takes "
                          f"one of {sorted(RETARGETERS)} (model=retarget_lstm)")
    bvh = _rig_file(cfg)  # a wrong rig is one line before anything else is printed
    if bvh is None:
        raise ConfigError("target_rig: required with task=retarget (a BVH file whose hierarchy is the target)")
    use_threads(cfg)
    L.seed_everything(cfg.seed, workers=True)
    out = output_dir(cfg)
    rc = cfg.retarget
    data = make_datamodule(cfg).load_data()
    rig = _target(bvh, data, f"target_rig {cfg.target_rig}")
    contents = list(rc.contents) if rc.get("contents") else None
    train, sets = _sets(cfg, data, contents, float(rc.train_fraction))
    pairs = make_pairs(rig, train)
    (x_mean, x_std), (y_mean, y_std) = stats([p.x for p in pairs]), stats([p.y for p in pairs])
    norm = {"x_mean": x_mean, "x_std": x_std, "y_mean": y_mean, "y_std": y_std}

    ref = BVH(bvh.names, bvh.parents, bvh.offsets, bvh.channels, bvh.end_sites, bvh.frame_time, bvh.motion[:1],
              bvh.source)
    plain = OmegaConf.to_container
    module = RetargetModule(model=plain(cfg.model, resolve=True), loss=plain(rc.loss, resolve=True),
                            smooth_kernel=list(rc.smooth_kernel), optim=plain(cfg.optim, resolve=True),
                            skeleton=data.skeleton.to_dict(), forward=list(data.forward_axis), rig_bvh=format_bvh(ref),
                            rig_name=Path(cfg.target_rig).name, fps=float(data.fps),
                            norm={k: v.tolist() for k, v in norm.items()},
                            split={"contents": contents, "train_fraction": float(rc.train_fraction)})
    loader = window_loader(pairs, norm, int(rc.window), int(rc.stride), int(rc.batch_size), int(cfg.seed))
    print(f"task=retarget: {len(pairs)} training clips ({sum(len(p.x) for p in pairs)} frames, {len(loader)} batches "
          f"of {rc.batch_size} windows of {rc.window} frames); source {data.skeleton.num_joints} joints -> target "
          f"{rig.skeleton.num_joints} ({len(rig.driven)} driven); held out: "
          + ", ".join(f"{k} {len(v)} clips" for k, v in sets.items()))
    trainer = _trainer(cfg)
    trainer.fit(module, train_dataloaders=loader)
    module.eval()
    trainer.save_checkpoint(out / "checkpoints" / "retarget.ckpt", weights_only=True)  # no optimiser state
    learned = module.retargeter()
    results = {"dataset": data.name, "target_rig": str(cfg.target_rig), "split": module.hparams["split"],
               "steps": int(trainer.global_step), "sets": score_sets(learned, sets, data.contact, float(data.fps))}
    fig = _report(out, results, learned, sets, f"Held-out clips (retargeting onto {cfg.target_rig}):")
    for lg in trainer.loggers:
        lg.log_metrics({f"test/{s}/{m}/{k}": v for s, r in results["sets"].items() for m in ("learned", "analytic",
                        "copy") for k, v in r[m].items()}, step=trainer.global_step)
        if fig is not None and hasattr(lg.experiment, "add_figure"):
            lg.experiment.add_figure("test/retarget", fig, global_step=trainer.global_step)
        lg.finalize("success")
    first = next(iter(results["sets"].values()))
    return {f"{m}.{k}": v for m in ("learned", "analytic", "copy") for k, v in first[m].items()}


def eval_retarget(cfg: DictConfig) -> dict[str, float]:
    """Score a retargeting checkpoint (``ckpt_path``) on its held-out clips of the ``data`` group; ``target_rig``
    (optional) must be the rig it was trained for."""
    use_threads(cfg)
    out = output_dir(cfg)
    path = cfg.get("ckpt_path")
    if not path:
        raise ConfigError("ckpt_path: required with task=retarget (a checkpoint of python train.py task=retarget)")
    try:
        learned = LearnedRetarget.from_checkpoint(path)
        bvh = _rig_file(cfg)
        if bvh is not None:
            check_target(learned.rig, bvh, "target_rig", str(path))
    except InbetweenError as e:
        raise CheckpointError(str(e)) from None
    data = make_datamodule(cfg).load_data()
    if not data.skeleton.same_topology(learned.rig.source):
        raise CheckpointError(f"ckpt_path: {path} retargets a {learned.rig.source.num_joints}-joint source; data "
                              f"{data.name!r} has {data.skeleton.num_joints} joints")
    split = _split_of(path)
    _, sets = _sets(cfg, data, split["contents"], split["train_fraction"])
    results = {"dataset": data.name, "ckpt_path": str(path), "split": split,
               "sets": score_sets(learned, sets, data.contact, float(data.fps))}
    _report(out, results, learned, sets, f"Held-out clips ({path}):")
    first = next(iter(results["sets"].values()))
    return {f"{m}.{k}": v for m in ("learned", "analytic", "copy") for k, v in first[m].items()}


def _split_of(path) -> dict:
    from inbetweening.predictor.checkpoint import read_checkpoint

    hp = read_checkpoint(path)["hyper_parameters"]
    return dict(hp.get("split") or {"contents": None, "train_fraction": 0.6})
