"""What the Hydra-configured jobs (:mod:`.train`, :mod:`.evaluate`, :mod:`.calibrate`) share: the CPU threads of a
job, the one check that a checkpoint fits the data's skeleton, writing ``benchmark.json``, and turning known user
errors into one line on stderr (:func:`run_cli`, the entry points ``train.py``, ``eval.py`` and ``calibrate.py``).

``benchmark.json``: ``{"dataset", "split", "model", "n_windows", "metrics": {"l2q@5": ...}}`` in the run's output
directory (:func:`write_benchmark`).
"""
from __future__ import annotations

import json
import math
import sys
from collections.abc import Callable
from pathlib import Path

import torch
from omegaconf import DictConfig

from inbetweening.atomic import write_text
from inbetweening.data.bvh import BVHError
from inbetweening.data.datasets import DatasetError
from inbetweening.predictor.checkpoint import CheckpointError
from inbetweening.training.callbacks import NonFiniteError
from inbetweening.training.config import ConfigError

__all__ = ["check_skeleton", "run_cli", "use_threads", "write_benchmark"]


def use_threads(cfg: DictConfig) -> None:
    """``threads``: the torch threads of this job (null: torch's default), so that jobs can share the CPU."""
    if cfg.get("threads"):
        torch.set_num_threads(int(cfg.threads))


def check_skeleton(ckpt_path, predictor, data) -> None:
    """A checkpoint's model (its ``predictor``: skeleton and training dataset's name) must have the joints of
    ``data`` (a :class:`~inbetweening.data.clips.MotionData`); :class:`CheckpointError` naming both otherwise."""
    if not predictor.skeleton.same_topology(data.skeleton):
        raise CheckpointError(f"ckpt_path: {ckpt_path} was trained on a {predictor.skeleton.num_joints}-joint skeleton "
                              f"({predictor.dataset}), data {data.name!r} has {data.skeleton.num_joints} joints")


def write_benchmark(path: Path, dataset: str, model: str, n_windows: int, metrics: dict,
                    split: str | None = None, keyframes: dict | None = None, interpolation: dict | None = None,
                    network: dict | None = None) -> dict:
    """Write ``benchmark.json`` (strict JSON, atomically); a non-finite metric is an error, never a number.
    ``split``: the dataset's split rule (``data.split``), recorded when given.  ``keyframes``: the
    ``protocol=keyframes`` figures ``{"<K>": {"model_cm": ..., "n_clips": ...}}``, written under the ``keyframes``
    key (integers stay integers; the per-clip ratios and the worst clips' names as they are).  ``interpolation``: the
    interpolation baseline's metrics on the same windows
    (the reference ratios are taken against), written under ``interpolation``.  ``network``: the network's metrics
    without the do-no-harm blend (``metrics`` are the blended fill's), under ``network``."""
    res = {"dataset": dataset, **({"split": split} if split else {}), "model": model, "n_windows": int(n_windows),
           "metrics": {k: float(v) for k, v in metrics.items()}}
    if interpolation is not None:
        res["interpolation"] = {k: float(v) for k, v in interpolation.items()}
    if network is not None:
        res["network"] = {k: float(v) for k, v in network.items()}
    checked = {**res["metrics"], **{f"interpolation.{k}": v for k, v in res.get("interpolation", {}).items()},
               **{f"network.{k}": v for k, v in res.get("network", {}).items()}}
    if keyframes is not None:
        res["keyframes"] = {str(k): {m: (v if isinstance(v, (int, str, dict)) else float(v)) for m, v in row.items()}
                            for k, row in keyframes.items()}
        checked.update({f"keyframes.{k}.{m}": v for k, row in res["keyframes"].items() for m, v in row.items()
                        if not isinstance(v, (str, dict))})
    bad = [k for k, v in checked.items() if not math.isfinite(v)]
    if bad:
        raise NonFiniteError(f"benchmark: {', '.join(bad)} not finite ({checked[bad[0]]}); "
                             f"{path} was not written")
    write_text(path, json.dumps(res, indent=2, allow_nan=False))
    return res


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
