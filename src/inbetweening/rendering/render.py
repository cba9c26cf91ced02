"""Headless rendering of skeleton sequences to files and arrays (PNG filmstrips, animated GIFs, arrays for
TensorBoard); the drawing itself is :mod:`inbetweening.rendering.skeleton_plot`'s.

Everything here draws on a :class:`matplotlib.figure.Figure` with its own Agg canvas; ``pyplot`` is never
imported, so the global matplotlib backend is left alone (safe in notebooks, on servers without a display and
inside training loops).  GIFs are written with Pillow, so no ffmpeg / ImageMagick is needed.

Input convention: ``sequences`` maps a label to *global* joint positions of shape ``(T, J, 3)`` (numpy arrays or
torch tensors), e.g. ``{"ground truth": gt, "prediction": pred, "interpolation": lerp}``.  All sequences share the
skeleton (same ``J == len(parents)``); their lengths ``T`` may differ (a shorter one holds its last frame).
``parents[j]`` is the parent joint of ``j`` (``-1`` for the root); bones are drawn as lines child -> parent.

The data axis ``up_axis`` is shown vertically.  The three data axes are shown in cyclic order
``(up + 1, up + 2, up) % 3`` on the plot's ``(x, y, z)``, which keeps right-handed data right-handed (not mirrored).
The pictures are framed on the body over a floor (``floor``, default height 0) with the feet's trails and planted
feet (``feet``, ``contacts``): see :mod:`inbetweening.rendering.skeleton_plot`.
"""
from __future__ import annotations

import io
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from inbetweening.rendering.plot_camera import (
    Camera,
    auto_view,
    body_height,
    fit_aspect,
    following_window,
    grid_step,
    shift_floor,
    to_plot,
)
from inbetweening.rendering.plot_inputs import (
    check_contacts,
    check_feet,
    check_highlight,
    check_parents,
    check_sequences,
    check_up_axis,
)
from inbetweening.rendering.skeleton_plot import (
    KEY_COLOR,
    PALETTE,
    Panel,
    add_legend,
    add_title,
    draw_sequences,
    figure_grid,
    ring_of,
)

__all__ = ["draw_sequences", "figure_to_array", "render_gif", "render_png"]


def render_png(
    sequences: Mapping[str, np.ndarray],
    parents: Sequence[int] | np.ndarray,
    path: str | Path,
    dpi: int = 100,
    **kw,
) -> Path:
    """Save :func:`draw_sequences` ``(sequences, parents, **kw)`` as a PNG at ``path`` (parent dirs created); at the
    default ``dpi`` and ``panel_size`` three labels make a 900 px wide picture.

    Returns the path written.
    """
    fig = draw_sequences(sequences, parents, **kw)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, format="png", dpi=dpi)
    return path


