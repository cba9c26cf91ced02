"""The window protocol: how clips become windows, in one place (data layer).

The LAFAN1 protocol (Harvey et al. 2020): windows are cut from each clip at ``i = 0, offset, 2*offset, ...`` while
``i + window < len`` (training: 50 frames every 20; test: 65 every 40); the scored windows are normalised
(:func:`centre_and_rotate`: centred in XZ on their mean root XZ, turned about Y so that the root's forward direction
at frame ``n_past - 1`` points to +X); for a transition length ``n`` the first ``n + 20`` frames of a test window are
used: context = frames ``0..n_past-1``, target keyframe = frame ``n_past + n``, transition = ``n_past .. n_past+n-1``.
The training statistics (mean/std of global positions over the normalised training windows) z-score the L2P metric
and the network's position features.

:class:`ClipWindows` cuts training windows on demand at any stride, in the clips' own (world) frame: the predictor
canonicalises every window it sees on its known frames (:meth:`inbetweening.predictor.predictor.Predictor.canonical_frame`);
the whole-window normalisation above is only where the protocol scores (test windows, statistics).

Numpy functions run in float64 so that results match the reference implementation.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from inbetweening.data.mirror import fit_mirror_frames, mirror_motion, mirror_permutation
from inbetweening.geometry.arrays import is_tensor
from inbetweening.geometry.canonical import facing_rotation, masked_mean
from inbetweening.geometry.interp import interpolate_pose
from inbetweening.geometry.kinematics_np import canonical_positions_np, canonicalise_windows_np, column_mean_std, fk_np
from inbetweening.geometry.quaternion import Array, qinv, qmul, qrot
from inbetweening.geometry.skeleton import Skeleton, fk, ik

__all__ = ["N_FUTURE", "N_PAST", "TEST_OFFSET", "TEST_WINDOW", "TRAIN_OFFSET", "TRAIN_WINDOW", "TRANSITION_LENGTHS",
           "BenchmarkSet", "ClipWindows", "canonicalise_windows", "centre_and_rotate", "extract_windows",
           "position_stats", "prepare_windows", "training_stats", "transition_inputs", "window_rows", "window_starts"]

N_PAST = 10
N_FUTURE = 10
TRAIN_WINDOW, TRAIN_OFFSET = 50, 20
TEST_WINDOW, TEST_OFFSET = 65, 40
TRANSITION_LENGTHS = (5, 15, 30, 45)

# ------------------------------------------------------------------------------------------
# Windows
# ------------------------------------------------------------------------------------------
def window_starts(num_frames: int, window: int, offset: int) -> list[int]:
    """Start frames ``0, offset, 2*offset, ...`` while ``start + window < num_frames`` (strict)."""
    if window < 1 or offset < 1:
        raise ValueError(f"window ({window}) and offset ({offset}) must be >= 1")
    return list(range(0, max(num_frames - window, 0), offset))


def extract_windows(clips: Sequence, skeleton: Skeleton, window: int, offset: int) -> tuple[np.ndarray, np.ndarray]:
    """Cut clips into raw (not yet normalised) windows.

    ``clips``: objects with ``root_pos (F, 3)`` and ``local_q (F, J, 4)``.
    Returns local positions ``X (N, window, J, 3)`` (root from the data, other joints = offsets)
    and local quaternions ``Q (N, window, J, 4)``, float64.
    """
    j = skeleton.num_joints
    rows, root, q = window_rows(clips, window, offset)
    if not len(rows):
        return np.zeros((0, window, j, 3)), np.zeros((0, window, j, 4))
    return skeleton.local_positions(root[rows]), q[rows]


def window_rows(clips: Sequence, window: int, offset: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The windows of :func:`extract_windows` as frame indices: ``(rows (N, window), root (F, 3), local_q (F, J, 4))``
    with ``root``/``local_q`` the clips that hold a window, concatenated (float64), and ``rows`` indexing them."""
    used, first, base = [], [], 0
    for clip in clips:  # per clip only its start frames; the windows are gathered in one indexing operation
        s = window_starts(len(clip.root_pos), window, offset)
        if s:
            used.append(clip)
            first.append(base + np.asarray(s, dtype=np.int64))
            base += len(clip.root_pos)
    if not used:
        return np.zeros((0, window), dtype=np.int64), np.zeros((0, 3)), np.zeros((0, 0, 4))
    rows = np.concatenate(first)[:, None] + np.arange(window)[None, :]
    root = np.concatenate([np.asarray(c.root_pos, dtype=np.float64) for c in used])
    return rows, root, np.concatenate([np.asarray(c.local_q, dtype=np.float64) for c in used])


