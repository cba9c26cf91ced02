"""Drawing skeleton sequences on matplotlib figures (no files): input checks, the camera, the floor, foot trails,
poses, and :func:`draw_sequences`, the filmstrip figure that :mod:`inbetweening.tools.render` saves (its GIF is
drawn with :class:`Panel` too).

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

__all__ = ["CONTACT_COLOR", "DEFAULT_VIEW", "FLOOR_COLOR", "KEY_COLOR", "PALETTE", "Camera", "Panel", "add_legend",
           "add_title", "auto_view", "body_height", "check_contacts", "check_feet", "check_highlight", "check_parents",
           "check_sequences", "check_up_axis", "draw_sequences", "figure_grid", "fit_aspect", "following_window", "frame_of",
           "grid_step", "new_figure", "overlay_columns", "pose_bones", "ring_of", "shared_window", "shift_floor", "to_plot"]

#: One colour per label (red is kept for keyframes, magenta for planted feet).
PALETTE = ("tab:blue", "tab:green", "tab:orange", "tab:purple", "tab:brown", "tab:cyan", "tab:olive", "tab:gray")
#: Colour of keyframes (``highlight``).
KEY_COLOR = "tab:red"
#: Colour of planted feet: the thick part of a foot trail and the marker on the foot.
CONTACT_COLOR = "#e6007e"
#: The floor's fill and grid lines.
FLOOR_COLOR, GRID_COLOR = "#ededed", "#c4c4c4"
#: Camera ``(elevation, azimuth)`` in degrees for a motion that does not travel (the mplot3d convention: the eye at
#: ``(cos e cos a, cos e sin a, sin e)`` in plot space).
DEFAULT_VIEW = (15.0, -60.0)
#: Elevation of the automatic view, and the angle between the travel direction and the screen's x axis (a 3/4 view:
#: the body moves to the right and a little towards the camera, so the two legs do not hide each other).
AUTO_ELEVATION, AUTO_TURN = 16.0, 15.0
#: At most this many grid lines across the floor (a coarser grid beyond).
MAX_GRID_LINES = 40
#: Number of frames shown by :func:`draw_sequences` when ``frames`` is None.
DEFAULT_N_FRAMES = 8
#: Panel aspect ratios (width / height) allowed: a narrower or wider framing is padded.
MIN_ASPECT, MAX_ASPECT = 0.6, 4.0
#: A figure with several panels is kept at most this tall relative to its width.
MAX_HEIGHT_RATIO = 1.0
#: Space (inches) above each panel for its title; the strips for the figure's title and its legend.
PANEL_TITLE_IN, TITLE_IN, LEGEND_IN = 0.22, 0.3, 0.26


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


def check_feet(feet, n_joints: int) -> list[int]:
    """Foot joint indices (``None`` or empty: no trails) -> distinct ints in ``[0, J)``, in the order given."""
    idx = [] if feet is None else [int(f) for f in _to_numpy(feet).reshape(-1)]
    bad = [f for f in idx if not 0 <= f < n_joints]
    if bad:
        raise ValueError(f"feet {bad} are not joint indices in [0, {n_joints})")
    if len(set(idx)) != len(idx):
        raise ValueError(f"feet lists a joint twice: {idx}")
    return idx


def check_contacts(contacts, seqs: Mapping[str, np.ndarray], feet: Sequence[int]) -> dict[str, np.ndarray]:
    """Planted flags -> ``label -> (T_label, K)`` bool, one column per foot of ``feet``.

    ``contacts``: one array for every label, or ``label -> array`` (labels left out get no contact marks); an array
    is ``(T_label, J)`` (every joint; the feet's columns are read) or ``(T_label, K)`` (the feet, in ``feet``'s order),
    of bools (or 0/1)."""
    if contacts is None:
        return {}
    if not feet:
        raise ValueError("contacts given without feet: pass feet=[joint indices] to say which joints they flag")
    given = contacts if isinstance(contacts, Mapping) else dict.fromkeys(seqs, contacts)
    unknown = [label for label in given if label not in seqs]
    if unknown:
        raise ValueError(f"contacts for {unknown}, which are not labels of sequences ({list(seqs)})")
    n_joints = next(iter(seqs.values())).shape[1]
    out = {}
    for label, flags in given.items():
        if flags is None:
            continue
        arr = _to_numpy(flags)
        t = seqs[label].shape[0]
        if arr.ndim != 2 or arr.shape[0] != t or arr.shape[1] not in (n_joints, len(feet)):
            raise ValueError(f"contacts of {label!r} must have shape ({t}, {n_joints}) (every joint) or ({t}, "
                             f"{len(feet)}) (the feet), got {arr.shape}")
        if arr.shape[1] == n_joints and n_joints != len(feet):
            arr = arr[:, list(feet)]
        if arr.dtype != bool:
            if not np.isin(arr, (0, 1)).all():
                raise ValueError(f"contacts of {label!r} must be planted flags (bool or 0/1); threshold a predicted "
                                 f"contact first (inbetweening.tools.foot_lock.THRESHOLD)")
            arr = arr.astype(bool)
        out[label] = arr
    return out


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


def _check_view(view) -> tuple[float, float] | None:
    if view is None:
        return None
    v = tuple(float(x) for x in view)
    if len(v) != 2 or not all(math.isfinite(x) for x in v):
        raise ValueError(f"view must be (elevation, azimuth) in degrees or None (automatic), got {view!r}")
    return v


# --------------------------------------------------------------------------- geometry of the picture


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


def _grid_segments(corners: np.ndarray, step: float) -> np.ndarray:
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
        self.grid.set_segments(list(self.cam.project(_grid_segments(corners, step))))

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


# --------------------------------------------------------------------------- framing and figure layout


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
    idx = _check_frames(frames, n_frames)
    if layout not in ("overlay", "grid"):
        raise ValueError(f"layout must be 'overlay' or 'grid', got {layout!r}")
    if columns is not None and (isinstance(columns, bool) or not isinstance(columns, (int, np.integer))
                                or columns < 1):
        raise ValueError(f"columns must be a positive integer or None, got {columns!r}")
    view = _check_view(view)
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
