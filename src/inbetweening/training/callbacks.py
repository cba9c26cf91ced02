"""Lightning callbacks and plugins of the project (the TensorBoard figures: :mod:`.figures`): the non-finite guard, the
resume state (RNG), the interrupt checkpoint and atomic checkpoint writes."""
from __future__ import annotations

import ctypes
import ctypes.util
import os

import lightning as L
import torch
from lightning.pytorch.callbacks import ModelCheckpoint
from lightning.pytorch.plugins.io import TorchCheckpointIO

from inbetweening.training.figures import SkeletonFigure  # noqa: F401  (its old home; configs name it here too)


class NonFiniteError(RuntimeError):
    """Training produced a NaN/inf loss or gradient; the message names the step, the quantity and the last
    good checkpoint."""


class NonFiniteGuard(L.Callback):
    """Stop training at the first non-finite training loss or gradient, before the optimiser step applies it,
    so every checkpoint written so far holds finite weights.  Raises :class:`NonFiniteError`."""

    def _fail(self, trainer: L.Trainer, what: str) -> None:
        ckpt = last_checkpoint_path(trainer)
        where = f"last good checkpoint: {ckpt}" if ckpt else "no checkpoint was written yet"
        raise NonFiniteError(f"step {trainer.global_step}: {what}; training stopped ({where}); "
                             "lower optim.optimizer.lr or check the data")

    def on_train_batch_end(self, trainer, pl_module, outputs, batch, batch_idx) -> None:
        loss = outputs.get("loss") if isinstance(outputs, dict) else outputs
        if isinstance(loss, torch.Tensor) and not bool(torch.isfinite(loss).all()):
            self._fail(trainer, f"training loss is {float(loss)}")

    def on_before_optimizer_step(self, trainer, pl_module, optimizer) -> None:
        for name, p in pl_module.named_parameters():
            if p.grad is not None and not bool(torch.isfinite(p.grad).all()):
                self._fail(trainer, f"gradient of {name} is not finite")


def _rng_state() -> dict:
    """Every global RNG state as tensors and plain values (loads with ``weights_only=True``)."""
    import random

    import numpy as np

    kind, keys, pos, has_gauss, cached = np.random.get_state()
    version, internal, gauss = random.getstate()
    return {"torch": torch.get_rng_state(), "numpy": {"kind": kind, "keys": torch.from_numpy(keys.astype("int64")),
            "pos": int(pos), "has_gauss": int(has_gauss), "cached": float(cached)},
            "python": {"version": version, "internal": torch.tensor(internal, dtype=torch.int64), "gauss": gauss}}


def _set_rng_state(state: dict) -> None:
    import random

    import numpy as np

    torch.set_rng_state(state["torch"])
    n = state["numpy"]
    np.random.set_state((n["kind"], n["keys"].numpy().astype("uint32"), n["pos"], n["has_gauss"], n["cached"]))
    p = state["python"]
    random.setstate((p["version"], tuple(int(v) for v in p["internal"].tolist()), p["gauss"]))


class ResumeState(L.Callback):
    """Saves the global RNG states (torch, numpy, python) in every checkpoint and restores them on resume, so a
    resumed run draws the same dropout masks as an uninterrupted one.  (Data order and the sampled transition
    lengths are pure functions of the seed, epoch and batch, and the training loader's position is saved by
    Lightning through its ``state_dict``: see :mod:`inbetweening.training.datamodule`.)"""

    def __init__(self):
        self._restore = None

    def state_dict(self) -> dict:
        return {"rng": _rng_state()}

    def load_state_dict(self, state_dict: dict) -> None:
        self._restore = state_dict.get("rng")  # applied when training starts, after Lightning's own set-up draws

    def on_train_start(self, trainer, pl_module) -> None:
        if self._restore is not None:
            _set_rng_state(self._restore)
            self._restore = None


