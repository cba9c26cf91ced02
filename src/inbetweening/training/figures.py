"""TensorBoard figures drawn during validation: the per-joint errors (:func:`per_joint_figure`) and one transition
of a fixed validation window (:func:`transition_figure`), and the callback that logs both (:class:`SkeletonFigure`).

Both are plain matplotlib figures on their own Agg canvas (no pyplot state), sized to stay readable at
TensorBoard's thumbnail width (the image dashboard shows them about 500 px wide).  Positions are in the dataset's
length unit (cm for every built-in dataset), rotations in degrees.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence

import lightning as L
import numpy as np
import torch
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from inbetweening.data.contacts import CONTACT_THRESHOLD
from inbetweening.rendering.skeleton_plot import CONTACT_COLOR, PALETTE

#: Drawing colours: ground truth grey, the model in colour, interpolation dashed.
GT_COLOR, MODEL_COLOR, INTERP_COLOR = "0.6", "tab:blue", "tab:orange"
#: Planted feet: the prediction's a filled dot in the contact colour, the ground truth's a dark ring.
GT_CONTACT_COLOR = "0.2"


def _figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), dpi=100)
    FigureCanvasAgg(fig)
    return fig


def per_joint_figure(names: Sequence[str], model: Mapping[int, Mapping[str, np.ndarray]],
                     interp: Mapping[int, Mapping[str, np.ndarray]] | None = None, title: str = "",
                     unit: str = "cm") -> Figure:
    """Mean position error (``unit``) and rotation error (degrees) per joint, joints in skeleton order on the x
    axis, one colour per transition length; the model solid, interpolation (when given) dashed.

    ``model[n]``/``interp[n]``: ``{"pos": (J,), "rot": (J,)}`` for transition length ``n``."""
    fig = _figure(7.0, 4.6)
    axes = fig.subplots(2, 1, sharex=True)
    x = np.arange(len(names))
    for ax, key, label in ((axes[0], "pos", f"position error ({unit})"), (axes[1], "rot", "rotation error (deg)")):
        for i, n in enumerate(sorted(model)):
            c = PALETTE[i % len(PALETTE)]
            ax.plot(x, np.asarray(model[n][key]), "-o", color=c, ms=3, lw=1.5, label=f"{n} frames")
            if interp and n in interp:
                ax.plot(x, np.asarray(interp[n][key]), "--", color=c, lw=1.0, alpha=0.8)
        ax.set_ylabel(label, fontsize=8)
        ax.grid(alpha=0.3)
        ax.tick_params(labelsize=7)
        ax.set_ylim(bottom=0)
    axes[1].set_xticks(x, list(names), rotation=90, fontsize=6)
    handles, labels = axes[0].get_legend_handles_labels()
    if interp:
        handles.append(axes[0].plot([], [], "--", color="k", lw=1.0)[0])
        labels.append("interpolation (dashed)")
    axes[0].legend(handles, labels, fontsize=7, ncol=3, loc="upper left")
    if title:
        fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    return fig


def _bones(parents: Sequence[int]) -> list[tuple[int, int]]:
    return [(j, p) for j, p in enumerate(parents) if p >= 0]


def transition_figure(gt: np.ndarray, pred: np.ndarray, interp: np.ndarray, parents: Sequence[int], n_past: int,
                      n: int, frames: Sequence[int], title: str = "", up_axis: int = 1, unit: str = "cm",
                      feet: Sequence[int] = (), contacts: Mapping[str, np.ndarray] | None = None,
                      foot_names: Sequence[str] | None = None) -> Figure:
    """One transition: a side view per frame in ``frames`` (ground truth grey, prediction in colour, interpolation
    dashed on top of it, the floor at height 0), each zoomed on the ground-truth root of its frame at a common scale,
    and below, the mean per-frame position error over the transition, model vs interpolation.

    ``gt``, ``pred``, ``interp``: global positions ``(T, J, 3)``.  The windows are normalised so that the root faces
    +X at the last context frame, so the view plots data X (forward) against ``up_axis``.

    ``contacts`` (a model with contact channels): ``{"prediction": (T, J) bool, "ground truth": (T, J) bool}``, the
    planted feet of ``feet`` (joint indices): in the side views a filled dot in :data:`CONTACT_COLOR` on the
    prediction's planted feet and a dark ring around the ground truth's; under the error curve one row per foot
    (``foot_names``), the ground truth's planted frames grey, the prediction's in the contact colour over them."""
    gt, pred, interp = (np.asarray(a, np.float64) for a in (gt, pred, interp))
    frames = [int(t) for t in frames]
    fwd = 0 if up_axis != 0 else 2
    feet = [int(j) for j in feet]
    contacts = {k: np.asarray(v, dtype=bool) for k, v in (contacts or {}).items()} if feet else {}
    fig = _figure(1.6 * len(frames), 3.9)
    ratios = [1.7, 1.0, 0.22 + 0.1 * len(feet)] if contacts else [1.7, 1.0]
    grid = fig.add_gridspec(len(ratios), len(frames), height_ratios=ratios, hspace=0.2, wspace=0.05)
    height = float(np.ptp(gt[..., up_axis])) or 1.0
    half = 0.65 * height
    bones = _bones(parents)
    target = n_past + n
    for i, t in enumerate(frames):
        ax = fig.add_subplot(grid[0, i])
        cx, cy = gt[t, 0, fwd], gt[t, :, up_axis].min() + height / 2
        # the interpolation last, dashed, above the prediction: where the two agree (a model that learned little, or
        # close to the keys) both stay visible, the prediction through the dashes' gaps
        for pose, style in ((gt[t], dict(color=GT_COLOR, lw=3.0, zorder=1)), (pred[t], dict(color=MODEL_COLOR, lw=1.6, zorder=2)),
                            (interp[t], dict(color=INTERP_COLOR, lw=1.3, ls=(0, (3, 3)), zorder=3))):
            for j, p in bones:
                ax.plot(pose[[j, p], fwd], pose[[j, p], up_axis], **style)
        ax.axhline(0.0, color="0.8", lw=0.8, zorder=0)  # the floor
        if contacts:
            on = [j for j in feet if contacts["ground truth"][t, j]]
            ax.plot(gt[t, on, fwd], gt[t, on, up_axis], "o", ms=7, mfc="none", mec=GT_CONTACT_COLOR, mew=1.2, zorder=4)
            on = [j for j in feet if contacts["prediction"][t, j]]
            ax.plot(pred[t, on, fwd], pred[t, on, up_axis], "o", ms=4.5, color=CONTACT_COLOR, mew=0, zorder=5)
        ax.set_xlim(cx - half, cx + half)
        ax.set_ylim(cy - half, cy + half)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        known = t < n_past or t == target
        ax.set_title(f"frame {t}" + (" (key)" if known else f" ({t - n_past + 1}/{n})"), fontsize=8,
                     color="tab:red" if known else "k")
    err = fig.add_subplot(grid[1, :])
    span = np.arange(n_past, target)
    model_err = np.linalg.norm(pred[span] - gt[span], axis=-1).mean(axis=-1)
    interp_err = np.linalg.norm(interp[span] - gt[span], axis=-1).mean(axis=-1)
    err.plot(span, model_err, "-o", color=MODEL_COLOR, ms=2.5, label=f"model (mean {model_err.mean():.2f})")
    err.plot(span, interp_err, "--", color=INTERP_COLOR, label=f"interpolation (mean {interp_err.mean():.2f})")
    for t in frames:
        err.axvline(t, color="0.85", lw=0.8, zorder=0)
    err.set_xlim(n_past - 1, target)
    err.set_ylim(bottom=0)
    if contacts:
        _contact_rows(fig.add_subplot(grid[2, :], sharex=err), contacts, feet, foot_names, frames)
        err.tick_params(labelbottom=False)
    else:
        err.set_xlabel("frame", fontsize=8)
    err.set_ylabel(f"position error ({unit})", fontsize=8)
    err.tick_params(labelsize=7)
    err.legend(fontsize=7, loc="upper left")
    err.grid(alpha=0.3)
    handles = [fig.axes[0].plot([], [], color=c, lw=w, ls=s)[0] for c, w, s in
               ((GT_COLOR, 3.0, "-"), (MODEL_COLOR, 1.6, "-"), (INTERP_COLOR, 1.2, "--"))]
    labels = ["ground truth", "prediction", "interpolation"]
    if contacts:
        handles += [fig.axes[0].plot([], [], "o", ms=4.5, color=CONTACT_COLOR, mew=0)[0],
                    fig.axes[0].plot([], [], "o", ms=7, mfc="none", mec=GT_CONTACT_COLOR, mew=1.2)[0]]
        labels += ["planted (predicted)", "planted (truth)"]
    fig.legend(handles, labels, loc="upper right", fontsize=7, ncol=len(labels), frameon=False)
    if title:
        fig.suptitle(title, fontsize=9, x=0.01, ha="left")
    fig.subplots_adjust(left=0.07, right=0.99, top=0.88, bottom=0.11)
    return fig


def _contact_rows(ax, contacts: Mapping[str, np.ndarray], feet: Sequence[int], names: Sequence[str] | None,
                  frames: Sequence[int]) -> None:
    """One row per foot over the window's frames: the ground truth's planted frames a wide grey bar, the
    prediction's a narrow bar in the contact colour on top."""
    t = np.arange(len(contacts["ground truth"]))
    for row, j in enumerate(feet):
        for key, color, width in (("ground truth", GT_COLOR, 7.0), ("prediction", CONTACT_COLOR, 3.0)):
            on = contacts[key][:, j]
            ax.hlines(np.full(on.sum(), row), t[on] - 0.5, t[on] + 0.5, color=color, lw=width)
    for f in frames:
        ax.axvline(f, color="0.85", lw=0.8, zorder=0)
    ax.set_yticks(range(len(feet)), list(names) if names else [str(j) for j in feet], fontsize=6)
    ax.set_ylim(len(feet) - 0.5, -0.5)
    ax.tick_params(labelsize=7, length=2)
    ax.set_xlabel("frame (planted: truth grey, prediction in the contact colour)", fontsize=8)