def centre_and_rotate(
    X: Array, Q: Array, parents: Sequence[int], forward_axis: Sequence[float] = (0.0, 1.0, 0.0), n_past: int = N_PAST
) -> tuple[Array, Array]:
    """Normalise windows the way the benchmark does.  ``(B, T, J, 3), (B, T, J, 4) -> same shapes``.

    1. subtract the mean root XZ over the window from the root XZ;
    2. rotate about Y so that the root's ``forward_axis`` (a direction in the root's local frame,
       LAFAN1: +Y) at frame ``n_past - 1``, taken to global space and projected onto XZ, points to +X;
       the rotation is applied to global quaternions/positions which are then taken back to local (IK).
    Works on numpy arrays (float64 recommended) and torch tensors (:func:`canonicalise_windows`).
    """
    return canonicalise_windows(X, Q, parents, forward_axis, n_past - 1)


def prepare_windows(
    clips: Sequence, skeleton: Skeleton, window: int, offset: int, forward_axis: Sequence[float]
) -> tuple[np.ndarray, np.ndarray]:
    """Extract and normalise windows: ``X (N, W, J, 3)`` local positions, ``Q (N, W, J, 4)`` local quats."""
    X, Q = extract_windows(clips, skeleton, window, offset)
    if len(X) == 0:
        return X, Q
    return centre_and_rotate(X, Q, skeleton.parents, forward_axis)


