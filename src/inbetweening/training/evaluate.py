"""``evaluate(cfg)``: the job behind ``eval.py``: a checkpoint or a baseline scored with the LAFAN1 protocol, or with
the keyframes-only protocol (``protocol=keyframes``, :func:`evaluate_keyframes`); and the scoring ``train`` reuses
after a fit (:func:`score_keyframes`, :func:`with_baselines`)."""
from __future__ import annotations

import logging

import numpy as np
import torch
from omegaconf import DictConfig

from inbetweening.evaluation import benchmark as B
from inbetweening.runtime.settings import DEFAULT_SETTINGS
from inbetweening.training.builders import make_datamodule, make_trainer, output_dir
from inbetweening.training.config import ConfigError, fill_settings, validate
from inbetweening.training.datamodule import InbetweenDataModule
from inbetweening.training.job import check_skeleton, use_threads, write_benchmark
from inbetweening.training.module import load_module

__all__ = ["animator_fill", "ensemble_transitions", "evaluate", "evaluate_ensemble",
           "evaluate_keyframes", "score_keyframes", "with_baselines"]

log = logging.getLogger("inbetweening")


def evaluate(cfg: DictConfig) -> dict[str, float]:
    """Benchmark a checkpoint (``ckpt_path``) or a baseline (``model=zero_velocity|interpolation``) with the
    LAFAN1 protocol, or with ``protocol=keyframes`` (:func:`evaluate_keyframes`)."""
    validate(cfg)
    use_threads(cfg)
    if cfg.get("protocol", "lafan") == "keyframes":
        return evaluate_keyframes(cfg)
    out = output_dir(cfg)
    ckpt_path = cfg.get("ckpt_path")
    if ckpt_path is not None and not isinstance(ckpt_path, str):
        return evaluate_ensemble(cfg, [str(p) for p in ckpt_path])
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
        check_skeleton(ckpt_path, module.predictor, dm.data)
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


def ensemble_transitions(paths: list[str], settings=None):
    """The LAFAN1 protocol's predictor (:func:`~inbetweening.evaluation.benchmark.evaluate_transitions`) of the ensemble
    of the checkpoints ``paths`` (:mod:`inbetweening.runtime.ensemble`): each window predicted through the fill
    runtime (:meth:`~inbetweening.runtime.FillRuntime.predict_windows`) and blended with the interpolation by the
    ensemble's weight for the length, as a single model's windows are scored (``settings``: the fill's
    :class:`~inbetweening.runtime.settings.FillSettings`, its ``share_power``); ``(predict_fn, first predictor)``."""
    from inbetweening.runtime import FillRuntime
    from inbetweening.runtime.ensemble import EnsembleBackend
    from inbetweening.runtime.torch_backend import TorchBackend
    from inbetweening.runtime.trust import blend

    members = [TorchBackend.from_checkpoint(p) for p in paths]
    runtime = FillRuntime(EnsembleBackend(members, paths), foot_lock=False, self_check=False,
                          settings=settings or DEFAULT_SETTINGS)

    def predict_fn(root, local_q, n):
        pr, pq, _ = runtime.predict_windows(root, local_q)
        w = runtime.info.blend_weight(n)
        if w is None or w >= 1.0:
            return pr, pq
        ir, iq = B.interpolation(root, local_q, n, runtime.info.n_past)
        return blend(ir, iq, pr, pq, w)

    return predict_fn, members[0].predictor


def evaluate_ensemble(cfg: DictConfig, paths: list[str]) -> dict[str, float]:
    """The LAFAN1 protocol for an ensemble (``ckpt_path=[a,b,...]``, :func:`ensemble_transitions`): ``benchmark.json``
    and the table with zero-velocity and interpolation on the same windows; returns the ensemble's metrics."""
    dm = make_datamodule(cfg)
    dm.prepare_data()
    dm.setup("test")
    predict_fn, predictor = ensemble_transitions(paths, fill_settings(cfg))
    check_skeleton(paths, predictor, dm.data)
    lengths = tuple(cfg.data.test_lengths)
    metrics = B.evaluate_transitions(dm.test_benchmark_set(), predict_fn, lengths)
    name = f"ensemble of {len(paths)}"
    out = output_dir(cfg)
    write_benchmark(out / "benchmark.json", dm.data.name, name, len(dm.test_set), metrics, dm.hparams.split)
    print(f"\nBenchmark: {dm.data.name}, split {dm.hparams.split}, {len(dm.test_set)} test windows, {name}: "
          f"{', '.join(paths)} -> {out / 'benchmark.json'}")
    print(B.format_table(with_baselines(name, metrics, dm, lengths), cfg.data.test_lengths))
    return metrics


def with_baselines(name: str, metrics: dict, dm: InbetweenDataModule, lengths) -> dict[str, dict[str, float]]:
    """Rows for the printed table: the model, then zero-velocity and interpolation on the same windows."""
    rows = {name: metrics}
    if name not in B.BASELINES:
        bench = dm.test_benchmark_set()
        for base in ("zero_velocity", "interpolation"):
            rows[base] = B.evaluate_transitions(bench, B.BASELINES[base], tuple(lengths))
    return rows


