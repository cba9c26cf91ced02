"""Drawing skeleton sequences on matplotlib figures (no files): input checks, the plot-space view, bones and
poses, and :func:`draw_sequences`, the filmstrip figure that :mod:`inbetweening.tools.render` saves.

Everything draws on a :class:`matplotlib.figure.Figure` with its own Agg canvas; ``pyplot`` is never imported.
Input convention: ``sequences`` maps a label to *global* joint positions ``(T, J, 3)`` (numpy arrays or torch
tensors); all share the skeleton (``J == len(parents)``); a shorter sequence holds its last frame.  The data axis
``up_axis`` is shown vertically; the three data axes are shown in cyclic order ``(up + 1, up + 2, up) % 3`` on the
plot's ``(x, y, z)``, which keeps right-handed data right-handed.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from mpl_toolkits.mplot3d import Axes3D  # noqa: F401  (registers the "3d" projection)
from mpl_toolkits.mplot3d.art3d import Line3DCollection

__all__ = ["DEFAULT_VIEW", "KEY_COLOR", "PALETTE", "check_highlight", "check_parents", "check_sequences",
           "check_up_axis", "draw_pose", "draw_sequences", "frame_of", "new_figure", "plot_limits", "pose_bones",
           "setup_axes", "to_plot"]

#: One colour per label (red is kept for keyframes).
PALETTE = ("tab:blue", "tab:green", "tab:orange", "tab:purple", "tab:brown", "tab:cyan", "tab:olive", "tab:gray")
#: Colour of keyframes (``highlight``).
KEY_COLOR = "tab:red"
#: Default camera: elevation and azimuth in degrees.
DEFAULT_VIEW = (15.0, -60.0)
#: Number of frames shown by :func:`draw_sequences` when ``frames`` is None.
DEFAULT_N_FRAMES = 8


# --------------------------------------------------------------------------- input handling


def _to_numpy(x) -> np.ndarray:
    """numpy array or torch tensor (any device, with or without grad) -> ``np.ndarray``."""
    if hasattr(x, "detach"):
        x = x.detach().cpu()
    return np.asarray(x)


def check_parents(parents) -> np.ndarray:
    """``parents`` -> ``(J,)`` int array; ``-1`` for roots, otherwise an index in ``[0, J)`` other than itself."""
    par = _to_numpy(parents)
    if par.ndim != 1 or par.size == 0:
        raise ValueError(f"parents must be a non-empty 1-D sequence of ints, got shape {par.shape}")
    if not np.issubdtype(par.dtype, np.integer) and not (
        np.issubdtype(par.dtype, np.floating) and np.all(np.equal(np.mod(par, 1), 0))
    ):
        raise ValueError(f"parents must hold integers, got {par.tolist()}")
    par = par.astype(np.int64)
    n = par.size
    bad = [j for j, p in enumerate(par) if p < -1 or p >= n or p == j]
    if bad:
        raise ValueError(f"invalid parents at joints {bad}: each entry must be -1 (root) or another joint in [0, {n})")
    return par


def check_sequences(sequences: Mapping, n_joints: int) -> dict[str, np.ndarray]:
    """Validate ``label -> (T, J, 3)`` and convert to float64 numpy arrays."""
    if not isinstance(sequences, Mapping):
        raise TypeError(f"sequences must be a dict label -> (T, J, 3) array, got {type(sequences).__name__}")
    if len(sequences) == 0:
        raise ValueError("sequences is empty: pass at least one label -> (T, J, 3) array")
    out: dict[str, np.ndarray] = {}
    for label, seq in sequences.items():
        arr = _to_numpy(seq)
        if arr.ndim != 3 or arr.shape[-1] != 3:
            raise ValueError(f"sequence {label!r} must have shape (T, J, 3) (global joint positions), got {arr.shape}")
        if arr.shape[0] == 0:
            raise ValueError(f"sequence {label!r} has no frames (T == 0)")
        if arr.shape[1] != n_joints:
            raise ValueError(f"sequence {label!r} has J={arr.shape[1]} joints but parents describes {n_joints} joints")
        arr = arr.astype(np.float64)
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"sequence {label!r} contains NaN or infinite values")
        out[str(label)] = arr
    return out


def check_up_axis(up_axis: int) -> int:
    if up_axis not in (0, 1, 2):
        raise ValueError(f"up_axis must be 0, 1 or 2 (the data axis that points up), got {up_axis!r}")
    return int(up_axis)


def check_highlight(highlight, n_frames: int) -> np.ndarray:
    """``highlight`` -> ``(T,)`` bool array (all False when None); ``T`` is the longest sequence's length."""
    if highlight is None:
        return np.zeros(n_frames, dtype=bool)
    hl = _to_numpy(highlight)
    if hl.ndim != 1 or hl.shape[0] != n_frames:
        raise ValueError(
            f"highlight must be a (T,) bool mask with T={n_frames} (the longest sequence), got shape {hl.shape}"
        )
    return hl.astype(bool)


