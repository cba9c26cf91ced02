"""Scoring of the standard in-betweening benchmark (Harvey et al. 2020, LAFAN1 protocol).

The windows, their normalisation and the training statistics are the data layer's
(:mod:`inbetweening.data.windows`); this module scores predictions on them: for a transition length ``n``,
context = frames 0..9, target keyframe = frame ``10 + n``, evaluated frames = ``10 .. 9 + n``.

Metrics (all on FK of local quaternions with the skeleton offsets for non-root joints):

* L2Q  - per frame the L2 norm over all joints' global quaternion 4-vectors of ``pred - gt``, mean.
* L2P  - global positions z-scored with the training statistics, per frame L2 norm, mean.
* NPSS - normalised power spectrum similarity on flattened global quaternions.

Numpy functions run in float64 so that results match the reference implementation.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from inbetweening.data.windows import N_FUTURE, N_PAST, TRANSITION_LENGTHS, BenchmarkSet, transition_inputs
from inbetweening.geometry.interp import interpolate_pose
from inbetweening.geometry.skeleton import Skeleton

# predictor(root (B, n+11, 3), local_q (B, n+11, J, 4), n) -> (root (B, n, 3), local_q (B, n, J, 4))
Predictor = Callable[[np.ndarray, np.ndarray, int], tuple[np.ndarray, np.ndarray]]


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
    return score_global(pr_gq, pr_gp, gt_gq, gt_gp, mean, std, n)


def score_global(pr_gq: np.ndarray, pr_gp: np.ndarray, gt_gq: np.ndarray, gt_gp: np.ndarray, mean: np.ndarray,
                 std: np.ndarray, n: int) -> dict[str, float]:
    """:func:`score` of poses already taken through FK: global quaternions ``(B, n, J, 4)`` and positions
    ``(B, n, J, 3)`` (float64) of the prediction and the ground truth."""
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
