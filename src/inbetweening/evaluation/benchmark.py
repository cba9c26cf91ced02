"""The standard in-betweening benchmark (Harvey et al. 2020, LAFAN1 protocol), as reusable functions.

Windows are cut from each clip at ``i = 0, offset, 2*offset, ...`` while ``i + window < len``;
each window is centred in XZ on its mean root XZ, then rotated about Y so that the root's forward
direction at frame ``n_past - 1`` points to +X.  For a transition length ``n`` the first ``n + 20``
frames of a test window are used: context = frames 0..9, target keyframe = frame ``10 + n``,
evaluated frames = ``10 .. 9 + n``.

Metrics (all on FK of local quaternions with the skeleton offsets for non-root joints):

* L2Q  - per frame the L2 norm over all joints' global quaternion 4-vectors of ``pred - gt``, mean.
* L2P  - global positions z-scored with the training statistics, per frame L2 norm, mean.
* NPSS - normalised power spectrum similarity on flattened global quaternions.

Numpy functions run in float64 so that results match the reference implementation; the window
normalisation (:func:`centre_and_rotate`) also accepts torch tensors, for the training pipeline.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from inbetweening.geometry.canonical import canonicalise_windows
from inbetweening.geometry.fastkin import canonical_positions_np, column_mean_std, fk_np
from inbetweening.geometry.interp import interpolate_pose
from inbetweening.geometry.quaternion import Array
from inbetweening.geometry.skeleton import Skeleton

N_PAST = 10
N_FUTURE = 10
TRAIN_WINDOW, TRAIN_OFFSET = 50, 20
TEST_WINDOW, TEST_OFFSET = 65, 40
TRANSITION_LENGTHS = (5, 15, 30, 45)

# predictor(root (B, n+11, 3), local_q (B, n+11, J, 4), n) -> (root (B, n, 3), local_q (B, n, J, 4))
Predictor = Callable[[np.ndarray, np.ndarray, int], tuple[np.ndarray, np.ndarray]]


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
    Works on numpy arrays (float64 recommended) and torch tensors
    (:func:`inbetweening.geometry.canonical.canonicalise_windows`).
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


# ------------------------------------------------------------------------------------------
# Metrics
# ------------------------------------------------------------------------------------------
def l2q(pred_gq: np.ndarray, gt_gq: np.ndarray) -> float:
    """Mean over windows and frames of the L2 norm over all joints of global quaternion differences.

    ``(B, T, J, 4), (B, T, J, 4) -> float`` (no sign alignment, as in the reference).
    """
    return float(np.mean(np.sqrt(np.sum((pred_gq - gt_gq) ** 2, axis=(2, 3)))))


def l2p(pred_gp: np.ndarray, gt_gp: np.ndarray, mean: np.ndarray, std: np.ndarray) -> float:
    """Mean per-frame L2 norm of z-scored global positions.  ``(B, T, J, 3) x2, (J*3,) x2 -> float``."""
    b, t = gt_gp.shape[:2]
    p = (pred_gp.reshape(b, t, -1) - mean) / std
    g = (gt_gp.reshape(b, t, -1) - mean) / std
    return float(np.mean(np.sqrt(np.sum((p - g) ** 2, axis=-1))))


def npss(gt_seq: np.ndarray, pred_seq: np.ndarray) -> float:
    """Normalised Power Spectrum Similarity (Gopalakrishnan et al. 2019), reference formulation.

    ``gt_seq, pred_seq: (B, T, D)``.  Power = square of the real part of the FFT along time,
    normalised per dimension by its total; L1 distance of the cumulative sums; average weighted by
    the ground truth's total power per dimension.
    """
    gt_power = np.square(np.real(np.fft.fft(gt_seq, axis=1)))
    pred_power = np.square(np.real(np.fft.fft(pred_seq, axis=1)))
    gt_total = gt_power.sum(axis=1)
    pred_total = pred_power.sum(axis=1)
    gt_cdf = np.cumsum(gt_power / gt_total[:, None, :], axis=1)
    pred_cdf = np.cumsum(pred_power / pred_total[:, None, :], axis=1)
    emd = np.abs(pred_cdf - gt_cdf).sum(axis=1)
    return float(np.average(emd, weights=gt_total))


# ------------------------------------------------------------------------------------------
# Baselines
# ------------------------------------------------------------------------------------------
def zero_velocity(root: np.ndarray, local_q: np.ndarray, n: int, n_past: int = N_PAST):
    """Repeat the last context frame.  ``(B, T, 3), (B, T, J, 4), n -> (B, n, 3), (B, n, J, 4)``."""
    r = np.repeat(root[:, n_past - 1 : n_past], n, axis=1)
    q = np.repeat(local_q[:, n_past - 1 : n_past], n, axis=1)
    return r, q


def interpolation(root: np.ndarray, local_q: np.ndarray, n: int, n_past: int = N_PAST):
    """Root lerp and local-quaternion slerp between frame ``n_past - 1`` and the target ``n_past + n``.

    Weights ``linspace(0, 1, n + 2)`` (float32, as in the reference), inner ``n`` used; slerp falls
    back to linear where ``1 - |dot| < 0.01``; the result is normalised.
    ``(B, T, 3), (B, T, J, 4), n -> (B, n, 3), (B, n, J, 4)``.
    """
    w = np.linspace(0.0, 1.0, num=n + 2, dtype=np.float32)[1:-1].astype(np.float64)
    a, b = slice(n_past - 1, n_past), slice(n_past + n, n_past + n + 1)
    return interpolate_pose(root[:, a], local_q[:, a], root[:, b], local_q[:, b], w[None, :])


BASELINES: dict[str, Predictor] = {"zero_velocity": zero_velocity, "interpolation": interpolation}


# ------------------------------------------------------------------------------------------
# The whole benchmark
# ------------------------------------------------------------------------------------------
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


def evaluate_transitions(
    bench: BenchmarkSet,
    predict_fn: Predictor,
    lengths: Sequence[int] = TRANSITION_LENGTHS,
    n_past: int = N_PAST,
) -> dict[str, float]:
    """Run ``predict_fn`` for each transition length and score it.  Returns ``{"l2q@5": ..., "l2p@5": ..., "npss@5": ...}``."""
    skel = bench.skeleton
    out: dict[str, float] = {}
    for n in lengths:
        if n_past + n + N_FUTURE > bench.X.shape[1]:
            raise ValueError(f"transition length {n} needs windows of {n_past + n + N_FUTURE} frames, have {bench.X.shape[1]}")
        root_in, q_in = transition_inputs(bench, n, n_past)
        pred_root, pred_q = predict_fn(root_in, q_in, n)
        pred_root = np.asarray(pred_root, dtype=np.float64)
        pred_q = np.asarray(pred_q, dtype=np.float64)
        if pred_root.shape != (bench.n_windows, n, 3) or pred_q.shape != (bench.n_windows, n, skel.num_joints, 4):
            raise ValueError(
                f"predictor returned shapes {pred_root.shape}, {pred_q.shape} for n={n}; expected "
                f"{(bench.n_windows, n, 3)}, {(bench.n_windows, n, skel.num_joints, 4)}"
            )
        if not (np.isfinite(pred_root).all() and np.isfinite(pred_q).all()):
            raise ValueError(f"predictor returned non-finite values for transition length {n}")
        out.update(score_transition(bench, pred_root, pred_q, n, n_past))
    return out


def score_transition(
    bench: BenchmarkSet, pred_root: np.ndarray, pred_q: np.ndarray, n: int, n_past: int = N_PAST
) -> dict[str, float]:
    """L2Q, L2P and NPSS of predicted transition frames ``(B, n, 3), (B, n, J, 4)`` against the windows."""
    sl = slice(n_past, n_past + n)
    return score(bench.X[:, sl, 0], bench.Q[:, sl], pred_root, pred_q, bench.skeleton, bench.mean, bench.std, n)


def score(
    gt_root: np.ndarray, gt_q: np.ndarray, pred_root: np.ndarray, pred_q: np.ndarray, skeleton: Skeleton,
    mean: np.ndarray, std: np.ndarray, n: int,
) -> dict[str, float]:
    """The three benchmark metrics for ``n`` transition frames.

    ``gt_root, pred_root (B, n, 3)``, ``gt_q, pred_q (B, n, J, 4)`` local; non-root joints use the
    skeleton offsets; returns ``{"l2q@n", "l2p@n", "npss@n"}``.
    """
    gt_gq, gt_gp = skeleton.pose(np.asarray(gt_root, np.float64), np.asarray(gt_q, np.float64))
    pr_gq, pr_gp = skeleton.pose(np.asarray(pred_root, np.float64), np.asarray(pred_q, np.float64))
    b = gt_gq.shape[0]
    return {
        f"l2q@{n}": l2q(pr_gq, gt_gq),
        f"l2p@{n}": l2p(pr_gp, gt_gp, mean, std),
        f"npss@{n}": npss(gt_gq.reshape(b, n, -1), pr_gq.reshape(b, n, -1)),
    }


def format_table(rows: dict[str, dict[str, float]], lengths: Sequence[int] = TRANSITION_LENGTHS) -> str:
    """Markdown table: one row per model, columns L2Q/L2P/NPSS at each length."""
    metrics = ("l2q", "l2p", "npss")
    head = "| model | " + " | ".join(f"{m.upper()}@{n}" for m in metrics for n in lengths) + " |"
    sep = "|---|" + "---:|" * (len(metrics) * len(lengths))
    lines = [head, sep]
    for name, res in rows.items():
        cells = []
        for m in metrics:
            for n in lengths:
                v = res.get(f"{m}@{n}")
                cells.append("" if v is None else (f"{v:.4f}" if m == "npss" else f"{v:.3f}"))
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)
