"""``calibrate(cfg)``: the job behind ``calibrate.py``, and :func:`calibrate_module`, the do-no-harm blend's fit that
``train`` runs after a fit too."""
from __future__ import annotations

from pathlib import Path

import torch
from omegaconf import DictConfig

from inbetweening.predictor.checkpoint import read_checkpoint, trained_gap
from inbetweening.training.builders import make_datamodule
from inbetweening.training.config import ConfigError, validate
from inbetweening.training.datamodule import InbetweenDataModule
from inbetweening.training.job import check_skeleton, use_threads
from inbetweening.training.module import InbetweenModule, load_module

__all__ = ["calibrate", "calibrate_module"]


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
    check_skeleton(ckpt_path, module.predictor, dm.data)
    calibrate_module(module, dm, cfg, ckpt_path, out, max_gap=trained_gap(read_checkpoint(ckpt_path)))
    return {f"weight@{i + 1}": w for i, w in enumerate(module.predictor.blend)}