# ------------------------------------------------------------------------------------------ keyframes protocol
def animator_runtime(model, foot_lock: bool = True, self_check: bool = True, settings=None):
    """The animator's fill runtime (:class:`~inbetweening.runtime.FillRuntime`, the torch backend) of ``model``, a
    checkpoint path, a predictor, or a list of checkpoint paths (their ensemble, :mod:`inbetweening.runtime.ensemble`;
    the first one's predictor is returned): ``(runtime, predictor)``; the options as :func:`animator_fill`."""
    from inbetweening.runtime import FillRuntime
    from inbetweening.runtime.ensemble import EnsembleBackend
    from inbetweening.runtime.torch_backend import TorchBackend

    if isinstance(model, torch.nn.Module):
        backend = first = TorchBackend(model)
    elif isinstance(model, str):
        backend = first = TorchBackend.from_checkpoint(model)
    else:
        members = [TorchBackend.from_checkpoint(str(p)) for p in model]
        backend, first = EnsembleBackend(members, [str(p) for p in model]), members[0]
    runtime = FillRuntime(backend, foot_lock=foot_lock, self_check=self_check,
                          settings=settings or DEFAULT_SETTINGS)
    return runtime, first.predictor


def animator_fill(model, foot_lock: bool = True, self_check: bool = True, settings=None):
    """The animator's fill (the fill runtime, :class:`~inbetweening.runtime.FillRuntime`, with the torch backend) of
    ``model``, a checkpoint path, a predictor, or a list of checkpoint paths (their ensemble,
    :mod:`inbetweening.runtime.ensemble`; the first one's predictor is returned) (feet locked unless
    ``foot_lock=False``; the self-check of the do-no-harm blend unless ``self_check=False``): ``(fill, predictor)``,
    ``fill(root, local_q, keys, partial=None) -> (root, local_q)``: what ``predict``, the Python API and Blender fill
    with (``partial``: partial keys, ``{frame: joints}``); ``settings``: the fill's tuned numbers
    (:class:`~inbetweening.runtime.settings.FillSettings`; ``None``: the shipped ones)."""
    runtime, predictor = animator_runtime(model, foot_lock, self_check, settings)

    def fill(root, local_q, keys, partial=None):
        out = runtime.fill(root, local_q, keys, partial=partial)
        return out.root, out.local_q

    return fill, predictor


def evaluate_keyframes(cfg: DictConfig) -> dict[str, float]:
    """``protocol=keyframes`` (:mod:`inbetweening.evaluation.keyframes`): whole test clips, a keyframe every ``K``
    frames (``keyframe_intervals``), the rest generated by the animator path (:func:`animator_fill`) of the
    checkpoint, or by the baseline itself.  Writes ``benchmark.json`` with a ``keyframes`` key; returns
    ``{"<figure>@<K>": value}``."""
    from inbetweening.evaluation import keyframes as KF

    dm = make_datamodule(cfg)
    data = dm.load_data()
    ckpt_path, name, fill = cfg.get("ckpt_path"), cfg.model.name, None
    if ckpt_path:
        ckpt_path = ckpt_path if isinstance(ckpt_path, str) else [str(p) for p in ckpt_path]
        fill, predictor = animator_fill(ckpt_path, foot_lock=bool(cfg.get("foot_lock", True)),
                                        self_check=bool(cfg.get("self_check", True)), settings=fill_settings(cfg))
        check_skeleton(ckpt_path, predictor, data)
        name = predictor.model_cfg.get("name", "model")
        if not isinstance(ckpt_path, str):
            name = f"ensemble of {len(ckpt_path)} ({name} first)"
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
    return {f"{m}@{k}": float(v) for k, row in res.items() for m, v in row.items() if not isinstance(v, (str, dict))}


def score_keyframes(model, data, intervals: list, seed: int = 0, foot_lock: bool = True,
                    max_clips: int | None = None, self_check: bool = True, settings=None) -> dict:
    """The keyframes-only figures of ``model`` (a predictor, through the animator path, with its feet locked unless
    ``foot_lock=False``; or a fill function; ``None``: interpolation) on the whole test clips of ``data`` for each
    schedule of ``intervals`` (an interval ``K`` or a keypose schedule name; ``seed`` seeds the random one):
    ``{schedule: {figure: value}}``.  ``max_clips``: score that many test clips, evenly spaced (quick comparisons);
    ``settings``: the fill's tuned numbers (``None``: the shipped ones)."""
    from inbetweening.evaluation import keyframes as KF

    fill = (animator_fill(model, foot_lock=foot_lock, self_check=self_check, settings=settings)[0]
            if isinstance(model, torch.nn.Module) else model)
    feet = KF.foot_spec(data.skeleton, data.contact)
    clips = data.test
    if max_clips and max_clips < len(clips):
        clips = [clips[i] for i in np.linspace(0, len(clips) - 1, int(max_clips)).round().astype(int)]
    return KF.evaluate_clips(clips, data.skeleton, fill, intervals, data.fps, feet, progress=log.info, seed=seed)
