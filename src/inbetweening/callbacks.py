"""Lightning callbacks of the project: a TensorBoard figure of a fixed validation window."""
from __future__ import annotations

import lightning as L
import torch

from . import features as F
from .inference import predict_features
from .masks import transition_known
from .render import draw_sequences
from .skeleton import fk


class SkeletonFigure(L.Callback):
    """Every ``every_n_epochs`` epochs, draw ground truth vs prediction vs interpolation for one fixed
    validation window (transition length ``n``) and log it to TensorBoard as ``val/skeleton``."""

    def __init__(self, every_n_epochs: int = 5, window: int = 0, n: int = 30, frames: int = 6):
        self.every = max(1, int(every_n_epochs))
        self.window, self.n, self.frames = int(window), int(n), int(frames)

    def sequences(self, pl_module, root: torch.Tensor, q: torch.Tensor) -> dict:
        """Global positions ``(T, J, 3)`` of ground truth, prediction and interpolation for one window."""
        sk, n, p = pl_module.skeleton, self.n, pl_module.n_past
        t = p + n + 1
        feats = F.encode(root[None, :t].double(), q[None, :t].double(), sk, pl_module.mean, pl_module.std).float()
        feats = feats.to(pl_module.device)
        known = transition_known(1, t, sk.num_joints, p, n, device=feats.device)
        pred, interp = predict_features(pl_module.net, pl_module.mask_name, feats, known, pl_module.centre,
                                        pl_module.std)
        out = {}
        for label, f in (("ground truth", feats), ("prediction", pred), ("interpolation", interp)):
            r, lq = F.decode(f.double().cpu(), pl_module.mean, pl_module.std)
            out[label] = fk(lq, sk.local_positions(r), sk.parents)[1][0].numpy()
        return out

    def on_validation_epoch_end(self, trainer: L.Trainer, pl_module) -> None:
        if trainer.sanity_checking or trainer.current_epoch % self.every or not trainer.loggers:
            return
        ds = trainer.datamodule.val_set if trainer.datamodule is not None else None
        if ds is None or len(ds) == 0:
            return
        item = ds[min(self.window, len(ds) - 1)]
        was_training = pl_module.training
        pl_module.eval()
        seqs = self.sequences(pl_module, item["root"], item["q"])
        pl_module.train(was_training)
        t = next(iter(seqs.values())).shape[0]
        frames = sorted({round(i * (t - 1) / max(self.frames - 1, 1)) for i in range(self.frames)})
        highlight = transition_known(1, t, 1, pl_module.n_past, self.n)[0, :, 0].numpy()
        fig = draw_sequences(seqs, pl_module.skeleton.parents, frames=frames, highlight=highlight,
                             title=f"epoch {trainer.current_epoch}: transition of {self.n} frames")
        for logger in trainer.loggers:
            exp = getattr(logger, "experiment", None)
            if hasattr(exp, "add_figure"):
                exp.add_figure("val/skeleton", fig, global_step=trainer.global_step)


class NonFiniteError(RuntimeError):
    """Training produced a NaN/inf loss or gradient; the message names the step, the quantity and the last
    good checkpoint."""


class NonFiniteGuard(L.Callback):
    """Stop training at the first non-finite training loss or gradient, before the optimiser step applies it,
    so every checkpoint written so far holds finite weights.  Raises :class:`NonFiniteError`."""

    def _fail(self, trainer: L.Trainer, what: str) -> None:
        ckpt = getattr(trainer.checkpoint_callback, "last_model_path", "") or None
        where = f"last good checkpoint: {ckpt}" if ckpt else "no checkpoint was written yet"
        raise NonFiniteError(f"step {trainer.global_step}: {what}; training stopped ({where}); "
                             "lower optim.lr or check the data")

    def on_train_batch_end(self, trainer, pl_module, outputs, batch, batch_idx) -> None:
        loss = outputs.get("loss") if isinstance(outputs, dict) else outputs
        if isinstance(loss, torch.Tensor) and not bool(torch.isfinite(loss).all()):
            self._fail(trainer, f"training loss is {float(loss)}")

    def on_before_optimizer_step(self, trainer, pl_module, optimizer) -> None:
        for name, p in pl_module.named_parameters():
            if p.grad is not None and not bool(torch.isfinite(p.grad).all()):
                self._fail(trainer, f"gradient of {name} is not finite")
