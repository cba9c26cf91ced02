"""Reading checkpoints safely: no code runs while loading, and a wrong file is one clear error.

Every load of the package (training resume, ``eval.py``, ``predict``, ``export``, ``Inbetweener``) goes
through :func:`read_checkpoint` / :func:`load_predictor` (and the training module's
:func:`inbetweening.training.module.load_module`, built on them): ``torch.load(weights_only=True)``
only rebuilds tensors, numbers, strings, lists and dicts, so a checkpoint carrying a pickled code payload is
refused before anything in it runs.  Inference tools load a :class:`~inbetweening.predictor.predictor.Predictor`
straight from the hyper-parameters and state dict (:func:`load_predictor`), never importing the training code.

State dict layouts: the training module keeps the predictor under ``predictor.`` (``predictor.net.*``);
checkpoints made before the predictor existed, and inference-only exports, hold the predictor's own keys
(``net.*``).  :func:`predictor_state` and :func:`upgrade_module_state` read both.
"""
from __future__ import annotations

import io
import math
import pickle
import re
import warnings
from pathlib import Path

import torch

from inbetweening.predictor.predictor import Predictor, upgrade_hparams


class CheckpointError(ValueError):
    """A checkpoint is missing, unreadable, unsafe, non-finite or not an inbetweening checkpoint."""


def read_checkpoint_bytes(path: str | Path) -> bytes:
    """The file's bytes; :class:`CheckpointError` naming ``ckpt_path`` when it does not exist."""
    p = Path(path)
    if not p.is_file():
        raise CheckpointError(f"ckpt_path: {p} does not exist")
    return p.read_bytes()


