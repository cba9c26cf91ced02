"""The retargeting task's data (src/inbetweening/retarget/data.py)."""
from __future__ import annotations

import numpy as np
import pytest

from inbetweening.data.clips import Clip
from inbetweening.data.errors import DatasetError
from inbetweening.retarget.data import content_of, make_pairs, select, split_clips, stats, window_loader
from inbetweening.retarget.rig import TargetRig
from retarget_fixtures import rig_of, source_clips, source_skeleton


def _clips(n):
    contents = ("walk", "walk-turn-left", "run", "wave-both-hands")
    return [Clip(f"dataset-2_{contents[i % 4]}_active_{i:03d}", np.zeros((5, 1, 4)), np.zeros((5, 3))) for i in range(n)]


def test_the_split_is_60_40_deterministic_and_the_same_whatever_is_selected():
    clips = _clips(2000)
    train, test = split_clips(clips, 0.6)
    assert len(train) + len(test) == 2000 and abs(len(train) / 2000 - 0.6) < 0.03
    assert [c.name for c in split_clips(clips[::-1], 0.6)[0]] == [c.name for c in train]
    walking = select(clips, ["walk", "run"])
    assert {content_of(c.name) for c in walking} == {"walk", "walk-turn-left", "run"}
    held = {c.name for c in split_clips(walking, 0.6)[1]}
    assert held <= {c.name for c in test}  # a held-out walking clip is held out among all contents too


def test_selecting_nothing_says_what_there_is():
    with pytest.raises(DatasetError, match="retarget.contents: no clip's content holds any of \\['jump'\\]"):
        select(_clips(4), ["jump"])
    assert len(select(_clips(4), None)) == 4


def test_pairs_windows_and_statistics():
    sk = source_skeleton()
    rig = TargetRig(rig_of(sk, "cmu"), sk)
    pairs = make_pairs(rig, source_clips(sk, 2, frames=40))
    assert [p.x.shape for p in pairs] == [(40, rig.source_dim())] * 2
    (xm, xs), (ym, ys) = stats([p.x for p in pairs]), stats([p.y for p in pairs])
    assert (xs >= 1e-2).all() and xm.shape == (rig.source_dim(),)
    norm = {"x_mean": xm, "x_std": xs, "y_mean": ym, "y_std": ys}
    loader = window_loader(pairs, norm, window=16, stride=8, batch_size=2, seed=0)
    x, y = next(iter(loader))
    assert x.shape == (2, 16, rig.source_dim()) and y.shape == (2, 16, rig.target_dim())
    assert len(loader) == 2 * 4 // 2  # 4 windows per 40-frame clip
    with pytest.raises(DatasetError, match="no training clip has 64 frames"):
        window_loader(pairs, norm, window=64, stride=8, batch_size=2, seed=0)
