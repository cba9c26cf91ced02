"""The geometry of a skeleton picture: plot space, the orthographic :class:`Camera`, the automatic view, the
floor's grid and rectangle, and the framing of panels (shared or following the root).  No drawing: see
:mod:`inbetweening.rendering.skeleton_plot`."""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

__all__ = ["AUTO_ELEVATION", "AUTO_TURN", "DEFAULT_VIEW", "MAX_ASPECT", "MAX_GRID_LINES", "MAX_HEIGHT_RATIO", "MIN_ASPECT",
           "Camera", "auto_view", "body_height", "fit_aspect", "following_window", "frame_of", "grid_segments", "grid_step",
           "overlay_columns", "pose_bones", "shared_window", "shift_floor", "to_plot"]

#: Camera ``(elevation, azimuth)`` in degrees for a motion that does not travel (the mplot3d convention: the eye at
#: ``(cos e cos a, cos e sin a, sin e)`` in plot space).
DEFAULT_VIEW = (15.0, -60.0)
#: Elevation of the automatic view, and the angle between the travel direction and the screen's x axis (a 3/4 view:
#: the body moves to the right and a little towards the camera, so the two legs do not hide each other).
AUTO_ELEVATION, AUTO_TURN = 16.0, 15.0
#: At most this many grid lines across the floor (a coarser grid beyond).
MAX_GRID_LINES = 40
#: Panel aspect ratios (width / height) allowed: a narrower or wider framing is padded.
MIN_ASPECT, MAX_ASPECT = 0.6, 4.0
#: A figure with several panels is kept at most this tall relative to its width.
MAX_HEIGHT_RATIO = 1.0


def to_plot(pos: np.ndarray, up_axis: int) -> np.ndarray:
    """Reorder data axes ``(..., 3)`` so that ``up_axis`` becomes the plot's z (cyclic: handedness preserved)."""
    return pos[..., [(up_axis + 1) % 3, (up_axis + 2) % 3, up_axis]]


def frame_of(seq: np.ndarray, t: int) -> np.ndarray:
    """Frame ``t`` of ``(T, J, 3)``; shorter sequences hold their last frame."""
    return seq[min(t, seq.shape[0] - 1)]