class InterruptCheckpoint(L.Callback):
    """On Ctrl-C (SIGINT) or SIGTERM: write ``<dirpath>/last.ckpt`` at the current step and print how to resume."""

    def __init__(self, dirpath: str, resume_command: str):
        self.dirpath, self.resume_command = dirpath, resume_command

    def on_exception(self, trainer: L.Trainer, pl_module, exception: BaseException) -> None:
        from lightning.pytorch.utilities.exceptions import SIGTERMException

        if not isinstance(exception, (KeyboardInterrupt, SIGTERMException)) or trainer.state.fn != "fit":
            return
        import os

        path = os.path.join(self.dirpath, "last.ckpt")
        trainer.save_checkpoint(path)
        if trainer.is_global_zero:
            what = "SIGTERM" if isinstance(exception, SIGTERMException) else "interrupted (Ctrl-C)"
            print(f"\n{what} at step {trainer.global_step}: saved {path}\nresume with: {self.resume_command} "
                  f"ckpt_path={path}", flush=True)


def last_checkpoint_path(trainer: L.Trainer) -> str | None:
    """The newest ``last.ckpt`` any checkpoint callback of ``trainer`` has written, else ``None``."""
    paths = [getattr(c, "last_model_path", "") for c in trainer.checkpoint_callbacks]
    return next((p for p in paths if p), None)


class AtomicCheckpointIO(TorchCheckpointIO):
    """Lightning checkpoint writes made atomic: a temporary file in the target's directory, fsynced, then
    ``os.replace``d, so a kill during a write never leaves a truncated ``last.ckpt`` (nor temp files elsewhere)."""

    def save_checkpoint(self, checkpoint: dict, path, storage_options=None) -> None:
        from inbetweening.atomic import atomic_path

        with atomic_path(path) as tmp:
            torch.save(checkpoint, tmp)


class LastCheckpoint(ModelCheckpoint):
    """``last.ckpt`` every ``every_n_train_steps`` optimiser steps AND at every training epoch end (whether or not
    validation improved), so at most N steps of work are ever at risk.  Writes nothing else."""

    def __init__(self, dirpath: str, every_n_train_steps: int = 200):
        super().__init__(dirpath=dirpath, save_last=True, save_top_k=0, every_n_train_steps=int(every_n_train_steps))

    def on_train_epoch_end(self, trainer, pl_module) -> None:
        if not self._should_skip_saving_checkpoint(trainer):
            self._save_last_checkpoint(trainer, self._monitor_candidates(trainer))




def trim_heap() -> bool:
    """Give the C heap's free pages back to the OS (glibc ``malloc_trim``); ``False`` where there is no glibc."""
    name = ctypes.util.find_library("c")
    if not name:
        return False
    libc = ctypes.CDLL(name)
    if not hasattr(libc, "malloc_trim"):
        return False
    libc.malloc_trim(0)
    return True


def resident_mb() -> float:
    """This process's resident set size in MB (``/proc/self/statm``; 0 where there is no procfs)."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
    except (OSError, ValueError, IndexError):
        return 0.0


class TrimHeap(L.Callback):
    """:func:`trim_heap` every ``every_n_steps`` training steps, after any step that leaves the process more than
    ``slack_mb`` above its size after the last trim, at each epoch start, and before and after each validation (whose
    batches have other shapes than the training steps').

    glibc keeps the memory that a training step frees (activations of 9-18 MB each for the default graph
    transformer) in a heap that fragments over steps of different shapes (training, validation); without trimming
    the default synthetic run's peak grew from 1.27 GB after one epoch to 1.71 GB after 15.  A trim costs the page
    faults of growing back once, so it runs when the heap has grown, not after every step (trimming every step made
    training 15% slower; serving large blocks by their own memory maps, 50%).  BENCHMARKS.md, "Memory".
    """

    def __init__(self, every_n_steps: int = 25, slack_mb: float = 512.0):
        self.every = max(1, int(every_n_steps))
        self.slack = float(slack_mb)
        self.floor = float("inf")  # resident size right after the last trim (none yet)

    def _trim(self) -> None:
        trim_heap()
        self.floor = resident_mb()

    def on_train_epoch_start(self, trainer, pl_module) -> None:
        self._trim()

    def on_train_batch_end(self, trainer, pl_module, outputs, batch, batch_idx) -> None:
        if (batch_idx + 1) % self.every == 0 or resident_mb() > self.floor + self.slack:
            self._trim()

    def on_validation_epoch_start(self, trainer, pl_module) -> None:
        self._trim()

    def on_validation_epoch_end(self, trainer, pl_module) -> None:
        self._trim()