def _load(raw: bytes, p: str) -> dict:
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # torch's notes on pickle protocols: the error below says it all
            return torch.load(io.BytesIO(raw), map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as e:
        found = re.search(r"GLOBAL (\S+)", str(e))
        if found is None:  # not a pickle of the kind torch.save writes
            raise CheckpointError(f"ckpt_path: {p} is not a readable PyTorch checkpoint (corrupt or another format)") \
                from None
        raise CheckpointError(f"ckpt_path: {p} refused: it holds a Python object ({found.group(1)}) that could run code "
                              "when loaded; checkpoints may hold only tensors and plain values") from None
    except Exception as e:  # noqa: BLE001 - any other failure means "not a checkpoint"
        raise CheckpointError(f"ckpt_path: {p} is not a readable PyTorch checkpoint ({type(e).__name__}: {e})") from None


def non_finite_tensor(state_dict: dict) -> str | None:
    """Name of the first floating-point tensor of ``state_dict`` holding NaN or inf, else ``None``."""
    for k, v in state_dict.items():
        if isinstance(v, torch.Tensor) and v.is_floating_point() and not bool(torch.isfinite(v).all()):
            return k
        if isinstance(v, float) and not math.isfinite(v):
            return k
    return None


def read_checkpoint(path: str | Path, raw: bytes | None = None) -> dict:
    """The checkpoint's dict, loaded without running code, checked to be an inbetweening checkpoint with
    finite weights; :class:`CheckpointError` says what is wrong otherwise."""
    p = str(path)
    ckpt = _load(read_checkpoint_bytes(path) if raw is None else raw, p)
    hp = ckpt.get("hyper_parameters") if isinstance(ckpt, dict) else None
    if not hp or "model" not in hp or "skeleton" not in hp or "state_dict" not in ckpt:
        raise CheckpointError(f"ckpt_path: {p} is not an inbetweening checkpoint (no model/skeleton hyper-parameters)")
    bad = non_finite_tensor(ckpt["state_dict"])
    if bad is not None:
        raise CheckpointError(f"ckpt_path: {p} has non-finite weights ({bad} holds NaN or inf); "
                              "use an earlier checkpoint of the run")
    return ckpt


PREDICTOR_PREFIX = "predictor."


def predictor_state(state_dict: dict) -> dict:
    """The predictor's own entries (``net.*``) of a training module's state dict, of either layout."""
    if any(k.startswith(PREDICTOR_PREFIX) for k in state_dict):
        return {k[len(PREDICTOR_PREFIX):]: v for k, v in state_dict.items() if k.startswith(PREDICTOR_PREFIX)}
    return {k: v for k, v in state_dict.items() if k.startswith("net.")}


def kept_start(ckpt: dict, start: dict, keep: float) -> dict:
    """A copy of the checkpoint dict ``ckpt`` whose network weights are taken ``keep`` of the way back to those of
    ``start`` (a checkpoint dict of the same network, either layout): ``(1 - keep) * trained + keep * start`` for
    every floating-point tensor of the predictor (weight-space ensembling of a fine-tune with the model it started
    from, ``init_keep``).  ``keep`` 0 is ``ckpt``, 1 its start's network; the hyper-parameters are ``ckpt``'s, so both
    must share the normalisation statistics.  :class:`CheckpointError` when the networks differ."""
    mine, theirs = ckpt["state_dict"], predictor_state(start["state_dict"])
    prefix = PREDICTOR_PREFIX if any(k.startswith(PREDICTOR_PREFIX) for k in mine) else ""
    ours = {k[len(prefix):]: k for k in mine if k.startswith(prefix + "net.")}
    if set(ours) != set(theirs) or any(tuple(mine[ours[k]].shape) != tuple(theirs[k].shape) for k in ours):
        raise CheckpointError("init_keep: the trained network and init_from's differ in their parameters; "
                              "weights can only be mixed between one network's")
    state = dict(mine)
    for k, full in ours.items():
        if torch.is_floating_point(mine[full]):
            state[full] = (1.0 - keep) * mine[full] + keep * theirs[k].to(mine[full].dtype)
    out = {k: v for k, v in ckpt.items() if k not in ("optimizer_states", "lr_schedulers")}
    out["state_dict"] = state
    return out


def some_layers(state: dict, model: dict, layers) -> tuple[dict, dict]:
    """A shallower network from a predictor's: its state ``state`` (``net.*``, as :func:`predictor_state` gives) and
    model settings ``model`` cut to the layers ``layers`` (numbers of its ``net.layers.<i>``, in the new order), every
    other weight as it was (``init_layers``).  Returns the new state and settings (``depth`` = the number of layers).
    :class:`CheckpointError` for a network without a ``depth`` and a ``layers`` list, or a layer it does not have."""
    depth = model.get("depth")
    found = {int(m.group(1)) for k in state if (m := re.match(r"net\.layers\.(\d+)\.", k))}
    if not isinstance(depth, int) or not found:
        raise CheckpointError(f"init_layers: init_from's network ({model.get('name')}) has no list of layers to take "
                              "some of (a depth and net.layers.<i> weights)")
    missing = [i for i in layers if i not in found]
    if missing:
        raise CheckpointError(f"init_layers: init_from's network has layers 0-{depth - 1}, not {missing}")
    where = {old: new for new, old in enumerate(layers)}
    out = {}
    for k, v in state.items():
        m = re.match(r"net\.layers\.(\d+)\.(.*)", k)
        if m is None:
            out[k] = v
        elif int(m.group(1)) in where:
            out[f"net.layers.{where[int(m.group(1))]}.{m.group(2)}"] = v
    return out, {**model, "depth": len(layers)}


def upgrade_module_state(state_dict: dict) -> dict:
    """A training module's state dict in today's layout: older ``net.*`` keys become ``predictor.net.*``."""
    return {(PREDICTOR_PREFIX + k if k.startswith("net.") else k): v for k, v in state_dict.items()}


def peek_hyper_parameters(source) -> dict:
    """The ``hyper_parameters`` of a checkpoint (a path or a readable binary file, rewound afterwards), loaded
    without running code; ``{}`` when it cannot be read (the real load then says why)."""
    try:
        pos = source.tell() if hasattr(source, "read") else None
        ckpt = _load(source.read() if pos is not None else read_checkpoint_bytes(source), str(source))
        if pos is not None:
            source.seek(pos)
    except (CheckpointError, OSError):
        return {}
    hp = ckpt.get("hyper_parameters") if isinstance(ckpt, dict) else None
    return dict(hp) if isinstance(hp, dict) else {}


def trained_gap(ckpt: dict) -> int | None:
    """The longest transition a checkpoint's model was trained on: the data module's ``transition_max`` it records
    (not for the mocap-recovery task, ``mask=joints``, whose gaps are per joint); ``None`` when it records none
    (inference-only exports: the tools then take ``train_window - n_past - 1``)."""
    dm = ckpt.get("datamodule_hyper_parameters") or {}
    if dm.get("mask", "lerp") != "joints" and dm.get("transition_max"):
        return int(dm["transition_max"])
    return None


def load_predictor(path: str | Path, device: str | torch.device = "cpu", ckpt: dict | None = None):
    """The :class:`~inbetweening.predictor.predictor.Predictor` of a checkpoint (training or inference-only, any
    layout; older checkpoints without ``centre`` get ``window``), in eval mode on ``device``, without Lightning.
    ``ckpt``: the checkpoint's dict when already read with :func:`read_checkpoint`."""
    ckpt = read_checkpoint(path) if ckpt is None else ckpt
    try:
        pred = Predictor.from_hparams(upgrade_hparams(ckpt["hyper_parameters"]))
        pred.load_state_dict(predictor_state(ckpt["state_dict"]))
    except (RuntimeError, KeyError, TypeError, ValueError) as e:
        msg = " ".join(str(e).split())
        raise CheckpointError(f"ckpt_path: {path} does not match this version's models ({msg[:300]})") from None
    return pred.to(device).eval()
