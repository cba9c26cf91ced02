"""The retargeting task's module and losses (src/inbetweening/training/retarget_module.py)."""
from __future__ import annotations

import torch

from inbetweening.predictor.checkpoint import read_checkpoint
from inbetweening.training.retarget_module import smoothness
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


def test_training_lowers_every_loss(tmp_path):
    sk = source_skeleton()
    before = read_checkpoint(tiny_checkpoint(tmp_path / "a.ckpt", sk))
    after = read_checkpoint(tiny_checkpoint(tmp_path / "b.ckpt", sk, steps=20))
    from inbetweening.runtime.learned_retarget import LearnedRetarget
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
