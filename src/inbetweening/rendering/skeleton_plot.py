"""Drawing skeleton sequences on matplotlib figures (no files): the floor, foot trails, poses (:class:`Panel`), the
figure's layout and :func:`draw_sequences`, the filmstrip figure that :mod:`inbetweening.rendering.render` saves (its
GIF is drawn with :class:`Panel` too).  Input checks: :mod:`.plot_inputs`; camera and framing: :mod:`.plot_camera`.

Everything draws on a :class:`matplotlib.figure.Figure` with its own Agg canvas; ``pyplot`` is never imported.
Input convention: ``sequences`` maps a label to *global* joint positions ``(T, J, 3)`` (numpy arrays or torch
tensors); all share the skeleton (``J == len(parents)``); a shorter sequence holds its last frame.  The data axis
``up_axis`` is shown vertically; the three data axes are shown in cyclic order ``(up + 1, up + 2, up) % 3`` on the
plot's ``(x, y, z)`` ("plot space", z up), which keeps right-handed data right-handed.

The picture is made to be read small (a README is about 900 px wide): each panel is an orthographic 3-D view drawn
on a plain 2-D axes, framed on the motion (no empty 3-D box, no axes), over a floor at height ``floor`` of the up
axis (the project's data: y = 0, cm) with a grid.  The feet (``feet``: joint indices) leave trails on the floor; where
a foot is planted (``contacts``) its trail is drawn thick in :data:`CONTACT_COLOR`, so a planted foot that stays put
is a dot and one that slides is a streak.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from matplotlib import patheffects
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Polygon

from inbetweening.rendering.plot_camera import (
    MAX_ASPECT,
    MAX_HEIGHT_RATIO,
    MIN_ASPECT,
    Camera,
    auto_view,
    body_height,
    fit_aspect,
    following_window,
    frame_of,
    grid_segments,
    grid_step,
    overlay_columns,
    pose_bones,
    shared_window,
    shift_floor,
    to_plot,
)
from inbetweening.rendering.plot_inputs import (
    check_contacts,
    check_feet,
    check_frames,
    check_highlight,
    check_parents,
    check_sequences,
    check_up_axis,
    check_view,
)

__all__ = ["CONTACT_COLOR", "FLOOR_COLOR", "KEY_COLOR", "PALETTE", "Panel", "add_legend", "add_title", "draw_sequences",
           "figure_grid", "new_figure", "ring_of"]

#: One colour per label (red is kept for keyframes, magenta for planted feet).
PALETTE = ("tab:blue", "tab:green", "tab:orange", "tab:purple", "tab:brown", "tab:cyan", "tab:olive", "tab:gray")
#: Colour of keyframes (``highlight``).
KEY_COLOR = "tab:red"
#: Colour of planted feet: the thick part of a foot trail and the marker on the foot.
CONTACT_COLOR = "#e6007e"
#: The floor's fill and grid lines.
FLOOR_COLOR, GRID_COLOR = "#ededed", "#c4c4c4"
#: Space (inches) above each panel for its title; the strips for the figure's title and its legend.
PANEL_TITLE_IN, TITLE_IN, LEGEND_IN = 0.22, 0.3, 0.26


# --------------------------------------------------------------------------- drawing


def new_figure(width: float, height: float, dpi: float) -> Figure:
    """An empty figure with its own Agg canvas (no pyplot)."""
    fig = Figure(figsize=(width, height), dpi=dpi)
    FigureCanvasAgg(fig)  # attaches itself as fig.canvas
    return fig


_OUTLINE = [patheffects.Stroke(linewidth=3.4, foreground="white"), patheffects.Normal()]


class Panel:
    """One label's panel: a 2-D axes showing plot space through a :class:`Camera`.  Every ``draw_*``/``set_*``
    method draws or replaces one layer (floor, trails, poses), so a GIF updates the same artists frame after frame.

    Layers, bottom to top: the floor (a filled rectangle and its grid), the feet's trails on the floor (thin, the
    label's colour) with the planted stretches over them (thick, :data:`CONTACT_COLOR`), then the poses (bones
    outlined in white and drawn far to near, so crossing limbs stay readable), planted feet ringed."""

    def __init__(self, ax, camera: Camera, parents: np.ndarray, color: str, floor: float | None, title: str = ""):
        self.ax, self.cam, self.parents, self.color, self.floor = ax, camera, parents, color, floor
        ax.set_axis_off()
        ax.set_aspect("equal", adjustable="box")
        if title:
            ax.set_title(title, fontsize=9, pad=3)
        self.floor_patch = Polygon(np.zeros((4, 2)), closed=True, facecolor=FLOOR_COLOR, edgecolor=GRID_COLOR,
                                   lw=0.8, zorder=0, visible=floor is not None)
        ax.add_patch(self.floor_patch)
        self.grid = LineCollection([], colors=GRID_COLOR, linewidths=0.6, zorder=0.5)
        ax.add_collection(self.grid)
        self.grid.set_clip_path(self.floor_patch)
        self.trail = LineCollection([], colors=color, linewidths=1.0, alpha=0.55, zorder=1)
        ax.add_collection(self.trail)
        self.planted = LineCollection([], colors=CONTACT_COLOR, linewidths=3.0, zorder=2, capstyle="round")
        ax.add_collection(self.planted)
        (self.planted_dots,) = ax.plot([], [], "o", color=CONTACT_COLOR, ms=4.0, mew=0, zorder=2)
        self._poses: list[tuple[LineCollection, Line2D, Line2D]] = []

    def set_view(self, bounds: np.ndarray) -> None:
        """Show the screen rectangle ``[xmin, xmax, ymin, ymax]``."""
        self.ax.set_xlim(bounds[0], bounds[1])
        self.ax.set_ylim(bounds[2], bounds[3])

    def set_floor(self, rect, step: float) -> None:
        """The floor rectangle ``(u0, u1, v0, v1)`` (the camera's floor coordinates, :meth:`Camera.on_floor`) with
        grid lines every ``step``."""
        if self.floor is None:
            return
        corners = self.cam.floor_corners(rect, self.floor)
        self.floor_patch.set_xy(self.cam.project(corners))
        self.grid.set_segments(list(self.cam.project(grid_segments(corners, step))))

    def set_trails(self, feet_path: np.ndarray, planted: np.ndarray | None) -> None:
        """``feet_path (T, K, 3)``: the feet's positions, drawn on the floor; ``planted (T, K)`` bool: the stretches
        drawn thick where the foot is planted at both ends (a foot that holds still: a dot)."""
        z = self.floor if self.floor is not None else float(feet_path[..., 2].min())
        on_floor = feet_path.copy()
        on_floor[..., 2] = z
        xy = self.cam.project(on_floor)  # (T, K, 2)
        self.trail.set_segments([xy[:, k] for k in range(xy.shape[1])] if len(xy) > 1 else [])
        if planted is None or len(xy) == 0:
            self.planted.set_segments([])
            self.planted_dots.set_data([], [])
            return
        both = planted[:-1] & planted[1:]  # (T-1, K)
        t, k = np.nonzero(both)
        self.planted.set_segments(list(np.stack([xy[t, k], xy[t + 1, k]], axis=1)))
        dots = xy[planted]
        self.planted_dots.set_data(dots[:, 0], dots[:, 1])

    def add_pose(self, pose: np.ndarray, color: str, alpha: float = 1.0, planted=None, zorder: float = 3.0) -> None:
        """Draw one ``(J, 3)`` plot-space pose; ``planted``: ``(J,)`` bool, joints ringed in :data:`CONTACT_COLOR`."""
        bones = LineCollection([], linewidths=2.0, alpha=alpha, zorder=zorder, capstyle="round")
        bones.set_path_effects(_OUTLINE)
        self.ax.add_collection(bones)
        (joints,) = self.ax.plot([], [], "o", ms=2.4, mew=0, alpha=alpha, zorder=zorder + 0.01)
        (rings,) = self.ax.plot([], [], "o", ms=6.5, mfc="none", mec=CONTACT_COLOR, mew=1.6, zorder=zorder + 0.02)
        self._poses.append((bones, joints, rings))
        self.set_pose(len(self._poses) - 1, pose, color, planted)

    def set_pose(self, i: int, pose: np.ndarray, color: str, planted=None) -> None:
        """Replace pose ``i`` (see :meth:`add_pose`)."""
        bones, joints, rings = self._poses[i]
        segs = pose_bones(pose, self.parents)
        order = np.argsort(self.cam.depth(segs.mean(axis=1)))  # far first
        bones.set_segments(list(self.cam.project(segs[order])))
        bones.set_color(color)
        xy = self.cam.project(pose)
        joints.set_data(xy[:, 0], xy[:, 1])
        joints.set_color(color)
        ring = xy[np.asarray(planted, dtype=bool)] if planted is not None else np.zeros((0, 2))
        rings.set_data(ring[:, 0], ring[:, 1])

def _panel_rects(fig_w: float, rows: int, cols: int, panel_w: float, panel_h: float, top: float, bottom: float):
    """``(figure height, axes rectangles in figure fractions)``, row-major, for a ``rows x cols`` grid of panels
    (each with room for its title) between ``top`` and ``bottom`` inches of margin."""
    fig_h = top + rows * (panel_h + PANEL_TITLE_IN) + bottom
    rects = []
    for r in range(rows):
        for c in range(cols):
            y = fig_h - top - PANEL_TITLE_IN - (r + 1) * panel_h - r * PANEL_TITLE_IN
            rects.append([c * panel_w / fig_w, y / fig_h, panel_w / fig_w, panel_h / fig_h])
    return fig_h, rects


def figure_grid(rows: int, cols: int, panel_w: float, bounds: np.ndarray, dpi: float, title: bool, legend: bool):
    """A new figure of ``rows x cols`` panels ``panel_w`` inches wide whose height follows the screen ``bounds``'
    aspect, with a strip for the title (``title``) and one for the legend (``legend``): ``(figure, rectangles)``."""
    panel_h = panel_w * (bounds[3] - bounds[2]) / (bounds[1] - bounds[0])
    top, bottom = (TITLE_IN if title else 0.04), (LEGEND_IN if legend else 0.04)
    fig_h, rects = _panel_rects(panel_w * cols, rows, cols, panel_w, panel_h, top, bottom)
    return new_figure(panel_w * cols, fig_h, dpi), rects


def add_legend(fig: Figure, keys: bool, trails: bool, contacts: bool) -> bool:
    """The legend along the figure's bottom edge: what red poses, thin and thick trails mean (those drawn)."""
    handles = []
    if keys:
        handles.append(Line2D([], [], color=KEY_COLOR, lw=2, label="keyframe"))
    if trails:
        handles.append(Line2D([], [], color="0.45", lw=1, label="foot trail"))
    if contacts:
        handles.append(Line2D([], [], color=CONTACT_COLOR, lw=3, marker="o", ms=4, label="foot planted (streak: "
                              "sliding)"))
    if handles:
        fig.legend(handles=handles, loc="lower center", fontsize=7, ncol=len(handles), frameon=False,
                   bbox_to_anchor=(0.5, 0.0), handlelength=1.6, borderaxespad=0.1, columnspacing=1.2)
    return bool(handles)


def add_title(fig: Figure, title: str, color: str = "black"):
    """The figure title, left-aligned in the top strip."""
    return fig.suptitle(title, fontsize=9.5, x=0.01, y=1.0 - 0.05 / fig.get_figheight(), ha="left", va="top",
                        color=color)


def ring_of(flags: np.ndarray | None, feet: Sequence[int], t: int, n_joints: int) -> np.ndarray | None:
    """``(J,)`` bool: the feet planted at frame ``t`` (a shorter sequence holds its last frame); None without flags."""
    if flags is None:
        return None
    out = np.zeros(n_joints, dtype=bool)
    out[list(feet)] = flags[min(t, len(flags) - 1)]
    return out


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
    view: tuple[float, float] | None = None,
    panel_size: float = 3.0,
    columns: int | None = None,
    feet: Sequence[int] | None = None,
    contacts: Mapping[str, np.ndarray] | np.ndarray | None = None,
    floor: float | None = 0.0,
) -> Figure:
    """Draw skeleton sequences, one panel per label, on a headless (Agg) figure.

    Args:
        sequences: ``label -> (T, J, 3)`` global joint positions (numpy or torch); ``T`` may differ per label
            (a shorter sequence holds its last frame), ``J`` must equal ``len(parents)``.
        parents: ``(J,)`` parent index per joint, ``-1`` for the root.
        frames: frame indices to show (``0 <= t < T_max``); default: up to 8 evenly spaced frames, first and last
            included.
        up_axis: which data axis points up (1 for Y-up data such as this project's, 2 for Z-up); it is shown
            vertically.
        highlight: ``(T_max,)`` bool mask of keyframes, drawn in :data:`KEY_COLOR` instead of the label's colour.
        title: figure title.
        layout: ``"overlay"`` (a filmstrip: the selected frames drawn in one panel per label, opacity increasing
            with time, the feet's trails from the first to the last selected frame) or ``"grid"`` (one row per
            selected frame, each panel following the root, the trails up to that frame).
        view: camera ``(elevation, azimuth)`` in degrees; ``None``: from the side of the root's travel
            (:func:`auto_view`).
        panel_size: the width of one panel in inches when the panels stand side by side: the figure is
            ``panel_size * len(sequences)`` inches wide (3 panels of 3 inches at 100 dpi: a 900 px picture).
        columns: panels per row of the overlay layout; ``None``: side by side, or stacked when the motion is much
            wider than tall (:func:`overlay_columns`).
        feet: foot joint indices: their paths are drawn on the floor.
        contacts: where the feet are planted: one array for every label or ``label -> array`` (see
            :func:`check_contacts`); a planted stretch of a trail is drawn thick in :data:`CONTACT_COLOR` and the
            planted feet of the last pose are ringed.
        floor: the floor's height on the up axis, drawn with a grid; ``None``: no floor.

    Returns:
        A :class:`matplotlib.figure.Figure` with an Agg canvas (``fig.savefig`` / ``figure_to_array`` work; no
        pyplot state is touched).  Overlay: every panel shows the same region (every selected frame of every
        sequence, and the frames between), so positions are directly comparable.  Grid: every panel has the same
        size, centred on its root.
    """
    par = check_parents(parents)
    seqs = check_sequences(sequences, par.size)
    up = check_up_axis(up_axis)
    n_frames = max(s.shape[0] for s in seqs.values())
    keys = check_highlight(highlight, n_frames)
    idx = check_frames(frames, n_frames)
    if layout not in ("overlay", "grid"):
        raise ValueError(f"layout must be 'overlay' or 'grid', got {layout!r}")
    if columns is not None and (isinstance(columns, bool) or not isinstance(columns, (int, np.integer))
                                or columns < 1):
        raise ValueError(f"columns must be a positive integer or None, got {columns!r}")
    view = check_view(view)
    foot = check_feet(feet, par.size)
    planted = check_contacts(contacts, seqs, foot)
    plot = {label: to_plot(s, up) for label, s in seqs.items()}
    colors = {label: PALETTE[i % len(PALETTE)] for i, label in enumerate(plot)}
    cam = Camera(*(view or auto_view(plot, par, idx)))
    height = body_height(plot)
    step = grid_step(height)
    z = None if floor is None else float(floor)
    legend = bool(keys[idx].any()) or bool(foot)
    n = len(plot)

    if layout == "overlay":
        bounds, rect = shared_window(plot, idx, cam, height, z)
        aspect = (bounds[1] - bounds[0]) / (bounds[3] - bounds[2])
        cols = min(int(columns), n) if columns is not None else overlay_columns(n, aspect)
        rows = math.ceil(n / cols)
        panel_w = panel_size * n / cols
        lo = max(MIN_ASPECT, rows / (MAX_HEIGHT_RATIO * cols)) if n > 1 else MIN_ASPECT
        bounds = fit_aspect(bounds, lo=lo, hi=max(lo, MAX_ASPECT))
        fig, rects = figure_grid(rows, cols, panel_w, bounds, 100, bool(title), legend)
        shown = f"frames {idx[0]}-{idx[-1]}" if len(idx) > 1 else f"frame {idx[0]}"
        alphas = np.linspace(0.3, 1.0, len(idx)) if len(idx) > 1 else [1.0]
        for (label, seq), box in zip(plot.items(), rects):
            p = Panel(fig.add_axes(box), cam, par, colors[label], z, f"{label} ({shown})")
            p.set_view(bounds)
            p.set_floor(rect, step)
            flags = planted.get(label)
            if foot:
                a, b = min(min(idx), len(seq) - 1), min(max(idx), len(seq) - 1)
                p.set_trails(seq[a : b + 1][:, foot], None if flags is None else flags[a : b + 1])
            for i, (t, alpha) in enumerate(zip(idx, alphas)):
                ring = ring_of(flags, foot, t, par.size) if i == len(idx) - 1 else None
                p.add_pose(frame_of(seq, t), KEY_COLOR if keys[t] else colors[label], float(alpha), ring,
                           zorder=3.0 + 0.1 * i)
    else:
        rel, rect0, centres = following_window(plot, par, idx, cam, height, z)
        rel = fit_aspect(rel, lo=0.75, hi=1.6)
        fig, rects = figure_grid(len(idx), n, panel_size, rel, 100, bool(title), legend)
        for r, t in enumerate(idx):
            for c, (label, seq) in enumerate(plot.items()):
                name = f"{label} - frame {t}" + (" (key)" if keys[t] else "")
                p = Panel(fig.add_axes(rects[r * n + c]), cam, par, colors[label], z, name)
                centre = centres[label][min(t, len(seq) - 1)]
                p.set_view(rel + np.repeat(cam.project(centre), 2))
                p.set_floor(shift_floor(rect0, cam, centre), step)
                flags = planted.get(label)
                if foot:
                    b = min(t, len(seq) - 1)
                    p.set_trails(seq[: b + 1][:, foot], None if flags is None else flags[: b + 1])
                p.add_pose(frame_of(seq, t), KEY_COLOR if keys[t] else colors[label], 1.0,
                           ring_of(flags, foot, t, par.size))
    add_legend(fig, bool(keys[idx].any()), bool(foot), bool(planted))
    if title:
        add_title(fig, title)
    return fig
