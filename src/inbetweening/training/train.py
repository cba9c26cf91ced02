"""``train(cfg)`` and ``evaluate(cfg)``: the Hydra-configured jobs behind ``train.py`` and ``eval.py``.

Both return a metrics dict and write ``benchmark.json`` (``{"dataset", "split", "model", "n_windows",
"metrics": {"l2q@5": ...}}``) into the run's output directory.
"""
from __future__ import annotations

import json
import logging
import math
import sys
from collections.abc import Callable
from pathlib import Path

import lightning as L
import torch
from hydra.utils import instantiate
from lightning.pytorch.utilities.exceptions import SIGTERMException
from omegaconf import DictConfig, OmegaConf

from inbetweening.atomic import write_text
from inbetweening.checkpoint import CheckpointError, load_module, read_checkpoint
from inbetweening.data.bvh import BVHError
from inbetweening.data.datasets import DatasetError
from inbetweening.data.specs import get_spec
from inbetweening.evaluation import benchmark as B
from inbetweening.training.callbacks import (
    AtomicCheckpointIO,
    InterruptCheckpoint,
    NonFiniteError,
    NonFiniteGuard,
    ResumeState,
    TrimHeap,
    trim_heap,
)
from inbetweening.training.config import ConfigError, validate
from inbetweening.training.datamodule import InbetweenDataModule
from inbetweening.training.module import InbetweenModule
from inbetweening.training.tb_logging import (
    HParamsSession,
    RunLogger,
    TrainStats,
    curated_hparams,
    resumed_version,
    run_label,
    swept_keys,
    task_overrides,
)

log = logging.getLogger("inbetweening")


# ------------------------------------------------------------------------------------------
def output_dir(cfg: DictConfig) -> Path:
    out = Path(cfg.paths.output_dir)
    out.mkdir(parents=True, exist_ok=True)
    return out


def _plain(node):
    return OmegaConf.to_container(node, resolve=True)


def mask_settings(cfg: DictConfig) -> dict:
    """The ``mask`` group as the data module and the LightningModule take it: the mask's name, and the gap
    settings of ``mask=joints`` (``None`` for the other masks)."""
    return {"mask": cfg.mask.name, "joint_mask": _plain(cfg.mask) if cfg.mask.name == "joints" else None}


def make_datamodule(cfg: DictConfig) -> InbetweenDataModule:
    """``cfg.data`` (``_target_`` and the data module's arguments), completed with the mask settings and the seed."""
    return instantiate(cfg.data, _convert_="all", **mask_settings(cfg), seed=int(cfg.seed))


def make_module(cfg: DictConfig, dm: InbetweenDataModule) -> InbetweenModule:
    """The LightningModule from the ``model``, ``mask``, ``loss`` and ``optim`` groups, ``centre``, and what the
    (set up) data module knows: skeleton, statistics, benchmark lengths."""
    return InbetweenModule(model=_plain(cfg.model), loss=_plain(cfg.loss), optim=_plain(cfg.optim), centre=cfg.centre,
                           **mask_settings(cfg), **dm.model_kwargs())


def _make_logger(cfg: DictConfig, node: DictConfig):
    """A logger from its config; a :class:`RunLogger` without a ``version`` is named after the run's configuration
    (:func:`~inbetweening.training.tb_logging.run_label`), or continues the run a resumed fit was logging to."""
    if str(node.get("_target_", "")).endswith("RunLogger") and node.get("version") is None:
        version = resumed_version(node.save_dir, bool(cfg.get("ckpt_path")))
        return instantiate(node, version=version or run_label(cfg, task_overrides(), swept_keys()))
    return instantiate(node)


def make_trainer(cfg: DictConfig, callbacks=True, loggers=True) -> L.Trainer:
    cbs = [instantiate(c) for c in (cfg.get("callbacks") or {}).values() if c is not None] if callbacks else []
    lgs = [_make_logger(cfg, c) for c in (cfg.get("logger") or {}).values() if c is not None] if loggers else []
    if not lgs:  # logger=none: callbacks that need a logger are dropped instead of failing
        cbs = [c for c in cbs if not isinstance(c, L.pytorch.callbacks.LearningRateMonitor)]
    elif callbacks:  # TensorBoard: throughput, epoch time, gradient norm; the HParams session from the fit's start
        hp, shown = curated_hparams(cfg, task_overrides(), swept_keys())
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


def write_benchmark(path: Path, dataset: str, model: str, n_windows: int, metrics: dict,
                    split: str | None = None, keyframes: dict | None = None, interpolation: dict | None = None) -> dict:
    """Write ``benchmark.json`` (strict JSON, atomically); a non-finite metric is an error, never a number.
    ``split``: the dataset's split rule (``data.split``), recorded when given.  ``keyframes``: the
    ``protocol=keyframes`` figures ``{"<K>": {"model_cm": ..., "n_clips": ...}}``, written under the ``keyframes``
    key (integers stay integers).  ``interpolation``: the interpolation baseline's metrics on the same windows
    (the reference ratios are taken against), written under ``interpolation``."""
    res = {"dataset": dataset, **({"split": split} if split else {}), "model": model, "n_windows": int(n_windows),
           "metrics": {k: float(v) for k, v in metrics.items()}}
    if interpolation is not None:
        res["interpolation"] = {k: float(v) for k, v in interpolation.items()}
    checked = {**res["metrics"], **{f"interpolation.{k}": v for k, v in res.get("interpolation", {}).items()}}
    if keyframes is not None:
        res["keyframes"] = {str(k): {m: (v if isinstance(v, int) else float(v)) for m, v in row.items()}
                            for k, row in keyframes.items()}
        checked.update({f"keyframes.{k}.{m}": v for k, row in res["keyframes"].items() for m, v in row.items()})
    bad = [k for k, v in checked.items() if not math.isfinite(v)]
    if bad:
        raise NonFiniteError(f"benchmark: {', '.join(bad)} not finite ({checked[bad[0]]}); "
                             f"{path} was not written")
    write_text(path, json.dumps(res, indent=2, allow_nan=False))
    return res


# ------------------------------------------------------------------------------------------
def train(cfg: DictConfig) -> dict[str, float]:
    """Fit (unless the model is a non-trainable baseline), then run the test benchmark with the best
    checkpoint and write ``benchmark.json``.  Returns the test metrics."""
    validate(cfg)
    if cfg.get("threads"):
        torch.set_num_threads(int(cfg.threads))
    L.seed_everything(cfg.seed, workers=True)
    out = output_dir(cfg)
    dm = make_datamodule(cfg)
    dm.prepare_data()
    dm.setup("fit")
    module = make_module(cfg, dm)
    module.compile_network(bool(cfg.get("compile", False)))
    trainer = make_trainer(cfg)
    ckpt_path = cfg.get("ckpt_path")
    if ckpt_path:
        check_checkpoint(ckpt_path)
    best = None
    if module.trainable and cfg.trainer.get("max_steps", -1) != 0:
        try:
            trainer.fit(module, datamodule=dm, ckpt_path=ckpt_path, weights_only=True)
        except SIGTERMException:  # (a SystemExit) the checkpoint and the resume hint were written
            raise SystemExit(143) from None
        except SystemExit:  # Lightning exits after a graceful Ctrl-C; the checkpoint and hint were written
            raise SystemExit(130) from None
        best = getattr(trainer.checkpoint_callback, "best_model_path", None) or None
    metrics: dict[str, float] = {}
    if cfg.get("run_test", True):
        trim_heap()  # the test batches start from the heap the training steps left
        test_trainer = make_trainer(cfg, callbacks=False, loggers=False)
        if best and Path(best).exists():
            module = load_module(best)
        test_trainer.test(module, datamodule=dm, verbose=False)
        metrics = dict(module.test_results)
        name = cfg.model.name
        if not test_trainer.is_global_zero:  # DDP: metrics are synced; rank 0 alone writes and prints
            return metrics
        kf = None
        if cfg.get("test_keyframes"):  # the keyframes-only protocol on the whole test clips, through the animator path
            kf = score_keyframes(module.predictor, dm.data, list(cfg.test_keyframes))
        rows = with_baselines(name, metrics, dm, cfg.data.test_lengths)
        write_benchmark(out / "benchmark.json", dm.data.name, name, len(dm.test_set), metrics, dm.hparams.split,
                        keyframes=kf, interpolation=rows.get("interpolation"))
        print(f"\nTest benchmark ({dm.data.name}, split {dm.hparams.split}, {len(dm.test_set)} windows, "
              f"checkpoint: {best or 'final weights'})")
        print(B.format_table(rows, cfg.data.test_lengths))
        if "recovery_rmse" in metrics:
            print(f"mocap recovery: RMSE of recovered joint positions = {metrics['recovery_rmse']:.3f}")
        if kf is not None:
            from inbetweening.evaluation.keyframes import format_table

            print(f"\nKeyframes-only protocol ({len(dm.data.test)} whole test clips)\n" + format_table(kf))
        log_test(trainer, module)
    return metrics


