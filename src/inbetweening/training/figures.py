"""TensorBoard figures drawn during validation: the per-joint errors (:func:`per_joint_figure`) and one transition
of a fixed validation window (:func:`transition_figure`), and the callback that logs both (:class:`SkeletonFigure`).

Both are plain matplotlib figures on their own Agg canvas (no pyplot state) designed for TensorBoard's image card,
which fits an image, whatever its size, into a box about 320-430 px wide and 230 px high (:data:`CARD_PX`; Time
Series, seen in Chromium): landscape, :data:`WIDTH_PX` x at most :data:`HEIGHT_PX`, every text at least
:data:`FONT_SMALL` points (8-11 px in the card), few panels, and every legend outside the data areas.  Positions are
in the dataset's length unit (cm for every built-in dataset), rotations in degrees.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence

import lightning as L
import numpy as np
import torch
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator

from inbetweening.data.contacts import CONTACT_THRESHOLD
from inbetweening.rendering.skeleton_plot import CONTACT_COLOR, PALETTE

#: Drawing colours: ground truth grey, the model in colour, interpolation dashed.
GT_COLOR, MODEL_COLOR, INTERP_COLOR = "0.6", "tab:blue", "tab:orange"
#: Planted feet: the prediction's a filled dot in the contact colour, the ground truth's a dark ring.
GT_CONTACT_COLOR = "0.2"
#: Figure width in pixels (at :data:`DPI`), the titles' and labels' font size and the smallest one (ticks, legends) in
#: points: in a 320 px card, 12 pt at 100 dpi on a 600 px figure is about 9 px.
WIDTH_PX, HEIGHT_PX, FONT, FONT_SMALL = 640, 380, 13, 12
#: The box TensorBoard's Time Series image card fits an image into at its narrowest (width, height in px).
CARD_PX = (320, 230)
DPI = 100


def _figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), dpi=DPI)
    FigureCanvasAgg(fig)
    return fig


def per_joint_figure(names: Sequence[str], model: Mapping[int, Mapping[str, np.ndarray]],
                     interp: Mapping[int, Mapping[str, np.ndarray]] | None = None, title: str = "",
                     unit: str = "cm", key: str = "pos") -> Figure:
    """Mean position error (``key="pos"``, ``unit``) or rotation error (``key="rot"``, degrees) per joint, one
    panel: joints in skeleton order on the x axis, one colour per transition length, the model solid with dots,
    interpolation (when given) dashed; the legend above the panel, outside the data.

    ``model[n]``/``interp[n]``: ``{"pos": (J,), "rot": (J,)}`` for transition length ``n``."""
    fig = _figure(WIDTH_PX / DPI, HEIGHT_PX / DPI)
    ax = fig.add_axes([0.1, 0.36, 0.88, 0.45])
    x = np.arange(len(names))
    for i, n in enumerate(sorted(model)):
        c = PALETTE[i % len(PALETTE)]
        ax.plot(x, np.asarray(model[n][key]), "-o", color=c, ms=4, lw=1.6, label=f"{n}")
        if interp and n in interp:
            ax.plot(x, np.asarray(interp[n][key]), "--", color=c, lw=1.2, alpha=0.8)
    ax.set_ylabel(f"{'position' if key == 'pos' else 'rotation'} ({unit if key == 'pos' else 'deg'})", fontsize=FONT)
    ax.grid(alpha=0.3)
    ax.tick_params(labelsize=FONT_SMALL)
    peak = max([float(np.max(m[key])) for m in model.values()] + [float(np.max(m[key])) for m in (interp or {}).values()]
               + [0.0])
    ax.set_ylim(0, 1.12 * peak if peak > 0 else 1.0)  # room above the highest dot: no peak cut by the frame
    ax.yaxis.set_major_locator(MaxNLocator(4))
    ax.set_xticks(x, list(names), rotation=90, fontsize=FONT_SMALL)
    ax.set_xlim(-0.5, len(names) - 0.5)
    handles, labels = ax.get_legend_handles_labels()
    labels = [f"{lb} frames" if i == len(labels) - 1 else lb for i, lb in enumerate(labels)]
    if interp:
        handles.append(Line2D([], [], ls="--", color="k", lw=1.2))
        labels.append("interpolation")
    fig.legend(handles, labels, loc="lower left", bbox_to_anchor=(0.09, 0.81), fontsize=FONT_SMALL, ncol=len(labels),
               frameon=False, handlelength=1.5, columnspacing=0.8, handletextpad=0.4, borderaxespad=0.1)
    if title:
        fig.suptitle(title, fontsize=FONT, x=0.01, ha="left", y=0.99, va="top")
    return fig


def _bones(parents: Sequence[int]) -> list[tuple[int, int]]:
    return [(j, p) for j, p in enumerate(parents) if p >= 0]


def transition_figure(gt: np.ndarray, pred: np.ndarray, interp: np.ndarray, parents: Sequence[int], n_past: int,
                      n: int, frames: Sequence[int], title: str = "", up_axis: int = 1, unit: str = "cm",
                      feet: Sequence[int] = (), contacts: Mapping[str, np.ndarray] | None = None,
                      foot_names: Sequence[str] | None = None) -> Figure:
    """One transition, landscape for TensorBoard's card: left, a side view per frame in ``frames`` (3 a row; ground
    truth grey, prediction in colour, interpolation dashed on top of it, the floor at height 0), each zoomed on the
    ground-truth root of its frame at a common scale; right, the mean per-frame position error over the transition,
    model vs interpolation, the means in its title.  Title and legend on top, outside every data area.

    ``gt``, ``pred``, ``interp``: global positions ``(T, J, 3)``.  The windows are normalised so that the root faces
    +X at the last context frame, so the view plots data X (forward) against ``up_axis``.

    ``contacts`` (a model with contact channels): ``{"prediction": (T, J) bool, "ground truth": (T, J) bool}``, the
    planted feet of ``feet`` (joint indices): in the side views a filled dot in :data:`CONTACT_COLOR` on the
    prediction's planted feet and a dark ring around the ground truth's; under the error curve one row per foot in
    skeleton order, the ground truth's planted frames grey, the prediction's in the contact colour over them.
    ``foot_names``: accepted for callers; the card has no room for the names beside the rows."""
    gt, pred, interp = (np.asarray(a, np.float64) for a in (gt, pred, interp))
    frames = [int(t) for t in frames]
    fwd = 0 if up_axis != 0 else 2
    feet = [int(j) for j in feet]
    contacts = {k: np.asarray(v, dtype=bool) for k, v in (contacts or {}).items()} if feet else {}
    # landscape, in inches: title and legend on top; left, the side views (3 a row); right, the error curve and,
    # under it, the contact rows
    W, H = WIDTH_PX / DPI, HEIGHT_PX / DPI
    fig = _figure(W, H)
    cols = min(len(frames), 3)
    rows = -(-len(frames) // cols)
    top = 0.78 if title else 0.45  # title, legend
    side_w = 4.0 if rows == 1 else 3.3  # one row of views (the default three): wider, the error curve narrower
    panel = min(side_w / cols, (H - top - 0.05) / rows - 0.27)
    height = float(np.ptp(gt[..., up_axis])) or 1.0
    half = 0.62 * height
    bones = _bones(parents)
    target = n_past + n
    for i, t in enumerate(frames):
        r, c = divmod(i, cols)
        x0, y0 = 0.05 + c * (side_w / cols), H - top - (r + 1) * (panel + 0.27)
        ax = fig.add_axes([x0 / W, y0 / H, (panel - 0.06) / W, panel / H])
        cx, cy = gt[t, 0, fwd], gt[t, :, up_axis].min() + height / 2
        # the interpolation last, dashed, above the prediction: where the two agree (a model that learned little, or
        # close to the keys) both stay visible, the prediction through the dashes' gaps
        for pose, style in ((gt[t], dict(color=GT_COLOR, lw=2.6, zorder=1)), (pred[t], dict(color=MODEL_COLOR, lw=1.5, zorder=2)),
                            (interp[t], dict(color=INTERP_COLOR, lw=1.3, ls=(0, (2.5, 2.5)), zorder=3))):
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
        ax.set_aspect("equal", adjustable="box")
        ax.set_xticks([])
        ax.set_yticks([])
        known = t < n_past or t == target
        ax.set_title(f"{t} key" if known else f"{t} ({t - n_past + 1}/{n})", fontsize=FONT_SMALL,
                     color="tab:red" if known else "k", pad=2)
    # the error curve, right; its means in the title above it (no legend box over the curve)
    ex0, ew = side_w + 0.55, W - side_w - 0.55 - 0.2
    foot_h = 0.2 * len(feet) + 0.1 if contacts else 0.0
    eb = 0.55 + (foot_h + 0.1 if contacts else 0.0)
    err = fig.add_axes([ex0 / W, eb / H, ew / W, (H - top - 0.3 - eb) / H])
    span = np.arange(n_past, target)
    model_err = np.linalg.norm(pred[span] - gt[span], axis=-1).mean(axis=-1)
    interp_err = np.linalg.norm(interp[span] - gt[span], axis=-1).mean(axis=-1)
    err.plot(span, model_err, "-o", color=MODEL_COLOR, ms=2.5, label="prediction")
    err.plot(span, interp_err, "--", color=INTERP_COLOR, lw=1.5, label="interpolation")
    for t in frames:
        err.axvline(t, color="0.85", lw=0.8, zorder=0)
    err.set_xlim(n_past - 1, target)
    err.set_ylim(bottom=0)
    err.yaxis.set_major_locator(MaxNLocator(4))
    err.xaxis.set_major_locator(MaxNLocator(4, integer=True))
    err.set_title(f"error ({unit}), mean\n{model_err.mean():.2f} / interp. {interp_err.mean():.2f}",
                  fontsize=FONT_SMALL, loc="left", pad=3)
    if contacts:
        _contact_rows(fig.add_axes([ex0 / W, 0.55 / H, ew / W, foot_h / H], sharex=err), contacts, feet, foot_names,
                      frames)
        err.tick_params(labelbottom=False)
    else:
        err.set_xlabel("frame", fontsize=FONT_SMALL)
    err.tick_params(labelsize=FONT_SMALL)
    err.grid(alpha=0.3)
    handles = [Line2D([], [], color=c, lw=w, ls=s) for c, w, s in
               ((GT_COLOR, 2.6, "-"), (MODEL_COLOR, 1.5, "-"), (INTERP_COLOR, 1.3, "--"))]
    labels = ["truth", "prediction", "interp." if contacts else "interpolation"]
    if contacts:
        handles += [Line2D([], [], ls="", marker="o", ms=4.5, color=CONTACT_COLOR, mew=0),
                    Line2D([], [], ls="", marker="o", ms=7, mfc="none", mec=GT_CONTACT_COLOR, mew=1.2)]
        labels += ["planted", "truth planted"]
    fig.legend(handles, labels, loc="upper left", bbox_to_anchor=(0.005, 1.0 - (top - 0.42) / H), fontsize=FONT_SMALL,
               ncol=len(labels), frameon=False, handlelength=1.5, columnspacing=0.9, handletextpad=0.4,
               borderaxespad=0.0)
    if title:
        fig.suptitle(title, fontsize=FONT, x=0.01, ha="left", y=1.0 - 0.06 / H, va="top")
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
    ax.set_yticks([])  # the feet in skeleton order, top to bottom (their names: too long for the card)
    ax.set_ylim(len(feet) - 0.5, -0.5)
    ax.tick_params(labelsize=FONT_SMALL, length=2)
    ax.set_xlabel("frame (feet planted)", fontsize=FONT_SMALL)


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

    - ``val/per_joint``, ``val/per_joint_rotation``: :func:`per_joint_figure` of the module's per-joint position and
      rotation errors (every validation);
    - ``val/skeleton``: :func:`transition_figure` of one fixed validation window at transition length ``n``, every
      ``every_n_epochs`` epochs, at each new best ``val/l2p_mean`` and at the last validation.

    Drawing goes through ``pl_module.predictor`` in eval mode with the global RNG states forked, so it changes
    neither the training nor its random draws."""

    def __init__(self, every_n_epochs: int = 5, window: int = 0, n: int = 30, frames: int = 3):
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
                                title=f"epoch {trainer.current_epoch + 1}, step {step}{why}: window {self.window}, "
                                      f"{n}-frame transition", feet=feet, contacts=contacts,
                                foot_names=[names[j] for j in feet])
        _add_figure(trainer, "val/skeleton", fig, step)

    def on_validation_end(self, trainer: L.Trainer, pl_module) -> None:
        if trainer.sanity_checking or not trainer.loggers or not trainer.is_global_zero or trainer.state.fn != "fit":
            return
        self._val_global_step = trainer.global_step
        errors = getattr(pl_module, "joint_errors", {}).get("val")
        if errors:
            for key, tag, what in (("pos", "val/per_joint", "position"), ("rot", "val/per_joint_rotation", "rotation")):
                fig = per_joint_figure(pl_module.skeleton.names, errors["model"], errors.get("interp"), key=key,
                                       title=f"validation per-joint {what} error, epoch {trainer.current_epoch + 1}")
                _add_figure(trainer, tag, fig, _step(trainer))
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
