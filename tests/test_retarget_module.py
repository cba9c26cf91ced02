"""The retargeting task's module and losses (src/inbetweening/retarget/module.py)."""
from __future__ import annotations

import pytest
import torch

from inbetweening.predictor.checkpoint import read_checkpoint
from inbetweening.retarget.module import smoothness
from retarget_fixtures import source_skeleton, tiny_checkpoint


def test_smoothness_repeats_the_boundary_frames():
    """A straight line is its own smoothing inside (the kernel is symmetric), and with the boundary frames repeated
    its ends are not: the term is small but positive; a constant is exactly smooth; noise is not."""
    k = torch.tensor([1.0, 4, 6, 4, 1]) / 16
    assert smoothness(torch.ones(2, 10, 3), k) == 0
    line = torch.arange(10.0).view(1, 10, 1)
    inner = smoothness(line, k).item()
    assert 0 < inner < 0.1
    torch.manual_seed(0)
    assert smoothness(torch.randn(1, 50, 3), k) > 10 * inner


def test_the_bone_term_is_zero_on_the_analytic_target_and_not_on_a_stretched_one(tmp_path):
    """The bone-length term reads the position head's joints: the analytic retarget's own positions have the rig's
    bone lengths (the term is ~0), the same positions stretched by 10 % do not (the term is ~0.1)."""
    import numpy as np

    from inbetweening.retarget.data import make_pairs
    from inbetweening.retarget.module import RetargetModule
    from retarget_fixtures import source_clips

    sk = source_skeleton()
    hp = read_checkpoint(tiny_checkpoint(tmp_path / "a.ckpt", sk))["hyper_parameters"]
    module = RetargetModule(**hp)
    pair = make_pairs(module.rig, source_clips(sk, 1, frames=20))[0]
    y = torch.from_numpy((pair.y - np.asarray(hp["norm"]["y_mean"])) / np.asarray(hp["norm"]["y_std"]))[None].float()
    parts = module.losses(y, y)
    assert parts["mse"] == 0 and parts["bone"] < 1e-3 and parts["smooth"] > 0
    stretched = pair.y.copy()
    stretched[:, module.pos] *= 1.1
    y2 = torch.from_numpy((stretched - np.asarray(hp["norm"]["y_mean"])) / np.asarray(hp["norm"]["y_std"]))[None]
    assert abs(module.losses(y2.float(), y)["bone"].item() - 0.1) < 0.01


@pytest.mark.slow
def test_training_lowers_every_loss(tmp_path):
    sk = source_skeleton()
    before = read_checkpoint(tiny_checkpoint(tmp_path / "a.ckpt", sk))
    after = read_checkpoint(tiny_checkpoint(tmp_path / "b.ckpt", sk, steps=20))
    from inbetweening.retarget.learned import LearnedRetarget
    from retarget_fixtures import source_clips

    c = source_clips(sk, 1)[0]
    errs = []
    for path in (tmp_path / "a.ckpt", tmp_path / "b.ckpt"):
        learned = LearnedRetarget.from_checkpoint(path)
        lq, lp = learned.rig.analytic(c.root_pos, c.local_q)
        lq2, lp2, _ = learned(c.root_pos, c.local_q)
        errs.append(float(abs(learned.rig.positions(lq2, lp2) - learned.rig.positions(lq, lp)).mean()))
    assert errs[1] < 0.7 * errs[0], errs
    assert before["hyper_parameters"]["skeleton"]["names"] == list(sk.names)
    assert set(after["hyper_parameters"]["loss"]) == {"mse", "smooth", "bone"}