def _check_frames(frames, n_frames: int) -> list[int]:
    """Frame indices to show; default: up to :data:`DEFAULT_N_FRAMES` evenly spaced, first and last included."""
    if frames is None:
        k = min(n_frames, DEFAULT_N_FRAMES)
        return sorted({round(float(f)) for f in np.linspace(0, n_frames - 1, k)})
    idx = [int(f) for f in _to_numpy(frames).reshape(-1)]
    if not idx:
        raise ValueError("frames is empty: pass at least one frame index (or None for the default selection)")
    bad = [f for f in idx if not 0 <= f < n_frames]
    if bad:
        raise ValueError(f"frames {bad} out of range [0, {n_frames}) (T of the longest sequence)")
    return idx


# --------------------------------------------------------------------------- drawing helpers


def to_plot(pos: np.ndarray, up_axis: int) -> np.ndarray:
    """Reorder data axes ``(..., 3)`` so that ``up_axis`` becomes the plot's z (cyclic: handedness preserved)."""
    return pos[..., [(up_axis + 1) % 3, (up_axis + 2) % 3, up_axis]]


def plot_limits(seqs: dict[str, np.ndarray], up_axis: int) -> tuple[np.ndarray, np.ndarray]:
    """Shared cubic bounds over all frames of all sequences: ``lo (3,), hi (3,)`` in plot coordinates."""
    pts = np.concatenate([to_plot(s, up_axis).reshape(-1, 3) for s in seqs.values()], axis=0)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre = (lo + hi) / 2.0
    half = max(float((hi - lo).max()) / 2.0, 1e-6) * 1.05
    return centre - half, centre + half


def frame_of(seq: np.ndarray, t: int) -> np.ndarray:
    """Frame ``t`` of ``(T, J, 3)``; shorter sequences hold their last frame."""
    return seq[min(t, seq.shape[0] - 1)]


