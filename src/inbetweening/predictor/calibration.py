"""The do-no-harm blend: how far to trust the network over the interpolation, per gap length, fitted on held-out
windows after training.

A network trained on one set of motions can be worse than plain interpolation where it has little to add: with
dense keys (short gaps the interpolation already fills well) and on motions unlike its training data.  The blend
(:attr:`Predictor.blend <inbetweening.predictor.predictor.Predictor>`) answers with the classic shrinkage of one
estimate towards another: every generated value is ``interpolation + w(L) x (network - interpolation)`` (rotations
by slerp), ``L`` being the length of the gap it lies in.  :func:`fit_blend` chooses each ``w(L)`` on a grid in
[0, 1] to minimise the mean joint position error (FK of the decoded prediction, the dataset's length unit) of
held-out windows of the benchmark's form: ``n_past`` known context frames, a gap of ``L`` frames, the target.
``w = 0`` is the interpolation and ``w = 1`` the network, so on those windows the blend is never worse than
either, gap length by gap length; what it buys on other motions is measured (RESULTS.md, section 5.1).

Shapes: windows ``root (N, T, 3)``, ``local_q (N, T, J, 4)`` (numpy or torch, any frame).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import torch

BLEND_STEPS = 21  # candidate weights 0, 0.05, ..., 1


@dataclass
class BlendFit:
    """What :func:`fit_blend` found: ``weights[L - 1]`` for gap length ``L``, and per gap length the mean joint
    position error of the network, the interpolation and the blend on the fitting windows (``rows``)."""

    weights: list[float]
    rows: list[dict] = field(default_factory=list)  # {"gap", "weight", "network", "interpolation", "blended"}
    windows: int = 0

    def table(self) -> str:
        """The fit as a text table: one row per gap length, errors in the dataset's unit."""
        lines = [f"do-no-harm blend fitted on {self.windows} held-out windows (mean joint position error)",
                 f"{'gap':>4} {'weight':>7} {'network':>9} {'interp':>9} {'blended':>9}"]
        lines += [f"{r['gap']:>4} {r['weight']:>7.2f} {r['network']:>9.3f} {r['interpolation']:>9.3f} "
                  f"{r['blended']:>9.3f}" for r in self.rows]
        return "\n".join(lines)


def gap_range(predictor, window_frames: int, max_gap: int | None = None) -> int:
    """The longest gap fitted: ``max_gap`` (default: the longest the model was trained on, ``train_window - n_past -
    1``), at most what a window of ``window_frames`` holds; ValueError when not even one gap frame fits."""
    limit = window_frames - predictor.n_past - 1
    longest = min(int(max_gap) if max_gap else predictor.train_window - predictor.n_past - 1, limit)
    if longest < 1:
        raise ValueError(f"blend: windows of {window_frames} frames leave no gap after {predictor.n_past} context "
                         "frames and the target")
    return longest


@torch.no_grad()
def fit_blend(predictor, root, local_q, max_gap: int | None = None, steps: int = BLEND_STEPS,
              batch_size: int = 64) -> BlendFit:
    """Fit the blend's weight of every gap length ``1..max_gap`` on the windows ``root``, ``local_q`` (their frames
    beyond ``n_past + L + 1`` unused); ties go to the smaller weight (nearer the interpolation).  The predictor is
    not changed: give ``fit.weights`` to it (``blend``) or to a checkpoint (:func:`calibrated_checkpoint`)."""
    root = torch.as_tensor(np.asarray(root), dtype=torch.float64)
    local_q = torch.as_tensor(np.asarray(local_q), dtype=torch.float64)
    if root.ndim != 3 or len(root) == 0:
        raise ValueError(f"blend: need windows root (N, T, 3) with N >= 1, got shape {tuple(root.shape)}")
    n_past, sk = predictor.n_past, predictor.skeleton
    longest = gap_range(predictor, root.shape[1], max_gap)
    candidates = torch.linspace(0.0, 1.0, steps)

    def positions(feats: torch.Tensor, gap: int) -> np.ndarray:
        r, q = predictor.decode(feats[:, n_past : n_past + gap])
        return sk.pose(r.cpu().numpy(), q.cpu().numpy())[1]

    weights, rows = [], []
    for gap in range(1, longest + 1):
        t = n_past + gap + 1
        err = np.zeros(steps)
        for s in range(0, len(root), batch_size):
            r, q = root[s : s + batch_size, :t], local_q[s : s + batch_size, :t]
            known = predictor.transition_known(len(r), t, gap)
            feats, _ = predictor.canonical_features(r, q, known)
            known = known.to(feats.device)
            out, interp = predictor.network_forward(feats, known, blend=False)
            truth = positions(feats, gap)
            for i, w in enumerate(candidates):
                p = positions(predictor.blended(out, interp, known, float(w)), gap)
                err[i] += np.linalg.norm(p - truth, axis=-1).sum()
        err /= len(root) * gap * sk.num_joints
        best = int(np.argmin(err))
        weights.append(round(float(candidates[best]), 4))
        rows.append({"gap": gap, "weight": weights[-1], "network": float(err[-1]), "interpolation": float(err[0]),
                     "blended": float(err[best])})
    return BlendFit(weights, rows, len(root))


def calibrated_checkpoint(ckpt: dict, weights: list[float]) -> dict:
    """A copy of a checkpoint's dict whose predictor carries the blend ``weights`` (its ``hyper_parameters``; the
    weights of the network are unchanged)."""
    out = dict(ckpt)
    out["hyper_parameters"] = {**ckpt["hyper_parameters"], "blend": [float(w) for w in weights]}
    return out