def pose_bones(pose: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """``(J, 3)`` pose -> ``(B, 2, 3)`` segments child -> parent (roots skipped)."""
    child = np.nonzero(parents >= 0)[0]
    return np.stack([pose[child], pose[parents[child]]], axis=1)


class Camera:
    """An orthographic camera at ``elevation`` / ``azimuth`` degrees (mplot3d's convention) looking at plot space
    (z up): :meth:`project` gives screen ``(x right, y up)`` in plot units, :meth:`depth` the distance towards the
    camera (larger: nearer)."""

    def __init__(self, elevation: float, azimuth: float):
        self.elevation, self.azimuth = float(elevation), float(azimuth)
        e, a = math.radians(self.elevation), math.radians(self.azimuth)
        right = [-math.sin(a), math.cos(a), 0.0]
        up = [-math.sin(e) * math.cos(a), -math.sin(e) * math.sin(a), math.cos(e)]
        self.towards = np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
        self.screen = np.array([right, up]).T  # (3, 2)
        self.floor_axes = np.array([right, [math.cos(a), math.sin(a), 0.0]]).T  # (3, 2): right, towards the camera

    def project(self, pts: np.ndarray) -> np.ndarray:
        """``(..., 3)`` plot-space points -> ``(..., 2)`` screen coordinates."""
        return np.asarray(pts) @ self.screen

    def depth(self, pts: np.ndarray) -> np.ndarray:
        """``(..., 3)`` -> ``(...)``: larger is nearer the camera."""
        return np.asarray(pts) @ self.towards

    def on_floor(self, pts: np.ndarray) -> np.ndarray:
        """``(..., 3)`` -> ``(..., 2)`` floor coordinates: along the screen's x axis, and towards the camera."""
        return np.asarray(pts) @ self.floor_axes

    def floor_corners(self, rect, z: float) -> np.ndarray:
        """``(4, 3)`` plot-space corners of the floor rectangle ``rect = (u0, u1, v0, v1)`` (floor coordinates) at
        height ``z``: it is seen as a screen-aligned rectangle."""
        u0, u1, v0, v1 = rect
        uv = np.array([[u0, v0], [u1, v0], [u1, v1], [u0, v1]])
        corners = uv @ self.floor_axes.T  # both axes are horizontal: z = 0
        corners[:, 2] = z
        return corners


def body_height(plot_seqs: Mapping[str, np.ndarray]) -> float:
    """The body's size: the median over frames of the joints' vertical extent (plot z), over every sequence; at
    least a tiny positive number (a flat or single-joint pose still gets a picture)."""
    ext = np.concatenate([np.ptp(s[..., 2], axis=-1) for s in plot_seqs.values()])
    h = float(np.median(ext))
    if h <= 0:  # a flat pose: its size on the floor instead
        h = float(np.median(np.concatenate([np.ptp(s[..., :2], axis=-2).max(axis=-1) for s in plot_seqs.values()])))
    if h <= 0:  # every joint at one point: a tenth of the motion's extent, else 1
        h = 0.1 * float(max(np.ptp(s.reshape(-1, 3), axis=0).max() for s in plot_seqs.values()))
    return h if h > 0 else 1.0


def auto_view(plot_seqs: Mapping[str, np.ndarray], parents: np.ndarray, frames: Sequence[int]) -> tuple[float, float]:
    """A camera for the motion: seen from its side, the travel direction of the root (the first root joint, from
    the first to the last of ``frames``, averaged over the sequences) turned :data:`AUTO_TURN` degrees from the
    screen's x axis towards the camera; :data:`DEFAULT_VIEW` when the root travels less than half the body's
    size."""
    root = int(np.flatnonzero(parents < 0)[0])
    a, b = min(frames), max(frames)
    travel = np.mean([frame_of(s, b)[root, :2] - frame_of(s, a)[root, :2] for s in plot_seqs.values()], axis=0)
    if float(np.hypot(*travel)) < 0.5 * body_height(plot_seqs):
        return DEFAULT_VIEW
    heading = math.degrees(math.atan2(travel[1], travel[0]))
    return AUTO_ELEVATION, (heading - 90.0 + AUTO_TURN + 180.0) % 360.0 - 180.0


def grid_step(size: float) -> float:
    """A round floor-grid spacing (1, 2 or 5 times a power of ten) of about a third of ``size``."""
    raw = max(size, 1e-9) / 3.0
    p = 10.0 ** math.floor(math.log10(raw))
    return min((m * p for m in (1.0, 2.0, 5.0, 10.0)), key=lambda s: abs(math.log(s / raw)))


def _floor_rect(points: np.ndarray, cam: Camera, pad: float) -> tuple[float, float, float, float]:
    """``(u0, u1, v0, v1)``: the floor under ``(..., 3)`` points in ``cam``'s floor coordinates, ``pad`` beyond."""
    uv = cam.on_floor(points.reshape(-1, 3))
    (u0, v0), (u1, v1) = uv.min(axis=0) - pad, uv.max(axis=0) + pad
    return float(u0), float(u1), float(v0), float(v1)


def grid_segments(corners: np.ndarray, step: float) -> np.ndarray:
    """``(N, 2, 3)``: grid lines of the floor at plot x and y multiples of ``step`` (world-fixed: they scroll under
    a moving view) across the bounding box of the floor's ``(4, 3)`` corners (the floor patch clips them)."""
    (x0, y0, z), (x1, y1, _) = corners.min(axis=0), corners.max(axis=0)
    while max(x1 - x0, y1 - y0) > MAX_GRID_LINES * step:  # a floor far larger than the body: a coarser grid
        step *= 10.0
    segs = [[[x, y0, z], [x, y1, z]] for x in np.arange(math.ceil(x0 / step), math.floor(x1 / step) + 1) * step]
    segs += [[[x0, y, z], [x1, y, z]] for y in np.arange(math.ceil(y0 / step), math.floor(y1 / step) + 1) * step]
    return np.array(segs, dtype=np.float64).reshape(-1, 2, 3)


def _bounds(pts2d: np.ndarray) -> np.ndarray:
    """``[xmin, xmax, ymin, ymax]`` of ``(..., 2)`` screen points."""
    p = pts2d.reshape(-1, 2)
    return np.array([p[:, 0].min(), p[:, 0].max(), p[:, 1].min(), p[:, 1].max()])


def fit_aspect(bounds: np.ndarray, lo: float = MIN_ASPECT, hi: float = MAX_ASPECT) -> np.ndarray:
    """Screen bounds padded (width or height, about the centre) to an aspect ratio in ``[lo, hi]``."""
    x0, x1, y0, y1 = bounds
    w, h = x1 - x0, y1 - y0
    if w < lo * h:
        d = (lo * h - w) / 2
        x0, x1 = x0 - d, x1 + d
    elif w > hi * h:
        d = (w / hi - h) / 2
        y0, y1 = y0 - d, y1 + d
    return np.array([x0, x1, y0, y1])


def overlay_columns(n_panels: int, aspect: float) -> int:
    """How many columns of panels: among the divisors of ``n_panels`` (no empty cell), the one that draws the body
    biggest within a figure at most :data:`MAX_HEIGHT_RATIO` as tall as wide (panels of aspect ``aspect``, or
    padded wider to fit), preferring fewer rows unless more draw it at least 1.5 times bigger."""
    best, best_scale = n_panels, 0.0
    for c in sorted((c for c in range(1, n_panels + 1) if n_panels % c == 0), reverse=True):
        rows = n_panels // c
        width, max_height = 1.0 / c, MAX_HEIGHT_RATIO * n_panels / rows  # in units of one side-by-side panel width
        scale = min(width * n_panels / aspect, max_height)  # the panel's height, which the body fills
        if scale > 1.5 * best_scale:
            best, best_scale = c, scale
    return best



def _floor_on(pts: np.ndarray, z: float) -> np.ndarray:
    """``pts (..., 3)`` dropped onto the floor ``z``, as ``(N, 3)``."""
    out = pts.reshape(-1, 3).copy()
    out[:, 2] = z
    return out


def shift_floor(rect, cam: Camera, centre: np.ndarray):
    """A floor rectangle ``(u0, u1, v0, v1)`` given relative to ``centre`` (plot space), made absolute."""
    u, v = cam.on_floor(centre)
    return rect[0] + u, rect[1] + u, rect[2] + v, rect[3] + v


def shared_window(plot_seqs: Mapping[str, np.ndarray], frames: Sequence[int], cam: Camera, height: float,
                  floor: float | None):
    """The overlay's framing, one for every panel: ``(screen bounds, floor rectangle)`` around every frame from the
    first to the last of ``frames`` of every sequence, the floor ``0.15 * height`` beyond the body."""
    span = range(min(frames), max(frames) + 1)
    pts = np.concatenate([np.stack([frame_of(s, t) for t in span]).reshape(-1, 3) for s in plot_seqs.values()])
    rect = _floor_rect(pts, cam, 0.15 * height)
    if floor is not None:
        pts = np.concatenate([pts, cam.floor_corners(rect, floor)])
    return _bounds(cam.project(pts)) + np.array([-1, 1, -1, 1]) * 0.03 * height, rect


def following_window(plot_seqs: Mapping[str, np.ndarray], parents: np.ndarray, frames: Sequence[int], cam: Camera,
                     height: float, floor: float | None):
    """A framing that follows the root: ``(screen bounds relative to the centre, floor rectangle relative to the
    centre, centres)``, ``centres[label]`` being ``(T_label, 3)``, the root joint dropped on the floor (kept at its
    height without one).  One size for every panel and frame: the bounds hold every pose of ``frames`` around its
    centre."""
    root = int(np.flatnonzero(parents < 0)[0])
    centres = {}
    rel, around_all = [], []
    for label, s in plot_seqs.items():
        c = s[:, root].copy()
        if floor is not None:
            c[:, 2] = floor
        centres[label] = c
        ts = sorted({min(t, len(s) - 1) for t in frames})
        around = s[ts] - c[ts, None]  # (F, J, 3)
        rel.append(_bounds(cam.project(around if floor is None else np.concatenate(
            [around.reshape(-1, 3), _floor_on(around, 0.0)]))))
        around_all.append(around.reshape(-1, 3))
    rel = np.stack(rel)
    bounds = np.array([rel[:, 0].min(), rel[:, 1].max(), rel[:, 2].min(), rel[:, 3].max()])
    rect = _floor_rect(np.concatenate(around_all), cam, 0.4 * height)
    if floor is not None:  # the floor's far edge in the picture too
        bounds[3] = max(bounds[3], float(cam.project(cam.floor_corners(rect, 0.0))[:, 1].max()))
    return bounds + np.array([-1, 1, -1, 1]) * 0.08 * height, rect, centres