def log_test(trainer: L.Trainer, module: InbetweenModule) -> None:
    """The test scalars (``test/l2p@15``, ``test/interp_l2p@15``, ``test/l2p_ratio@15``, ...) into the fit's
    TensorBoard run at its last step, and its HParams session marked ended."""
    for cb in trainer.callbacks:
        if isinstance(cb, HParamsSession):
            cb.start(trainer)  # a baseline was not fitted: its session starts here
    for lg in trainer.loggers:
        if isinstance(lg, RunLogger):
            lg.log_metrics(module.stage_logs.get("test", {}), step=trainer.global_step)
            lg.end_session("success")
        lg.finalize("success")


def with_baselines(name: str, metrics: dict, dm: InbetweenDataModule, lengths) -> dict[str, dict[str, float]]:
    """Rows for the printed table: the model, then zero-velocity and interpolation on the same windows."""
    rows = {name: metrics}
    if name not in B.BASELINES:
        bench = dm.test_benchmark_set()
        for base in ("zero_velocity", "interpolation"):
            rows[base] = B.evaluate_transitions(bench, B.BASELINES[base], tuple(lengths))
    return rows


def check_checkpoint(path: str) -> dict:
    """Load a checkpoint's dict safely, or raise :class:`CheckpointError` saying what is wrong with it."""
    return read_checkpoint(path)


def evaluate(cfg: DictConfig) -> dict[str, float]:
    """Benchmark a checkpoint (``ckpt_path``) or a baseline (``model=zero_velocity|interpolation``) with the
    LAFAN1 protocol, or with ``protocol=keyframes`` (:func:`evaluate_keyframes`)."""
    validate(cfg)
    if cfg.get("protocol", "lafan") == "keyframes":
        return evaluate_keyframes(cfg)
    out = output_dir(cfg)
    ckpt_path = cfg.get("ckpt_path")
    if not ckpt_path:
        name = cfg.model.name
        if name not in B.BASELINES:
            raise ConfigError(f"ckpt_path: required for model {name!r} (or use model=zero_velocity|interpolation)")
        dm = make_datamodule(cfg)
        data = dm._load()
        bench = data.benchmark_set()
        metrics = B.evaluate_transitions(bench, B.BASELINES[name], tuple(cfg.data.test_lengths))
        dataset, n = data.name, bench.n_windows
    else:
        module = load_module(ckpt_path)
        dm = make_datamodule(cfg)
        dm.prepare_data()
        dm.setup("test")
        if not module.skeleton.same_topology(dm.skeleton):
            raise CheckpointError(
                f"ckpt_path: {ckpt_path} was trained on a {module.skeleton.num_joints}-joint skeleton "
                f"({module.hparams.dataset}), data {dm.data.name!r} has {dm.skeleton.num_joints} joints"
            )
        # scored with the dataset's own training statistics (the benchmark protocol)
        for name in ("test_bench", "test_interp"):
            setattr(module, name, type(module.test_bench)(module.skeleton, dm.data.pos_mean, dm.data.pos_std,
                                                          cfg.data.test_lengths))
        trainer = make_trainer(cfg, callbacks=False, loggers=False)
        trainer.test(module, datamodule=dm, verbose=False)
        metrics, dataset, n = dict(module.test_results), dm.data.name, len(dm.test_set)
        name = module.hparams.model["name"]
        if not trainer.is_global_zero:  # DDP: metrics are synced; rank 0 alone writes and prints
            return metrics
    write_benchmark(out / "benchmark.json", dataset, name, n, metrics, dm.hparams.split)
    print(f"\nBenchmark: {dataset}, split {dm.hparams.split}, {n} test windows -> {out / 'benchmark.json'}")
    print(B.format_table({name: metrics}, cfg.data.test_lengths))
    return metrics