def pose_bones(pose: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """``(J, 3)`` plot-space pose -> ``(B, 2, 3)`` segments child -> parent (roots skipped)."""
    child = np.nonzero(parents >= 0)[0]
    return np.stack([pose[child], pose[parents[child]]], axis=1)


def setup_axes(ax, lo: np.ndarray, hi: np.ndarray, view: tuple[float, float], title: str | None) -> None:
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect((1.0, 1.0, 1.0), zoom=0.95)
    ax.view_init(elev=view[0], azim=view[1])
    ax.tick_params(labelsize=6, pad=0)
    if title:
        ax.set_title(title, fontsize=9)


def draw_pose(ax, pose: np.ndarray, parents: np.ndarray, color: str, alpha: float = 1.0) -> tuple:
    """Draw one plot-space ``(J, 3)`` pose; returns ``(bones Line3DCollection, joints Line3D)`` for updating."""
    lines = Line3DCollection(pose_bones(pose, parents), colors=color, linewidths=2.0, alpha=alpha)
    ax.add_collection3d(lines)
    (joints,) = ax.plot(pose[:, 0], pose[:, 1], pose[:, 2], "o", color=color, markersize=2.5, alpha=alpha)
    return lines, joints


def new_figure(width: float, height: float, dpi: float, top: float = 0.9) -> Figure:
    fig = Figure(figsize=(width, height), dpi=dpi)
    FigureCanvasAgg(fig)  # attaches itself as fig.canvas
    fig.subplots_adjust(left=0.0, right=1.0, bottom=0.0, top=top, wspace=0.0, hspace=0.1)
    return fig


# --------------------------------------------------------------------------- public API


def draw_sequences(
    sequences: Mapping[str, np.ndarray],
    parents: Sequence[int] | np.ndarray,
    frames: list[int] | None = None,
    up_axis: int = 1,
    highlight: np.ndarray | None = None,
    title: str | None = None,
    *,
    layout: str = "overlay",
    view: tuple[float, float] = DEFAULT_VIEW,
    panel_size: float = 3.5,
) -> Figure:
    """Draw skeleton sequences side by side, one column per label, on a headless (Agg) figure.

    Args:
        sequences: ``label -> (T, J, 3)`` global joint positions (numpy or torch); ``T`` may differ per label
            (a shorter sequence holds its last frame), ``J`` must equal ``len(parents)``.
        parents: ``(J,)`` parent index per joint, ``-1`` for the root.
        frames: frame indices to show (``0 <= t < T_max``); default: up to 8 evenly spaced frames, first and last
            included.
        up_axis: which data axis points up (1 for Y-up data such as LAFAN1, 2 for Z-up); it is shown vertically.
        highlight: ``(T_max,)`` bool mask of keyframes, drawn in :data:`KEY_COLOR` instead of the label's colour.
        title: figure title.
        layout: ``"overlay"`` (filmstrip: the selected frames drawn in one 3-D axes per label, opacity increasing
            with time) or ``"grid"`` (one row per selected frame).
        view: camera ``(elevation, azimuth)`` in degrees.
        panel_size: size of one panel in inches.

    Returns:
        A :class:`matplotlib.figure.Figure` with an Agg canvas (``fig.savefig`` / :func:`figure_to_array` work;
        no pyplot state is touched).  All panels share the same cubic axis limits (computed from every frame of
        every sequence), so positions are directly comparable.
    """
    par = check_parents(parents)
    seqs = check_sequences(sequences, par.size)
    up = check_up_axis(up_axis)
    n_frames = max(s.shape[0] for s in seqs.values())
    keys = check_highlight(highlight, n_frames)
    idx = _check_frames(frames, n_frames)
    if layout not in ("overlay", "grid"):
        raise ValueError(f"layout must be 'overlay' or 'grid', got {layout!r}")
    lo, hi = plot_limits(seqs, up)
    plot = {label: to_plot(s, up) for label, s in seqs.items()}
    colors = {label: PALETTE[i % len(PALETTE)] for i, label in enumerate(plot)}

    n_cols = len(plot)
    n_rows = 1 if layout == "overlay" else len(idx)
    height = panel_size * n_rows + (0.4 if title else 0.2)
    fig = new_figure(panel_size * n_cols, height, 100, top=1.0 - (0.7 if title else 0.35) / height)
    for c, (label, seq) in enumerate(plot.items()):
        if layout == "overlay":
            ax = fig.add_subplot(1, n_cols, c + 1, projection="3d")
            shown = f"frames {idx[0]}-{idx[-1]}" if len(idx) > 1 else f"frame {idx[0]}"
            setup_axes(ax, lo, hi, view, f"{label} ({shown})")
            alphas = np.linspace(0.25, 1.0, len(idx)) if len(idx) > 1 else [1.0]
            for t, a in zip(idx, alphas):
                draw_pose(ax, frame_of(seq, t), par, KEY_COLOR if keys[t] else colors[label], float(a))
        else:
            for r, t in enumerate(idx):
                ax = fig.add_subplot(n_rows, n_cols, r * n_cols + c + 1, projection="3d")
                setup_axes(ax, lo, hi, view, f"{label} - frame {t}" + (" (key)" if keys[t] else ""))
                draw_pose(ax, frame_of(seq, t), par, KEY_COLOR if keys[t] else colors[label])
    if keys[idx].any():
        fig.legend(handles=[Line2D([], [], color=KEY_COLOR, lw=2, label="keyframe")], loc="lower right", fontsize=8)
    if title:
        fig.suptitle(title)
    return fig


