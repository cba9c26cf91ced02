"""Test-time adaptation on the user's own keys (``fill.adapt_steps``): before a clip is filled, the network takes a few
gradient steps on the self-check's hide-a-key windows of that clip (:mod:`.trust`: each interior key hidden between
its neighbours, the keys before as context), and fills the clip adapted -- only where that helps on keys it did not
adapt on.

Every third checked key (the 2nd, 5th, 8th, ...) is held out: the network adapts on the others
(:meth:`TorchBackend.adapted <inbetweening.runtime.torch_backend.TorchBackend.adapted>`; an ensemble adapts each
member), then predicts the held-out keys; the adapted network fills the clip only when its error there is below the
original network's (the self-check's own figures), else the clip is filled as without adaptation.  The do-no-harm
weights stay those of the original network's self-check.  A clip with fewer than three checked keys (keys so far
apart that the check's window is longer than the model's trained gap, or few keys) is filled as without it.

This module is numpy-only; the gradient steps are the backend's (the PyTorch backend has them; the ONNX backend and
the Blender extension do not adapt).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .model import InbetweenError
from .trust import Check, scored

__all__ = ["Adaptation", "adapt_clip", "check_adaptable", "split_checks"]


@dataclass(frozen=True)
class Adaptation:
    """What adaptation did for one clip: ``kept``: whether the adapted network filled it; ``before``/``after``: the
    original's and the adapted network's error over interpolation's at the held-out keys (``nan`` without any);
    ``adapted_on``/``held_out``: the keys of each part."""

    kept: bool
    before: float = float("nan")
    after: float = float("nan")
    adapted_on: tuple[int, ...] = ()
    held_out: tuple[int, ...] = ()


def check_adaptable(backend) -> None:
    """:class:`InbetweenError` where ``backend`` cannot take gradient steps (``fill.adapt_steps`` needs PyTorch)."""
    if not hasattr(backend, "adapted"):
        raise InbetweenError(f"fill.adapt_steps: test-time adaptation needs the PyTorch backend; "
                             f"{type(backend).__name__} has no gradient steps (set fill.adapt_steps=0)")


def split_checks(checks: Sequence[Check]) -> tuple[list[int], list[int]]:
    """``(adapt on, held out)`` indices of ``checks``: every third (the 2nd, 5th, ...) held out."""
    held = [i for i in range(len(checks)) if i % 3 == 1]
    return [i for i in range(len(checks)) if i % 3 != 1], held


def _windows(runtime, base, checks: Sequence[Check], truth: bool):
    """The self-check windows of ``checks`` (one length) in the clip's frame, with the hidden key's true pose in
    place where ``truth``: ``(root, local_q, known, hidden frame per window)``."""
    p = runtime.info.n_past
    spans = [(c.a, c.b) for c in checks]
    wr, wq = runtime.windows([base[0]] * len(checks), [base[1]] * len(checks), spans)
    hidden = np.array([p + c.key - c.a - 1 for c in checks])
    if truth:
        rows = np.arange(len(checks))
        keys = [c.key for c in checks]
        q = base[1][keys]
        q = np.where(np.sum(q * wq[rows, hidden - 1], axis=-1, keepdims=True) < 0, -q, q)  # the window's signs
        wr[rows, hidden], wq[rows, hidden] = base[0][keys], q
    return wr, wq, runtime.known_mask(len(checks), spans[0][1] - spans[0][0] - 1), hidden


def _by_length(checks: Sequence[Check], idx: Sequence[int]) -> list[list[int]]:
    groups: dict[int, list[int]] = {}
    for i in idx:
        groups.setdefault(checks[i].b - checks[i].a, []).append(i)
    return list(groups.values())


def adapt_clip(runtime, base, checks: Sequence[Check]):
    """``(backend or None, Adaptation)`` for one clip: ``base`` = ``(root, local_q)`` the keys' interpolation (the
    self-check's context; the keys themselves at key frames), ``checks`` the self-check's scored keys (the original
    network's errors).  ``None``: fill with the runtime's backend (module docstring)."""
    settings = runtime.settings
    train, held = split_checks(checks)
    if settings.adapt_steps <= 0 or not held or not train:
        return None, Adaptation(False)
    check_adaptable(runtime.backend)
    groups = []
    for idx in _by_length(checks, train):
        wr, wq, known, hidden = _windows(runtime, base, [checks[i] for i in idx], truth=True)
        croot, cq, _ = runtime.canonical_windows(wr, wq, known)
        groups.append((croot, cq, known, hidden))
    adapted = runtime.backend.adapted(groups, settings.adapt_steps, settings.adapt_lr)
    after = list(checks)
    for idx in _by_length(checks, held):
        wr, wq, known, hidden = _windows(runtime, base, [checks[i] for i in idx], truth=False)
        pr, pq, _ = runtime.predict_windows(wr, wq, known, backend=adapted)
        for j, i in enumerate(idx):
            t = hidden[j] - runtime.info.n_past
            after[i] = scored(checks[i], runtime.info.skeleton, base[0], base[1], pr[j, t], pq[j, t])
    interp = sum(checks[i].interp for i in held)
    before_x = sum(checks[i].net for i in held) / interp if interp > 0 else float("nan")
    after_x = sum(after[i].net for i in held) / interp if interp > 0 else float("nan")
    kept = bool(after_x < before_x)
    report = Adaptation(kept, before_x, after_x, tuple(checks[i].key for i in train), tuple(checks[i].key for i in held))
    return (adapted if kept else None), report