def render_gif(
    sequences: Mapping[str, np.ndarray],
    parents: Sequence[int] | np.ndarray,
    path: str | Path,
    fps: int = 15,
    highlight: np.ndarray | None = None,
    up_axis: int = 1,
    dpi: int = 80,
    *,
    view: tuple[float, float] | None = None,
    panel_size: float = 3.0,
    title: str | None = None,
    feet: Sequence[int] | None = None,
    contacts: Mapping[str, np.ndarray] | np.ndarray | None = None,
    floor: float | None = 0.0,
) -> Path:
    """Write an animated GIF (Pillow, looping) with one image per frame and one panel per label, side by side, each
    panel following its root over the floor (the grid scrolls), the feet's trails growing behind them.

    Args:
        sequences: ``label -> (T, J, 3)`` global joint positions (numpy or torch); shorter sequences hold their
            last frame, so the GIF has ``T_max`` frames.
        parents: ``(J,)`` parent index per joint, ``-1`` for the root.
        path: output file (``.gif``); parent directories are created.
        fps: frames per second (GIF delays have 10 ms resolution).
        highlight: ``(T_max,)`` bool keyframe mask; keyframes are drawn in :data:`KEY_COLOR` and the title
            says ``[key]``.
        up_axis: which data axis points up.
        dpi: resolution; each panel is ``panel_size * dpi`` pixels wide.
        view: camera ``(elevation, azimuth)`` in degrees; ``None``: from the side of the root's travel.
        panel_size: width of one panel in inches.
        title: optional prefix of the per-frame title (which always shows ``frame t/T``).
        feet, contacts, floor: the feet's trails, where they are planted, and the floor height, as in
            :func:`~inbetweening.rendering.skeleton_plot.draw_sequences`.

    Returns:
        The path written.
    """
    if fps <= 0:
        raise ValueError(f"fps must be positive, got {fps}")
    par = check_parents(parents)
    seqs = check_sequences(sequences, par.size)
    up = check_up_axis(up_axis)
    n_frames = max(s.shape[0] for s in seqs.values())
    keys = check_highlight(highlight, n_frames)
    foot = check_feet(feet, par.size)
    planted = check_contacts(contacts, seqs, foot)
    plot = {label: to_plot(s, up) for label, s in seqs.items()}
    colors = {label: PALETTE[i % len(PALETTE)] for i, label in enumerate(plot)}
    every = range(n_frames)
    cam = Camera(*(view or auto_view(plot, par, every)))
    height = body_height(plot)
    step = grid_step(height)
    z = None if floor is None else float(floor)
    rel, rect, centres = following_window(plot, par, every, cam, height, z)
    rel = fit_aspect(rel, lo=0.75, hi=1.6)
    fig, rects = figure_grid(1, len(plot), panel_size, rel, dpi, True, bool(keys.any()) or bool(foot))
    add_legend(fig, bool(keys.any()), bool(foot), bool(planted))
    panels = {label: Panel(fig.add_axes(box), cam, par, colors[label], z, label) for label, box in zip(plot, rects)}
    for label, p in panels.items():
        p.add_pose(plot[label][0], colors[label])
    suptitle = add_title(fig, "")

    images = []
    for t in range(n_frames):
        for label, seq in plot.items():
            p, s = panels[label], min(t, len(seq) - 1)
            centre = centres[label][s]
            p.set_view(rel + np.repeat(cam.project(centre), 2))
            p.set_floor(shift_floor(rect, cam, centre), step)
            flags = planted.get(label)
            if foot:
                p.set_trails(seq[: s + 1][:, foot], None if flags is None else flags[: s + 1])
            p.set_pose(0, seq[s], KEY_COLOR if keys[t] else colors[label], ring_of(flags, foot, s, par.size))
        text = f"frame {t + 1}/{n_frames}" + ("  [key]" if keys[t] else "")
        suptitle.set_text(f"{title}  -  {text}" if title else text)
        suptitle.set_color(KEY_COLOR if keys[t] else "black")
        images.append(_image_from_array(figure_to_array(fig)))

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    images[0].save(
        path,
        format="GIF",
        save_all=True,
        append_images=images[1:],
        duration=max(round(1000.0 / fps), 10),
        loop=0,
    )
    return path


def _image_from_array(rgb: np.ndarray):
    """``(H, W, 3)`` uint8 -> palette PIL image (quantized once here so all GIF frames are encoded consistently)."""
    from PIL import Image

    return Image.fromarray(np.ascontiguousarray(rgb)).quantize(colors=256)


def figure_to_array(fig: Figure) -> np.ndarray:
    """Rasterize a figure to an ``(H, W, 3)`` uint8 RGB array.

    Works for figures from :func:`draw_sequences` (Agg canvas) and for any other figure (e.g. made with pyplot;
    rendered through PNG without changing its canvas).  For TensorBoard use
    ``writer.add_image(tag, figure_to_array(fig), step, dataformats="HWC")``.
    """
    canvas = fig.canvas
    if isinstance(canvas, FigureCanvasAgg):
        canvas.draw()
        return np.array(canvas.buffer_rgba(), dtype=np.uint8)[..., :3]
    from PIL import Image

    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    buf.seek(0)
    with Image.open(buf) as im:
        return np.array(im.convert("RGB"), dtype=np.uint8)
