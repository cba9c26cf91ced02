"""The figure of ``task=retarget``: the source character and the target character side by side (the analytic and the
learned retarget), a few frames of one clip drawn from the side (forward horizontal, up vertical), each row in its own
character's proportions.  A plain matplotlib figure on its own Agg canvas (no pyplot)."""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

__all__ = ["retarget_figure"]

COLORS = ("#1f4e9c", "#2e7d32", "#c62828", "#6a1b9a")


def retarget_figure(rows: Sequence[tuple[str, np.ndarray, Sequence[int]]], frames: Sequence[int], title: str = "",
                    forward: np.ndarray | None = None) -> Figure:
    """``rows``: ``(label, positions (F, J, 3) Y up, parents)`` per character; ``frames``: the frames drawn, each pose
    at its place along the motion's ``forward`` direction (default: the first row's overall travel in XZ)."""
    first = rows[0][1]
    if forward is None:
        travel = first[-1, 0] - first[0, 0]
        forward = np.array([travel[0], travel[2]])
        forward = forward / np.linalg.norm(forward) if np.linalg.norm(forward) > 1e-6 else np.array([0.0, 1.0])
    fig = Figure(figsize=(10, 2.4 * len(rows)), dpi=100)
    FigureCanvasAgg(fig)
    lo = min(float(p[frames][..., 1].min()) for _, p, _ in rows)
    hi = max(float(p[frames][..., 1].max()) for _, p, _ in rows)
    for r, (label, pos, parents) in enumerate(rows):
        ax = fig.add_subplot(len(rows), 1, r + 1)
        h = pos[..., [0, 2]] @ forward  # along the travel
        for k, t in enumerate(frames):
            for j, p in enumerate(parents):
                if p >= 0:
                    ax.plot([h[t, p], h[t, j]], [pos[t, p, 1], pos[t, j, 1]], color=COLORS[r % len(COLORS)],
                            lw=1.6, alpha=0.4 + 0.6 * (k + 1) / len(frames))
        ax.set_aspect("equal")
        ax.set_ylim(lo - 5, hi + 5)
        ax.set_ylabel(label, fontsize=9)
        ax.tick_params(labelsize=7)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig
