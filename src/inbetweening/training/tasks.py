"""The training task drawn on training windows (:class:`inbetweening.data.windows.ClipWindows`).

* :func:`draw_task` - per-sample context length, transition length and intermediate keyframes, and
  :func:`task_window`, the window cut to that task with its ``known`` mask.

All draws come from the batch's own ``torch.Generator`` (seeded by seed, epoch and batch number), so a batch is a
pure function of those: resumable and reproducible.
"""
from __future__ import annotations

import torch

from inbetweening.data.windows import N_PAST
from inbetweening.predictor.masks import transition_known

__all__ = ["draw_task", "mix_body_parts", "partial_keys", "subtrees", "task_window", "upper_body", "upper_limbs"]


def draw_task(gen: torch.Generator | None, batch: int, transition: tuple[int, int], per_sample: bool,
              context: tuple[int, int], keyframes_max: int, keyframe_prob: float, n_past: int = N_PAST):
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


def subtrees(parents) -> torch.Tensor:
    """``(J, J)`` bool: row ``j`` marks joint ``j`` and every joint below it (``parents[j] < j``, root ``-1``)."""
    j = len(parents)
    below = torch.eye(j, dtype=torch.bool)
    for c in range(j - 1, 0, -1):  # children after parents: fold each joint's row into its parent's
        p = int(parents[c])
        if p >= 0:
            below[p] |= below[c]
    return below


def upper_body(parents, feet: list[int]) -> torch.Tensor:
    """``(J,)`` bool: the upper body, the largest subtree under the root's children that holds no foot (the spine,
    neck, head and arms; the legs and the root stay out).  :class:`ValueError` when every child holds a foot."""
    below = subtrees(parents)
    tops = [c for c in range(len(parents)) if int(parents[c]) == 0 and not below[c, list(feet)].any()]
    if not tops:
        raise ValueError("data.mix_parts: no joint under the root without a foot below it (no upper body to mix)")
    return below[max(tops, key=lambda c: int(below[c].sum()))]


def upper_limbs(parents, upper: torch.Tensor) -> list[torch.Tensor]:
    """The upper body's limbs, ``(J,)`` bool each: the subtrees under its first joint with more than one child (the
    chest's neck and head, each arm).  An upper body that never branches is one limb, itself."""
    below = subtrees(parents)
    j = len(parents)
    for top in (int(i) for i in torch.nonzero(upper).flatten()):  # parents before children: the first branch
        children = [c for c in range(j) if int(parents[c]) == top]
        if len(children) > 1:
            return [below[c] for c in children]
    return [upper]


def mix_body_parts(gen: torch.Generator | None, q: torch.Tensor, parts: list[torch.Tensor],
                   prob: float = 0.5) -> torch.Tensor:
    """Body-part mixing: for each part (``(J,)`` bool) in turn, each window of ``q (B, W, J, 4)`` (local rotations),
    with probability ``prob``, takes that part's local rotations of another window of the batch, a donor drawn per
    part; the joints of no part -- root, hips, legs, the feet on the ground -- stay its own.  One part (the upper
    body) mixes whole; several (:func:`upper_limbs`) compose new motions, a left arm's wave with a right arm's."""
    b = q.shape[0]
    if b < 2:
        return q
    for part in parts:
        donor = (torch.arange(b) + torch.randint(1, b, (b,), generator=gen)) % b  # never the window itself
        take = torch.rand(b, generator=gen) < prob
        q = torch.where(take[:, None, None, None] & part[None, None, :, None], q[donor], q)
    return q


def partial_keys(gen: torch.Generator | None, keyframes: torch.Tensor, parents, prob: float) -> torch.Tensor:
    """Partial keys: ``keyframes (B, T)`` -> ``(B, T, J)``; each keyframe is, with probability ``prob``, known on one
    body part only: the joints below a random joint other than the root (an arm, a leg, the upper body...), or, half
    of the time, every joint but those (the animator keyed the body and left the arm free)."""
    b, t = keyframes.shape
    below = subtrees(parents)
    j = below.shape[0]
    part = torch.rand(b, t, generator=gen) < prob
    joint = torch.randint(1, j, (b, t), generator=gen)
    flip = torch.rand(b, t, generator=gen) < 0.5
    sel = below[joint] ^ flip[..., None]  # (B, T, J)
    return keyframes[..., None] & torch.where(part[..., None], sel, torch.ones_like(sel))


def task_window(root: torch.Tensor, q: torch.Tensor, context: torch.Tensor, n_trans: torch.Tensor,
                keyframes: torch.Tensor | None = None,
                n_past: int = N_PAST) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Cut windows to their task: ``(root (B, T, 3), q (B, T, J, 4), known (B, T, J))``.

    ``root (B, W, 3), q (B, W, J, 4)`` are windows whose frame ``n_past - 1`` is the last context frame; sample ``b``
    keeps its ``context[b]`` frames up to there, its ``n_trans[b]`` transition frames and the target keyframe; frames
    after the target repeat it (known, so never in the loss).  ``T = max(context + n_trans) + 1``.  ``keyframes
    (B, T)`` marks extra known frames inside the transition, ``(B, T, J)`` extra known values (partial keys,
    :func:`partial_keys`).
    """
    b, _, j, _ = q.shape
    t = int((context + n_trans).max()) + 1
    frame = torch.arange(t)[None, :]
    src = torch.minimum(n_past - context[:, None] + frame, (n_past + n_trans)[:, None])
    out_root = torch.gather(root, 1, src[:, :, None].expand(b, t, 3))
    out_q = torch.gather(q, 1, src[:, :, None, None].expand(b, t, j, 4))
    known = transition_known(b, t, j, context, n_trans)
    if keyframes is not None:
        known = known | (keyframes if keyframes.dim() == 3 else keyframes[:, :, None])
    return out_root, out_q, known
