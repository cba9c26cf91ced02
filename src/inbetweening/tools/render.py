"""Headless rendering of skeleton sequences to files and arrays (PNG filmstrips, animated GIFs, arrays for
TensorBoard); the drawing itself is :mod:`inbetweening.tools.skeleton_plot`'s.

Everything here draws on a :class:`matplotlib.figure.Figure` with its own Agg canvas; ``pyplot`` is never
imported, so the global matplotlib backend is left alone (safe in notebooks, on servers without a display and
inside training loops).  GIFs are written with Pillow, so no ffmpeg / ImageMagick is needed.

Input convention: ``sequences`` maps a label to *global* joint positions of shape ``(T, J, 3)`` (numpy arrays or
torch tensors), e.g. ``{"ground truth": gt, "prediction": pred, "interpolation": lerp}``.  All sequences share the
skeleton (same ``J == len(parents)``); their lengths ``T`` may differ (a shorter one holds its last frame).
``parents[j]`` is the parent joint of ``j`` (``-1`` for the root); bones are drawn as lines child -> parent.

The data axis ``up_axis`` is shown vertically.  The three data axes are shown in cyclic order
``(up + 1, up + 2, up) % 3`` on the plot's ``(x, y, z)``, which keeps right-handed data right-handed (not mirrored).
"""
from __future__ import annotations

import io
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from inbetweening.tools.skeleton_plot import (
    DEFAULT_VIEW,
    KEY_COLOR,
    PALETTE,
    check_highlight,
    check_parents,
    check_sequences,
    check_up_axis,
    draw_pose,
    draw_sequences,
    frame_of,
    new_figure,
    plot_limits,
    pose_bones,
    setup_axes,
    to_plot,
)

__all__ = ["draw_sequences", "figure_to_array", "render_gif", "render_png"]


def render_png(
    sequences: Mapping[str, np.ndarray],
    parents: Sequence[int] | np.ndarray,
    path: str | Path,
    dpi: int = 100,
    **kw,
) -> Path:
    """Save :func:`draw_sequences` ``(sequences, parents, **kw)`` as a PNG at ``path`` (parents dirs created).

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
    view: tuple[float, float] = DEFAULT_VIEW,
    panel_size: float = 3.0,
    title: str | None = None,
) -> Path:
    """Write an animated GIF (Pillow, looping) with one image per frame and one panel per label, side by side.

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
        view: camera ``(elevation, azimuth)`` in degrees.
        panel_size: size of one panel in inches.
        title: optional prefix of the per-frame title (which always shows ``frame t/T``).

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
    lo, hi = plot_limits(seqs, up)
    plot = {label: to_plot(s, up) for label, s in seqs.items()}
    colors = {label: PALETTE[i % len(PALETTE)] for i, label in enumerate(plot)}

    fig = new_figure(panel_size * len(plot), panel_size + 0.3, dpi, top=1.0 - 0.45 / (panel_size + 0.3))
    artists = {}
    for c, (label, seq) in enumerate(plot.items()):
        ax = fig.add_subplot(1, len(plot), c + 1, projection="3d")
        setup_axes(ax, lo, hi, view, label)
        artists[label] = draw_pose(ax, seq[0], par, colors[label])
    suptitle = fig.suptitle("")

    images = []
    for t in range(n_frames):
        for label, seq in plot.items():
            pose = frame_of(seq, t)
            color = KEY_COLOR if keys[t] else colors[label]
            lines, joints = artists[label]
            lines.set_segments(pose_bones(pose, par))
            lines.set_color(color)
            joints.set_data_3d(pose[:, 0], pose[:, 1], pose[:, 2])
            joints.set_color(color)
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
