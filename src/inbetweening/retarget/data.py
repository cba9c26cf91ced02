"""The retargeting task's data: source clips (a dataset of the source skeleton, e.g. Bandai-Namco-2) paired with their
analytic retarget onto the target rig (:class:`~inbetweening.retarget.rig.TargetRig`), the seed's split
(60 % of the clips for training, 40 % for testing, by a stable hash of the clip's name: deterministic, and the same
clip falls on the same side whatever contents are selected), the normalisation statistics and training windows.
"""
from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch
from torch.utils.data import DataLoader, TensorDataset

from inbetweening.data.clips import Clip
from inbetweening.data.errors import DatasetError
from inbetweening.data.specs import bandai_namco_content

from .rig import TargetRig

__all__ = ["Pair", "content_of", "make_pairs", "select", "split_clips", "stats", "window_loader"]


@dataclass
class Pair:
    """One clip: the source's motion, its features ``x (F, Din)`` and the analytic target's ``y (F, Dout)``, the
    target's ``local_q, local_p``."""

    clip: Clip
    x: np.ndarray
    y: np.ndarray
    local_q: np.ndarray
    local_p: np.ndarray


def content_of(name: str) -> str:
    """The content of a Bandai-Namco clip name ``dataset-N_<content>_<style>_<take>`` (the whole name otherwise)."""
    return bandai_namco_content(name) or name


def select(clips: Sequence[Clip], contents: Sequence[str] | None) -> list[Clip]:
    """The clips whose content holds one of ``contents`` (``walk`` takes ``walk-turn-left`` too); all for ``None``."""
    if not contents:
        return list(clips)
    out = [c for c in clips if any(w in content_of(c.name) for w in contents)]
    if not out:
        raise DatasetError(f"retarget.contents: no clip's content holds any of {list(contents)} (e.g. "
                           f"{content_of(clips[0].name) if clips else 'no clips at all'})")
    return out


def split_clips(clips: Sequence[Clip], train_fraction: float) -> tuple[list[Clip], list[Clip]]:
    """``(train, test)``: a clip is for training when the stable hash of its name, as a fraction in ``[0, 1)``, is
    below ``train_fraction`` (sorted by name)."""
    def u(name: str) -> float:
        return int.from_bytes(hashlib.sha1(name.encode()).digest()[:8], "big") / 2.0**64

    ordered = sorted(clips, key=lambda c: c.name)
    return [c for c in ordered if u(c.name) < train_fraction], [c for c in ordered if u(c.name) >= train_fraction]


def make_pairs(rig: TargetRig, clips: Sequence[Clip]) -> list[Pair]:
    """Each clip with its analytic retarget onto ``rig`` and both feature sequences."""
    out = []
    for c in clips:
        if c.num_frames < 4:
            continue
        lq, lp = rig.analytic(c.root_pos, c.local_q)
        out.append(Pair(c, rig.encode_source(c.root_pos, c.local_q), rig.encode_target(lq, lp, c.root_pos, c.local_q),
                        lq, lp))
    return out


def stats(arrays: Sequence[np.ndarray], floor: float = 1e-2) -> tuple[np.ndarray, np.ndarray]:
    """Per-feature mean and standard deviation (at least ``floor``) over the frames of ``arrays (F, D)``."""
    a = np.concatenate(arrays, axis=0).astype(np.float64)
    return a.mean(0).astype(np.float32), np.maximum(a.std(0), floor).astype(np.float32)


def window_loader(pairs: Sequence[Pair], norm: dict, window: int, stride: int, batch_size: int,
                  seed: int) -> DataLoader:
    """Shuffled training windows (``window`` frames every ``stride``) of the normalised features."""
    xs, ys = [], []
    for p in pairs:
        for s in range(0, max(len(p.x) - window, 0) + 1, stride):
            if s + window <= len(p.x):
                xs.append(p.x[s : s + window])
                ys.append(p.y[s : s + window])
    if not xs:
        raise DatasetError(f"retarget.window: no training clip has {window} frames")
    x = (np.stack(xs) - norm["x_mean"]) / norm["x_std"]
    y = (np.stack(ys) - norm["y_mean"]) / norm["y_std"]
    g = torch.Generator().manual_seed(int(seed))
    return DataLoader(TensorDataset(torch.from_numpy(x).float(), torch.from_numpy(y).float()),
                      batch_size=batch_size, shuffle=True, drop_last=True, generator=g)
