"""``inbetweening.training.builders``: every part of a run comes from its own config group, unmapped: the data module
takes the run's mask group and seed by interpolation, and a callbacks/logger group node without ``_target_`` (an
experiment's settings for a callback the run turned off) builds nothing."""
from __future__ import annotations

import pytest

from conftest import compose_cfg
from inbetweening.predictor.masks import JointGaps
from inbetweening.training.builders import make_datamodule, make_trainer
from inbetweening.training.figures import SkeletonFigure


@pytest.mark.parametrize("callbacks, figures", [("default", 1), ("none", 0)])
def test_an_experiment_composes_with_any_callbacks_group(callbacks, figures, tmp_path):
    cfg = compose_cfg("train", ["experiment=bn2_reference", f"callbacks={callbacks}", "logger=none"], tmp_path, tmp_path)
    if callbacks == "none":  # the experiment's tweak of the figure callback survives alone, without a _target_
        assert "_target_" not in cfg.callbacks.skeleton_figure
    trainer = make_trainer(cfg)
    found = [c for c in trainer.callbacks if isinstance(c, SkeletonFigure)]
    assert len(found) == figures
    if figures:
        assert found[0].every == 1  # the experiment's setting reached the callback


def test_the_data_module_takes_the_runs_mask_and_seed(tmp_path):
    cfg = compose_cfg("train", ["mask=joints", "mask.gap_max=50", "seed=9"], tmp_path, tmp_path)
    dm = make_datamodule(cfg)
    assert dm.mask_name == "joints" and dm.hparams.seed == 9
    assert dm.joint_gaps == JointGaps(gap_min=10, gap_max=50, frac_min=0.1, frac_max=0.3)
    dm = make_datamodule(compose_cfg("train", ["mask=zero"], tmp_path, tmp_path))
    assert dm.mask_name == "zero" and dm.joint_gaps == JointGaps()