def position_stats(X: np.ndarray, Q: np.ndarray, parents: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """Mean and std ``(J*3,)`` of global joint positions over all windows and frames (per coordinate)."""
    gp = fk_np(Q, X, parents, positions_only=True)  # skeleton.fk's arithmetic, bit for bit, cache-sized chunks
    flat = gp.reshape(-1, gp.shape[-2] * 3)
    return flat.mean(axis=0), flat.std(axis=0)


def training_stats(clips: Sequence, skeleton: Skeleton, window: int, offset: int, forward_axis: Sequence[float],
                   n_past: int = N_PAST, threads: int = 1) -> tuple[np.ndarray, np.ndarray] | None:
    """``position_stats(*prepare_windows(clips, ...), skeleton.parents)``, bit for bit, without materialising the
    windows (chunk by chunk, in ``threads`` threads); ``None`` when no window can be cut."""
    rows, root, q = window_rows(clips, window, offset)
    if not len(rows):
        return None
    gp = canonical_positions_np(root, rows, q, skeleton.offsets, skeleton.parents, forward_axis, n_past - 1,
                                threads=threads)
    return column_mean_std(gp.reshape(-1, gp.shape[-2] * 3), threads=threads)


def canonicalise_windows(X: Array, Q: Array, parents: Sequence[int], forward_axis: Sequence[float],
                         frame: int) -> tuple[Array, Array]:
    """The benchmark's normalisation (LAFAN1 protocol, bit for bit).  ``(B, T, J, 3), (B, T, J, 4) -> same``.

    ``X``/``Q`` are local positions / rotations.  The root XZ is centred on its mean over the whole window, then
    global rotations and positions (FK) are turned so the root faces +X at ``frame`` and taken back to local (IK).
    Numpy windows take :func:`inbetweening.geometry.kinematics_np.canonicalise_windows_np` (the same arithmetic,
    bit-identical, in cache-sized chunks); torch tensors the generic path below.
    """
    if not is_tensor(X) and not is_tensor(Q):
        return canonicalise_windows_np(X, Q, parents, forward_axis, frame)
    return _canonicalise_windows_generic(X, Q, parents, forward_axis, frame)


def _canonicalise_windows_generic(X: Array, Q: Array, parents: Sequence[int], forward_axis: Sequence[float],
                                  frame: int) -> tuple[Array, Array]:
    """:func:`canonicalise_windows` written once for numpy and torch (the definition the fast path is tested against)."""
    X = X.clone() if is_tensor(X) else np.array(X, copy=True)
    xz = masked_mean(X[:, :, 0, 0::2])  # (B, 1, 2)
    X[:, :, 0, 0] = X[:, :, 0, 0] - xz[..., 0]
    X[:, :, 0, 2] = X[:, :, 0, 2] - xz[..., 1]
    gq, gp = fk(Q, X, parents)
    inv = qinv(facing_rotation(gq[:, frame : frame + 1, 0:1, :], forward_axis))
    return ik(qmul(inv, gq), qrot(inv, gp), parents)[::-1]


@dataclass
class BenchmarkSet:
    """Normalised test windows plus the training statistics they are scored with."""

    X: np.ndarray  # (N, W, J, 3) local positions
    Q: np.ndarray  # (N, W, J, 4) local quaternions
    skeleton: Skeleton
    mean: np.ndarray  # (J*3,)
    std: np.ndarray  # (J*3,)

    @property
    def n_windows(self) -> int:
        return int(self.X.shape[0])


def transition_inputs(bench: BenchmarkSet, n: int, n_past: int = N_PAST) -> tuple[np.ndarray, np.ndarray]:
    """What a predictor sees for transition length ``n``: ``root (B, n_past+n+1, 3)``, ``q (B, n_past+n+1, J, 4)``.

    Context frames and the target keyframe carry the data; the ``n`` transition frames are NaN so
    that a predictor which reads them fails loudly instead of scoring with leaked ground truth.
    """
    root = bench.X[:, : n_past + n + 1, 0].copy()
    q = bench.Q[:, : n_past + n + 1].copy()
    root[:, n_past : n_past + n] = np.nan
    q[:, n_past : n_past + n] = np.nan
    return root, q


class ClipWindows:
    """Every ``window``-frame window of ``clips`` starting each ``stride`` frames (as
    :func:`window_starts` counts them), cut when a batch asks for it.

    Args:
        clips: objects with ``root_pos (F, 3)`` and ``local_q (F, J, 4)``.
        mirror: the dataset's left/right joint pairs (``MotionData.mirror``) to allow :meth:`windows` to mirror
            windows; ``None``: no mirroring.
    """

    def __init__(self, clips: Sequence, skeleton: Skeleton, window: int, stride: int,
                 mirror: Sequence[Sequence[str]] | None = None):
        self.skeleton, self.window = skeleton, int(window)
        self.root = np.concatenate([np.asarray(c.root_pos, dtype=np.float64) for c in clips])
        self.q = np.concatenate([np.asarray(c.local_q, dtype=np.float64) for c in clips])
        starts, ends, base = [], [], 0
        for c in clips:
            st = window_starts(c.num_frames, self.window, int(stride))
            starts.extend(base + s for s in st)
            ends.extend(base + c.num_frames for _ in st)
            base += c.num_frames
        self.starts = np.asarray(starts, dtype=np.int64)
        self.ends = np.asarray(ends, dtype=np.int64)  # one past the last frame of each window's clip
        self.mirror = None
        if mirror:
            perm = mirror_permutation(mirror, skeleton.names)
            try:
                frames, _ = fit_mirror_frames(skeleton.offsets, skeleton.parents, perm, self.q[:: max(1, len(self.q) // 20000)])
            except ValueError as e:
                raise ValueError(f"data.mirror: {e}") from None
            self.mirror = (perm, frames)

    def __len__(self) -> int:
        return len(self.starts)

    def max_speed(self, idx: Sequence[int]) -> np.ndarray:
        """``(B,)`` the fastest play-back of each window that stays inside its clip (>= 1)."""
        i = np.asarray(idx, dtype=np.int64)
        return (self.ends[i] - 1 - self.starts[i]) / max(self.window - 1, 1)

    def windows(self, idx: Sequence[int], mirrored: Sequence[bool] | None = None,
                speed: Sequence[float] | np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Windows ``root (B, W, 3), local_q (B, W, J, 4)`` (float64, the clips' own frame) of window numbers ``idx``; those
        flagged in ``mirrored`` are mirrored first (needs ``mirror``).  ``speed (B,)``: play each window that many
        times faster (frame ``i`` is the clip at ``start + i * speed``, root lerp and per-joint slerp between the two
        nearest frames); ``speed (B, 2)``: the play-back speed changes linearly from the first value at the window's
        first frame to the second at its last (a time warp varying within the window).  Either is slowed as a whole
        where it would run past its clip's end (:meth:`max_speed` for a constant speed); ``1`` (or ``None``) cuts the
        frames exactly as they are."""
        i = np.asarray(idx, dtype=np.int64)
        if speed is None:
            frames = self.starts[i][:, None] + np.arange(self.window)[None, :]
            root, q = self.root[frames], self.q[frames]
        else:
            sp = np.asarray(speed, dtype=np.float64).reshape(len(i), -1)
            if sp.shape[1] == 1 or np.array_equal(sp[:, 0], sp[:, -1]):  # constant: frame k at k * speed, exactly
                steps = np.arange(self.window)[None, :] * np.minimum(sp[:, 0], self.max_speed(i))[:, None]
            else:
                ramp = np.linspace(0.0, 1.0, self.window)[None, :]
                rate = sp[:, :1] + (sp[:, -1:] - sp[:, :1]) * ramp  # (B, W) clip frames per frame played
                steps = np.concatenate([np.zeros((len(i), 1)), np.cumsum(0.5 * (rate[:, 1:] + rate[:, :-1]), 1)], 1)
                room = (self.ends[i] - 1 - self.starts[i]).astype(np.float64)
                steps *= np.minimum(1.0, room / np.maximum(steps[:, -1], 1e-12))[:, None]
            t = self.starts[i][:, None] + steps
            f0 = np.minimum(np.floor(t + 1e-9).astype(np.int64), self.ends[i][:, None] - 1)
            f1 = np.minimum(f0 + 1, self.ends[i][:, None] - 1)
            w = np.clip(t - f0, 0.0, 1.0)
            root, q = interpolate_pose(self.root[f0], self.q[f0], self.root[f1], self.q[f1], w)
            exact = w < 1e-9  # whole frames stay bit-exact (slerp renormalises)
            root[exact], q[exact] = self.root[f0[exact]], self.q[f0[exact]]
        if mirrored is not None and np.any(mirrored):
            if self.mirror is None:
                raise ValueError("ClipWindows: mirroring asked for, but no mirror map was given")
            m = np.asarray(mirrored, dtype=bool)
            root[m], q[m] = mirror_motion(root[m], q[m], *self.mirror, self.skeleton.parents)
        return root, q