def evaluate_keyframes(cfg: DictConfig) -> dict[str, float]:
    """``protocol=keyframes`` (:mod:`inbetweening.evaluation.keyframes`): whole test clips, a keyframe every ``K``
    frames (``keyframe_intervals``), the rest generated by the animator path (``Inbetweener.fill_arrays``) of the
    checkpoint, or by the baseline itself.  Writes ``benchmark.json`` with a ``keyframes`` key; returns
    ``{"<figure>@<K>": value}``."""
    from inbetweening.evaluation import keyframes as KF
    from inbetweening.tools.inbetweener import Inbetweener

    dm = make_datamodule(cfg)
    data = dm._load()
    ckpt_path, name, fill = cfg.get("ckpt_path"), cfg.model.name, None
    if ckpt_path:
        ib = Inbetweener.from_checkpoint(ckpt_path)
        if not ib.skeleton.same_topology(data.skeleton):
            raise CheckpointError(f"ckpt_path: {ckpt_path} was trained on a {ib.skeleton.num_joints}-joint skeleton "
                                  f"({ib.predictor.dataset}), data {data.name!r} has {data.skeleton.num_joints} joints")
        name, fill = ib.predictor.model_cfg.get("name", "model"), ib.fill_arrays
    elif name not in B.BASELINES:
        raise ConfigError(f"ckpt_path: required for model {name!r} (or use model=zero_velocity|interpolation)")
    elif name == "zero_velocity":
        fill = KF.hold_keyframes
    res = score_keyframes(fill, data, list(cfg.keyframe_intervals))
    out = output_dir(cfg)
    write_benchmark(out / "benchmark.json", data.name, name, len(data.test), {}, dm.hparams.split, keyframes=res)
    print(f"\nKeyframes-only protocol: {data.name}, split {dm.hparams.split}, {len(data.test)} whole test clips, "
          f"{data.fps:g} fps, model {name} -> {out / 'benchmark.json'}")
    print(KF.format_table(res))
    return {f"{m}@{k}": float(v) for k, row in res.items() for m, v in row.items()}


def score_keyframes(model, data, intervals: list[int]) -> dict:
    """The keyframes-only figures of ``model`` (a predictor, through the animator path, or a fill function; ``None``:
    interpolation) on the whole test clips of ``data``: ``{K: {figure: value}}``."""
    from inbetweening.evaluation import keyframes as KF
    from inbetweening.tools.inbetweener import Inbetweener

    fill = Inbetweener(model).fill_arrays if isinstance(model, torch.nn.Module) else model
    feet = KF.foot_spec(data.skeleton, get_spec(data.name))
    return KF.evaluate_clips(data.test, data.skeleton, fill, intervals, data.fps, feet, progress=log.info)


def run_cli(job: Callable[[DictConfig], dict], cfg: DictConfig) -> float | None:
    """Run a job; known user errors become one clear line on stderr and exit status 2."""
    try:
        metrics = job(cfg)
    except (ConfigError, DatasetError, BVHError, CheckpointError) as e:
        print(f"error: {e}", file=sys.stderr)
        sys.exit(2)
    except NonFiniteError as e:  # diverged training or non-finite results: say where, keep what was good
        print(f"error: {e}", file=sys.stderr)
        sys.exit(3)
    key = cfg.get("optimized_metric")
    return metrics.get(key) if key and metrics else None