def frames_to_draw(n_past: int, n: int, count: int) -> list[int]:
    """``count`` frames: the last context frame, evenly spaced transition frames, and the target keyframe."""
    inner = max(count - 2, 1)
    mids = sorted({n_past + round((k + 1) * (n - 1) / (inner + 1)) for k in range(inner)})
    return [n_past - 1, *mids, n_past + n]


def _step(trainer: L.Trainer) -> int:
    """The step Lightning logs the validation scalars at."""
    return int(trainer.fit_loop.epoch_loop._batches_that_stepped)


def _add_figure(trainer: L.Trainer, tag: str, fig: Figure, step: int) -> None:
    for logger in trainer.loggers:
        exp = getattr(logger, "experiment", None)
        if hasattr(exp, "add_figure"):
            exp.add_figure(tag, fig, global_step=step)


class SkeletonFigure(L.Callback):
    """After each validation of a fit (global rank 0), log to TensorBoard, at the validation scalars' step:

    - ``val/per_joint``: :func:`per_joint_figure` of the module's per-joint errors (every validation);
    - ``val/skeleton``: :func:`transition_figure` of one fixed validation window at transition length ``n``, every
      ``every_n_epochs`` epochs, at each new best ``val/l2p_mean`` and at the last validation.

    Drawing goes through ``pl_module.predictor`` in eval mode with the global RNG states forked, so it changes
    neither the training nor its random draws."""

    def __init__(self, every_n_epochs: int = 5, window: int = 0, n: int = 30, frames: int = 6):
        self.every = max(1, int(every_n_epochs))
        self.window, self.n, self.frames = int(window), int(n), int(frames)
        self._val_global_step: int | None = None  # the optimiser step of the last validation of the fit

    def sequences(self, pl_module, root: torch.Tensor, q: torch.Tensor, n: int) -> dict[str, np.ndarray]:
        """Global positions ``(T, J, 3)`` of ground truth, prediction and interpolation for one window."""
        return self.window_motion(pl_module, root, q, n)[0]

    def window_motion(self, pl_module, root: torch.Tensor, q: torch.Tensor, n: int):
        """``(positions, contacts)`` of one window: :meth:`sequences`' positions, and for a representation with
        contact channels ``{"prediction", "ground truth"}`` -> ``(T, J)`` bool planted feet (the prediction above
        :data:`~inbetweening.data.contacts.CONTACT_THRESHOLD`, the ground truth labelled by the data's rule), else None."""
        pr = pl_module.predictor
        t = pr.n_past + n + 1
        known = pr.transition_known(1, t, n, device=pl_module.device)
        with torch.random.fork_rng(devices=[]), torch.no_grad():
            was_training = pl_module.training
            pl_module.eval()
            root, q = root[None, :t].to(pl_module.device), q[None, :t].to(pl_module.device)
            out = pr.predict_windows(root, q, known)
            pl_module.train(was_training)
        labelled = (("ground truth", (root, q)), ("prediction", (out.root, out.local_q)),
                    ("interpolation", (out.interp_root, out.interp_q)))
        positions = {label: pr.skeleton.pose(r.cpu(), lq.cpu())[1][0].numpy() for label, (r, lq) in labelled}
        rep = pr.representation
        predicted, truth = rep.contacts(out.pred), rep.contacts(out.feats)
        if predicted is None:
            return positions, None
        return positions, {"prediction": (predicted[0] > CONTACT_THRESHOLD).cpu().numpy(),
                           "ground truth": (truth[0] > 0.5).cpu().numpy()}

    def draw(self, trainer: L.Trainer, pl_module, why: str) -> None:
        ds = trainer.datamodule.val_set if trainer.datamodule is not None else None
        if ds is None or len(ds) == 0:
            return
        item = ds[min(self.window, len(ds) - 1)]
        n = min(self.n, item["root"].shape[0] - pl_module.n_past - 1)
        if n < 1:
            return
        s, contacts = self.window_motion(pl_module, item["root"], item["q"], n)
        step = _step(trainer)
        names = pl_module.skeleton.names
        contact = pl_module.predictor.contact
        feet = list(contact.indices(names)) if contacts is not None and contact.feet else []
        fig = transition_figure(s["ground truth"], s["prediction"], s["interpolation"], pl_module.skeleton.parents,
                                pl_module.n_past, n, frames_to_draw(pl_module.n_past, n, self.frames),
                                title=f"epoch {trainer.current_epoch}, step {step}{why}: window {self.window}, "
                                      f"{n}-frame transition", feet=feet, contacts=contacts,
                                foot_names=[names[j] for j in feet])
        _add_figure(trainer, "val/skeleton", fig, step)

    def on_validation_end(self, trainer: L.Trainer, pl_module) -> None:
        if trainer.sanity_checking or not trainer.loggers or not trainer.is_global_zero or trainer.state.fn != "fit":
            return
        self._val_global_step = trainer.global_step
        errors = getattr(pl_module, "joint_errors", {}).get("val")
        if errors:
            fig = per_joint_figure(pl_module.skeleton.names, errors["model"], errors.get("interp"),
                                   title=f"validation per-joint error, epoch {trainer.current_epoch} "
                                         "(solid: model, dashed: interpolation)")
            _add_figure(trainer, "val/per_joint", fig, _step(trainer))
        tags = []
        if getattr(pl_module, "val_improved", False):
            tags.append("best")
        if self._is_last(trainer):
            tags.append("last")
        if tags or trainer.current_epoch % self.every == 0:
            self.draw(trainer, pl_module, f" ({', '.join(tags)})" if tags else "")

    @staticmethod
    def _is_last(trainer: L.Trainer) -> bool:
        if trainer.should_stop:
            return True
        if trainer.max_epochs is not None and trainer.max_epochs > 0 and trainer.current_epoch + 1 >= trainer.max_epochs:
            return True
        return trainer.max_steps is not None and 0 < trainer.max_steps <= trainer.global_step

    def on_train_end(self, trainer: L.Trainer, pl_module) -> None:
        """Training stopped after its last validation (max_steps mid-epoch, max_time): draw the final weights."""
        if trainer.loggers and trainer.is_global_zero and self._val_global_step not in (None, trainer.global_step):
            self.draw(trainer, pl_module, " (end of training)")
