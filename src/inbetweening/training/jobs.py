"""``train(cfg)``, ``evaluate(cfg)`` and ``calibrate(cfg)``: the Hydra-configured jobs behind ``train.py``,
``eval.py`` and ``calibrate.py`` (their parts are built by :mod:`inbetweening.training.builders`).

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
import numpy as np
import torch
import yaml
from lightning.pytorch.utilities.exceptions import SIGTERMException
from omegaconf import DictConfig

from inbetweening.atomic import write_text
from inbetweening.data.bvh import BVHError
from inbetweening.data.datasets import DatasetError
from inbetweening.evaluation import benchmark as B
from inbetweening.predictor.checkpoint import CheckpointError, predictor_state, read_checkpoint, trained_gap
from inbetweening.training.builders import make_datamodule, make_module, make_trainer, output_dir
from inbetweening.training.callbacks import NonFiniteError, trim_heap
from inbetweening.training.config import ConfigError, validate
from inbetweening.training.datamodule import InbetweenDataModule
from inbetweening.training.module import InbetweenModule, load_module
from inbetweening.training.sampling import rank_world
from inbetweening.training.tb_logging import HParamsSession, RunLogger

log = logging.getLogger("inbetweening")


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


def use_threads(cfg: DictConfig) -> None:
    """``threads``: the torch threads of this job (null: torch's default), so that jobs can share the CPU."""
    if cfg.get("threads"):
        torch.set_num_threads(int(cfg.threads))


# ------------------------------------------------------------------------------------------
def train(cfg: DictConfig) -> dict[str, float]:
    """Fit (unless the model is a non-trainable baseline), then run the test benchmark with the best
    checkpoint and write ``benchmark.json``.  Returns the test metrics."""
    validate(cfg)
    use_threads(cfg)
    L.seed_everything(cfg.seed, workers=True)
    out = output_dir(cfg)
    dm = make_datamodule(cfg)
    dm.prepare_data()
    init = start_from(cfg.get("init_from"), dm)
    dm.setup("fit")
    report_derived(dm.data, out)
    module = make_module(cfg, dm, init)
    module.compile_network(bool(cfg.get("compile", False)))
    trainer = make_trainer(cfg)
    ckpt_path = cfg.get("ckpt_path")
    if ckpt_path:
        check_resume(ckpt_path, module)
    best = None
    if module.trainable and cfg.trainer.get("max_steps", -1) != 0:
        try:
            trainer.fit(module, datamodule=dm, ckpt_path=ckpt_path, weights_only=True)
        except SIGTERMException:  # (a SystemExit) the checkpoint and the resume hint were written
            raise SystemExit(143) from None
        except SystemExit:  # Lightning exits after a graceful Ctrl-C; the checkpoint and hint were written
            raise SystemExit(130) from None
        best = getattr(trainer.checkpoint_callback, "best_model_path", None) or None
    if best and Path(best).exists():
        module = load_module(best)
    else:
        best = None
    fitted = module.trainable and cfg.trainer.get("max_steps", -1) != 0
    if fitted and cfg.get("calibrate", True) and (best or cfg.get("run_test", True)):
        # every rank fits the same blend; rank 0 writes it
        best = calibrate_module(module, dm, cfg, best, write=rank_world()[0] == 0,
                                max_gap=int(dm.hparams.transition_max)) or best
    metrics: dict[str, float] = {}
    if cfg.get("run_test", True):
        trim_heap()  # the test batches start from the heap the training steps left
        test_trainer = make_trainer(cfg, callbacks=False, loggers=False)
        test_trainer.test(module, datamodule=dm, verbose=False)
        metrics = dict(module.test_results)
        name = cfg.model.name
        if not test_trainer.is_global_zero:  # DDP: metrics are synced; rank 0 alone writes and prints
            return metrics
        kf = None
        if cfg.get("test_keyframes"):  # the keyframes-only protocol on the whole test clips, through the animator path
            kf = score_keyframes(module.predictor, dm.data, list(cfg.test_keyframes), int(cfg.seed),
                                 bool(cfg.get("foot_lock", True)), cfg.get("keyframe_clips"))
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


def calibrate_module(module: InbetweenModule, dm: InbetweenDataModule, cfg: DictConfig, ckpt_path: str | None,
                     out: str | Path | None = None, write: bool = True, max_gap: int | None = None) -> str | None:
    """Fit the do-no-harm blend of ``module``'s predictor on ``dm``'s validation windows
    (:func:`~inbetweening.predictor.calibration.fit_blend`, ``calibrate_windows`` of them, gaps up to ``max_gap``:
    the longest gap the tools generate in one window; ``None``: ``train_window - n_past - 1``), give it to the module,
    print the fit, and (``write``) write the checkpoint ``ckpt_path`` with the blend to ``out`` (default
    ``calibrated.ckpt`` beside it); returns that path (``None`` without ``ckpt_path``)."""
    from inbetweening.predictor.calibration import calibrated_checkpoint, fit_blend
    from inbetweening.predictor.predictor import check_blend

    root, q = dm.calibration_windows(cfg.get("calibrate_windows"))
    fit = fit_blend(module.predictor, root, q, max_gap=max_gap)
    module.predictor.blend = check_blend(fit.weights)
    module.hparams["blend"] = list(fit.weights)
    if not ckpt_path:
        return None
    dst = Path(out) if out else Path(ckpt_path).with_name("calibrated.ckpt")
    if not write:
        return str(dst)
    print(fit.table())
    ckpt = calibrated_checkpoint(read_checkpoint(ckpt_path), fit.weights)
    ckpt["blend_fit"] = {"rows": fit.rows, "windows": fit.windows, "source": str(ckpt_path)}
    dst.parent.mkdir(parents=True, exist_ok=True)
    torch.save(ckpt, dst)
    print(f"calibrated checkpoint (do-no-harm blend): {dst}")
    return str(dst)


def calibrate(cfg: DictConfig) -> dict[str, float]:
    """``calibrate.py``: fit the do-no-harm blend of a checkpoint (``ckpt_path``) on the validation windows of
    ``data`` (gaps up to the longest the checkpoint was trained on, :func:`~inbetweening.predictor.checkpoint.
    trained_gap`, else ``train_window - n_past - 1``) and write the checkpoint with it (``out``, default
    ``<ckpt_path's stem>.calibrated.ckpt``).  Returns ``{"weight@<gap>": ...}``."""
    validate(cfg)
    use_threads(cfg)
    ckpt_path = cfg.get("ckpt_path")
    if not ckpt_path:
        raise ConfigError("ckpt_path: required (the checkpoint to calibrate)")
    src = Path(ckpt_path)
    out = Path(cfg.out) if cfg.get("out") else src.with_name(f"{src.stem}.calibrated.ckpt")
    if out.resolve() == src.resolve():
        raise ConfigError(f"out: {out} is the input checkpoint; write the calibrated one to another file")
    module = load_module(ckpt_path)
    dm = make_datamodule(cfg)
    dm.prepare_data()
    dm.setup("fit")
    if not module.skeleton.same_topology(dm.skeleton):
        raise CheckpointError(f"ckpt_path: {ckpt_path} was trained on a {module.skeleton.num_joints}-joint skeleton "
                              f"({module.hparams.dataset}), data {dm.data.name!r} has {dm.skeleton.num_joints} joints")
    calibrate_module(module, dm, cfg, ckpt_path, out, max_gap=trained_gap(read_checkpoint(ckpt_path)))
    return {f"weight@{i + 1}": w for i, w in enumerate(module.predictor.blend)}


def report_derived(data, out: Path) -> None:
    """``data=bvh``: print what was derived from the files, once, and save it as ``dataset.yaml`` next to the run."""
    if data.derived is None or rank_world()[0] != 0:
        return
    text = yaml.safe_dump(data.derived, sort_keys=False, width=118, default_flow_style=None)
    write_text(out / "dataset.yaml", text)
    print(f"\nDataset derived from the files of data.path (saved as {out / 'dataset.yaml'}; data.<key>=... overrides "
          f"any value):\n{text}")


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


def start_from(path: str | None, dm: InbetweenDataModule) -> dict | None:
    """``init_from``: the checkpoint a new run starts from (read safely), after putting the data's joints in the
    checkpoint's order (matched by name: the same joints and hierarchy in another order are fine).  A checkpoint of
    another skeleton is one :class:`CheckpointError` naming both skeletons."""
    if not path:
        return None
    ckpt = read_checkpoint(path)
    theirs = ckpt["hyper_parameters"]["skeleton"]
    names, parents = list(theirs["names"]), list(theirs["parents"])
    data = dm.load_data()
    mine = data.skeleton
    try:
        ordered = data.in_joint_order(names)
    except DatasetError as e:
        ordered = None
        why = str(e)
    if ordered is not None and list(ordered.skeleton.parents) != parents:
        ordered, why = None, "the same joints under other parents"
    if ordered is None:
        raise CheckpointError(f"init_from: {path} was trained on a {len(names)}-joint skeleton ({', '.join(names[:4])}, "
                              f"...); data {data.name!r} has {mine.num_joints} joints ({', '.join(mine.names[:4])}, "
                              f"...): {why}")
    dm.use_data(ordered)
    return ckpt


def _architecture(model: dict) -> str:
    return ", ".join(f"{k}={v}" for k, v in sorted(model.items()) if k != "name") or "defaults"


def check_resume(path: str, module: InbetweenModule) -> dict:
    """The checkpoint a fit resumes from, read safely and checked to fit this run's network: same skeleton, same
    parameter shapes; :class:`CheckpointError` naming both architectures otherwise (never a size-mismatch traceback)."""
    ckpt = read_checkpoint(path)
    hp = ckpt["hyper_parameters"]
    theirs, ours = predictor_state(ckpt["state_dict"]), module.predictor.state_dict()
    mine = dict(module.hparams["model"])
    old = dict(hp.get("model", {}))
    j_old, j_new = len(hp.get("skeleton", {}).get("names", [])), module.skeleton.num_joints
    if j_old != j_new:
        raise CheckpointError(f"ckpt_path: {path} was trained on a {j_old}-joint skeleton; this run's data "
                              f"{module.hparams.get('dataset', '')!r} has {j_new} joints: resume on the same data")
    bad = sorted(k for k in ours.keys() & theirs.keys() if tuple(ours[k].shape) != tuple(theirs[k].shape))
    missing = sorted(ours.keys() ^ theirs.keys())
    if bad or missing or old.get("name") != mine.get("name"):
        raise CheckpointError(
            f"ckpt_path: {path} holds another architecture: {old.get('name')} ({_architecture(old)}); this run builds "
            f"{mine.get('name')} ({_architecture(mine)}): resume with the checkpoint's model settings, or start a new "
            "run without ckpt_path")
    return ckpt


def evaluate(cfg: DictConfig) -> dict[str, float]:
    """Benchmark a checkpoint (``ckpt_path``) or a baseline (``model=zero_velocity|interpolation``) with the
    LAFAN1 protocol, or with ``protocol=keyframes`` (:func:`evaluate_keyframes`)."""
    validate(cfg)
    use_threads(cfg)
    if cfg.get("protocol", "lafan") == "keyframes":
        return evaluate_keyframes(cfg)
    out = output_dir(cfg)
    ckpt_path = cfg.get("ckpt_path")
    if not ckpt_path:
        name = cfg.model.name
        if name not in B.BASELINES:
            raise ConfigError(f"ckpt_path: required for model {name!r} (or use model=zero_velocity|interpolation)")
        dm = make_datamodule(cfg)
        data = dm.load_data()
        bench = data.benchmark_set()
        metrics = B.evaluate_transitions(bench, B.BASELINES[name], tuple(cfg.data.test_lengths))
        dataset, n = data.name, bench.n_windows
    else:
        dm = make_datamodule(cfg)
        dm.prepare_data()
        dm.setup("test")
        # scored with the dataset's own training statistics (the benchmark protocol) at the configured lengths
        module = load_module(ckpt_path, test_lengths=list(cfg.data.test_lengths),
                             score_stats={"mean": dm.data.pos_mean.tolist(), "std": dm.data.pos_std.tolist()})
        if not module.skeleton.same_topology(dm.skeleton):
            raise CheckpointError(
                f"ckpt_path: {ckpt_path} was trained on a {module.skeleton.num_joints}-joint skeleton "
                f"({module.hparams.dataset}), data {dm.data.name!r} has {dm.skeleton.num_joints} joints"
            )
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
    data = dm.load_data()
    ckpt_path, name, fill = cfg.get("ckpt_path"), cfg.model.name, None
    if ckpt_path:
        ib = Inbetweener.from_checkpoint(ckpt_path, foot_lock=bool(cfg.get("foot_lock", True)))
        if not ib.skeleton.same_topology(data.skeleton):
            raise CheckpointError(f"ckpt_path: {ckpt_path} was trained on a {ib.skeleton.num_joints}-joint skeleton "
                                  f"({ib.predictor.dataset}), data {data.name!r} has {data.skeleton.num_joints} joints")
        name, fill = ib.predictor.model_cfg.get("name", "model"), ib.fill_arrays
    elif name not in B.BASELINES:
        raise ConfigError(f"ckpt_path: required for model {name!r} (or use model=zero_velocity|interpolation)")
    elif name == "zero_velocity":
        fill = KF.hold_keyframes
    res = score_keyframes(fill, data, list(cfg.keyframe_intervals), int(cfg.seed), max_clips=cfg.get("keyframe_clips"))
    out = output_dir(cfg)
    write_benchmark(out / "benchmark.json", data.name, name, len(data.test), {}, dm.hparams.split, keyframes=res)
    print(f"\nKeyframes-only protocol: {data.name}, split {dm.hparams.split}, {len(data.test)} whole test clips, "
          f"{data.fps:g} fps, model {name} -> {out / 'benchmark.json'}")
    print(KF.format_table(res))
    return {f"{m}@{k}": float(v) for k, row in res.items() for m, v in row.items()}


def score_keyframes(model, data, intervals: list, seed: int = 0, foot_lock: bool = True,
                    max_clips: int | None = None) -> dict:
    """The keyframes-only figures of ``model`` (a predictor, through the animator path, with its feet locked unless
    ``foot_lock=False``; or a fill function; ``None``: interpolation) on the whole test clips of ``data`` for each
    schedule of ``intervals`` (an interval ``K`` or a keypose schedule name; ``seed`` seeds the random one):
    ``{schedule: {figure: value}}``.  ``max_clips``: score that many test clips, evenly spaced (quick comparisons)."""
    from inbetweening.evaluation import keyframes as KF
    from inbetweening.tools.inbetweener import Inbetweener

    fill = Inbetweener(model, foot_lock=foot_lock).fill_arrays if isinstance(model, torch.nn.Module) else model
    feet = KF.foot_spec(data.skeleton, data.contact)
    clips = data.test
    if max_clips and max_clips < len(clips):
        clips = [clips[i] for i in np.linspace(0, len(clips) - 1, int(max_clips)).round().astype(int)]
    return KF.evaluate_clips(clips, data.skeleton, fill, intervals, data.fps, feet, progress=log.info, seed=seed)


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
