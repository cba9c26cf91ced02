"""Training windows and the training task drawn on them.

* :class:`ClipWindows` - windows cut from the training clips on the fly, at any stride (dense sampling without a
  window tensor in memory), optionally mirrored left/right and played faster (time warp), normalised like the
  benchmark's windows
  (:func:`inbetweening.evaluation.benchmark.centre_and_rotate`: the root faces +X at the last context frame).
* :func:`draw_task` - per-sample context length, transition length and intermediate keyframes, and
  :func:`task_window`, the window cut to that task with its ``known`` mask.

All draws come from the batch's own ``torch.Generator`` (seeded by seed, epoch and batch number), so a batch is a
pure function of those: resumable and reproducible.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from inbetweening.data.mirror import fit_mirror_frames, mirror_motion, mirror_permutation
from inbetweening.evaluation import benchmark as B
from inbetweening.geometry.interp import interpolate_pose
from inbetweening.geometry.skeleton import Skeleton
from inbetweening.predictor.masks import transition_known

__all__ = ["ClipWindows", "draw_task", "task_window"]


class ClipWindows:
    """Every ``window``-frame window of ``clips`` starting each ``stride`` frames (as
    :func:`~inbetweening.evaluation.benchmark.window_starts` counts them), cut when a batch asks for it.

    Args:
        clips: objects with ``root_pos (F, 3)`` and ``local_q (F, J, 4)``.
        mirror: the dataset's left/right joint pairs (``MotionData.mirror``) to allow :meth:`windows` to mirror
            windows; ``None``: no mirroring.
    """

    def __init__(self, clips: Sequence, skeleton: Skeleton, window: int, stride: int, forward_axis: Sequence[float],
                 mirror: Sequence[Sequence[str]] | None = None):
        self.skeleton, self.window, self.forward_axis = skeleton, int(window), tuple(forward_axis)
        self.root = np.concatenate([np.asarray(c.root_pos, dtype=np.float64) for c in clips])
        self.q = np.concatenate([np.asarray(c.local_q, dtype=np.float64) for c in clips])
        starts, ends, base = [], [], 0
        for c in clips:
            st = B.window_starts(c.num_frames, self.window, int(stride))
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
                speed: Sequence[float] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Normalised windows ``root (B, W, 3), local_q (B, W, J, 4)`` (float64) of window numbers ``idx``; those
        flagged in ``mirrored`` are mirrored first (needs ``mirror``).  ``speed (B,)``: play each window that many
        times faster (frame ``i`` is the clip at ``start + i * speed``, root lerp and per-joint slerp between the two
        nearest frames), capped by :meth:`max_speed`; ``1`` (or ``None``) cuts the frames exactly as they are."""
        i = np.asarray(idx, dtype=np.int64)
        if speed is None:
            frames = self.starts[i][:, None] + np.arange(self.window)[None, :]
            root, q = self.root[frames], self.q[frames]
        else:
            sp = np.minimum(np.asarray(speed, dtype=np.float64), self.max_speed(i))
            t = self.starts[i][:, None] + np.arange(self.window)[None, :] * sp[:, None]
            f0 = np.minimum(np.floor(t).astype(np.int64), self.ends[i][:, None] - 1)
            f1 = np.minimum(f0 + 1, self.ends[i][:, None] - 1)
            w = t - f0
            root, q = interpolate_pose(self.root[f0], self.q[f0], self.root[f1], self.q[f1], w)
            exact = w == 0  # whole frames stay bit-exact (slerp renormalises)
            root[exact], q[exact] = self.root[f0[exact]], self.q[f0[exact]]
        if mirrored is not None and np.any(mirrored):
            if self.mirror is None:
                raise ValueError("ClipWindows: mirroring asked for, but no mirror map was given")
            m = np.asarray(mirrored, dtype=bool)
            root[m], q[m] = mirror_motion(root[m], q[m], *self.mirror, self.skeleton.parents)
        X, Q = B.centre_and_rotate(self.skeleton.local_positions(root), q, self.skeleton.parents, self.forward_axis)
        return X[:, :, 0], Q


def draw_task(gen: torch.Generator | None, batch: int, transition: tuple[int, int], per_sample: bool,
              context: tuple[int, int], keyframes_max: int, keyframe_prob: float, n_past: int = B.N_PAST):
    """Random task of a training batch: ``(context (B,), n_trans (B,), keyframes (B, T) bool | None)``.

    The transition length is drawn first (per batch or per sample, ``transition = (min, max)``), exactly as before
    the other options existed, so a run with the defaults (context ``(n_past, n_past)``, no keyframes) draws the same
    numbers; then the context length per sample, then, with probability ``keyframe_prob`` per sample,
    ``1..keyframes_max`` keyframes at random frames inside its transition (at least one frame stays unknown).
    """
    lo, hi = transition
    if per_sample:
        n = torch.randint(lo, hi + 1, (batch,), generator=gen)
    else:
        n = torch.randint(lo, hi + 1, (1,), generator=gen).expand(batch)
    cmin, cmax = context
    if (cmin, cmax) == (n_past, n_past):
        c = torch.full((batch,), n_past, dtype=torch.long)
    else:
        c = torch.randint(cmin, cmax + 1, (batch,), generator=gen)
    if keyframes_max <= 0 or keyframe_prob <= 0:
        return c, n, None
    t = int((c + n).max()) + 1
    want = torch.rand(batch, generator=gen) < keyframe_prob
    k = torch.randint(1, keyframes_max + 1, (batch,), generator=gen)
    k = torch.where(want, torch.minimum(k, n - 1), torch.zeros_like(k))
    frame = torch.arange(t)[None, :]
    inside = (frame >= c[:, None]) & (frame < (c + n)[:, None])
    score = torch.where(inside, torch.rand(batch, t, generator=gen), torch.full((batch, t), 2.0))
    rank = score.argsort(dim=1).argsort(dim=1)
    return c, n, inside & (rank < k[:, None])


def task_window(gt: torch.Tensor, context: torch.Tensor, n_trans: torch.Tensor, keyframes: torch.Tensor | None = None,
                n_past: int = B.N_PAST) -> tuple[torch.Tensor, torch.Tensor]:
    """Cut windows to their task: ``(gt (B, T, J, F), known (B, T, J))``.

    ``gt (B, W, J, F)`` are windows whose frame ``n_past - 1`` is the last context frame; sample ``b`` keeps its
    ``context[b]`` frames up to there, its ``n_trans[b]`` transition frames and the target keyframe; frames after the
    target repeat it (known, so never in the loss).  ``T = max(context + n_trans) + 1``.  ``keyframes (B, T)`` marks
    extra known frames inside the transition.
    """
    b, _, j, _ = gt.shape
    t = int((context + n_trans).max()) + 1
    frame = torch.arange(t)[None, :]
    src = torch.minimum(n_past - context[:, None] + frame, (n_past + n_trans)[:, None])
    out = torch.gather(gt, 1, src[:, :, None, None].expand(b, t, j, gt.shape[-1]))
    known = transition_known(b, t, j, context, n_trans)
    if keyframes is not None:
        known = known | keyframes[:, :, None]
    return out, known
