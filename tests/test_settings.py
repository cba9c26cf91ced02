"""The fill's tuned numbers (runtime/settings.py): one object, its defaults in the Hydra group, each value checked,
and each setting reaching the stage it tunes from every front end (Hydra config, API, command line)."""
from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from omegaconf import OmegaConf

from conftest import CONF_DIR, compose_cfg
from inbetweening.runtime import FillRuntime, InbetweenError
from inbetweening.runtime.ensemble import EnsembleBackend, member_weights
from inbetweening.runtime.settings import DEFAULT_SETTINGS, FillSettings
from inbetweening.training.config import ConfigError, fill_settings
from test_runtime import Recorder, info, motion, walking_on_the_spot


def test_the_hydra_group_holds_the_defaults_and_every_setting_has_its_evidence():
    yaml = OmegaConf.to_container(OmegaConf.load(Path(CONF_DIR) / "fill" / "default.yaml"))
    assert yaml.pop("_target_") == "inbetweening.runtime.settings.FillSettings"
    assert yaml == dataclasses.asdict(DEFAULT_SETTINGS)  # one default: the yaml lists FillSettings' own values
    for f in dataclasses.fields(FillSettings):
        assert f.metadata["meaning"] and f.metadata["evidence"], f.name
        assert f"fill.{f.name}=" in FillSettings.describe()


@pytest.mark.parametrize("config", ["eval", "train"])
def test_a_config_sets_the_fill_and_a_bad_value_names_its_key(config, tmp_path):
    assert fill_settings(compose_cfg(config, [], tmp_path, tmp_path)) == DEFAULT_SETTINGS
    cfg = compose_cfg(config, ["fill.x_full=0.7", "fill.short_gap=10"], tmp_path, tmp_path)
    assert fill_settings(cfg) == FillSettings(x_full=0.7, short_gap=10)
    with pytest.raises(ConfigError, match=r"^fill.x_full: must be below fill.x_none \(1.05\), got 2.0$"):
        fill_settings(compose_cfg(config, ["fill.x_full=2"], tmp_path, tmp_path))
    with pytest.raises(ConfigError, match="bogus"):
        fill_settings(compose_cfg(config, ["+fill.bogus=1"], tmp_path, tmp_path))


@pytest.mark.parametrize("values, match", [
    ({"x_full": 1.2}, r"fill.x_full: must be below fill.x_none"),
    ({"dense_x_none": 0.5}, r"fill.dense_x_full: must be below fill.dense_x_none"),
    ({"min_run": 2.5}, r"fill.min_run: expected an integer, got 2.5"),
    ({"min_run": 0}, r"fill.min_run: must be >= 1, got 0"),
    ({"trusted_share": 1.5}, r"fill.trusted_share: must be in \[0.0, 1.0\]"),
    ({"planted_reach": float("nan")}, r"fill.planted_reach: must be >= 0.0, got nan"),
    ({"share_power": True}, r"fill.share_power: expected a number, got True"),
    ({"reach": "3"}, r"fill.reach: expected an integer, got '3'"),
    ({"x_ful": 0.7}, r"fill.x_ful: not a fill setting; known: adapt_lr, adapt_steps, blend_frames, "),
])
def test_bad_settings_are_one_clear_error(values, match):
    with pytest.raises(InbetweenError, match=match):
        FillSettings.from_mapping(values)


def test_an_integer_setting_given_as_a_whole_float_is_an_integer():
    s = FillSettings.from_mapping({"min_run": 4.0, "x_full": 1})
    assert s.min_run == 4 and isinstance(s.min_run, int) and s.x_full == 1.0 and s.changed() == {"min_run": 4,
                                                                                                  "x_full": 1.0}


def test_the_self_check_thresholds_reach_the_fill():
    """A network that misses every hidden key: the shipped thresholds give its checked gaps back to interpolation;
    thresholds that trust any error ratio give exactly the fill without the self-check; thresholds that trust none
    give interpolation even where the default kept some."""
    root, q = motion(90, seed=3)
    keys = [0, 6, 12, 18, 60, 71, 82]
    model = info(trained_gap=12)
    shipped = FillRuntime(Recorder(model), foot_lock=False).fill(root, q, keys)
    assert [w for a, b, w in shipped.segments if b <= 18] == [0.0, 0.0, 0.0]
    lenient = FillSettings(x_full=100.0, x_none=101.0)
    trusting = FillRuntime(Recorder(model), foot_lock=False, settings=lenient).fill(root, q, keys)
    unchecked = FillRuntime(Recorder(model), foot_lock=False, self_check=False).fill(root, q, keys)
    assert [w for _, _, w in trusting.segments] == [1.0] * len(trusting.segments)
    assert np.array_equal(trusting.root, unchecked.root) and np.array_equal(trusting.local_q, unchecked.local_q)
    near = FillRuntime(Recorder(model), foot_lock=False, settings=FillSettings(reach=0)).fill(root, q, keys)
    assert {(a, b): w for a, b, w in near.segments}[(12, 18)] == 0.0  # the check at key 12 is inside the gap


def test_the_foot_settings_reach_the_lock():
    """Gaps of 9 frames: the loose planted rule holds the foot (as test_runtime checks); with ``planted_max_gap`` 9
    the rule no longer applies there and nothing is locked; ``blend_frames`` moves the frames around a lock."""
    root, q, foot, rt = walking_on_the_spot()
    keys = list(range(0, 81, 10))
    assert (rt.fill(root, q, keys).contact[1:80, foot] == 1).all()
    loose_off = FillRuntime(rt.backend, self_check=False, settings=FillSettings(planted_max_gap=9))
    assert (loose_off.fill(root, q, keys).contact[np.setdiff1d(np.arange(80), keys), foot] == 0).all()
    short = FillRuntime(rt.backend, self_check=False, settings=FillSettings(short_gap=20))
    assert (short.fill(root, q, keys).contact[np.setdiff1d(np.arange(80), keys), foot] == 0).all()  # no loose rule


def test_the_share_power_reaches_an_ensemble(tiny_checkpoint, tiny_contact_checkpoint):
    from inbetweening.runtime.torch_backend import TorchBackend

    members = [TorchBackend.from_checkpoint(tiny_checkpoint), TorchBackend.from_checkpoint(tiny_contact_checkpoint)]
    ens = EnsembleBackend(members)
    assert ens.share_power == DEFAULT_SETTINGS.share_power
    FillRuntime(ens, settings=FillSettings(share_power=0.0))
    assert ens.share_power == 0.0
    infos = [dataclasses.replace(m.info, blend=(0.9,)) for m in members[:1]] + [
        dataclasses.replace(members[1].info, blend=(0.1,))]
    assert np.allclose(member_weights(infos, 1, 0.0), [0.5, 0.5])  # power 0: equal shares


def test_the_api_takes_settings_or_the_ones_to_change(tiny_checkpoint):
    from inbetweening.api.inbetweener import Inbetweener

    ib = Inbetweener.from_checkpoint(tiny_checkpoint, settings={"x_full": 0.5})
    assert ib.settings == ib.runtime.settings == FillSettings(x_full=0.5)
    assert Inbetweener.from_checkpoint(tiny_checkpoint).settings == DEFAULT_SETTINGS
    with pytest.raises(InbetweenError, match="fill.x_none: must be >= 0.0"):
        Inbetweener.from_checkpoint(tiny_checkpoint, settings={"x_none": -1})
    with pytest.raises(InbetweenError, match="settings: expected a FillSettings"):
        FillRuntime(Recorder(info()), settings={"x_full": 0.5})


def test_the_command_line_lists_and_checks_the_settings(tmp_path):
    def cli(*args):
        return subprocess.run([sys.executable, "-m", "inbetweening.predict", *args], capture_output=True, text=True,
                              timeout=120, check=False, cwd=tmp_path)

    shown = cli("--help")
    assert shown.returncode == 0 and all(f"fill.{f.name}=" in shown.stdout for f in dataclasses.fields(FillSettings))
    clip = tmp_path / "in.bvh"
    clip.write_text("HIERARCHY\n")
    bad = cli(f"input={clip}", f"output={tmp_path / 'out.bvh'}", "keyframes=0,30", "fill.min_run=2.5")
    assert bad.returncode == 2 and bad.stderr.strip() == "error: fill.min_run: expected an integer, got 2.5"
    unknown = cli(f"input={clip}", f"output={tmp_path / 'out.bvh'}", "keyframes=0,30", "fill.minrun=2")
    assert unknown.returncode == 2 and "unknown option 'fill.minrun'" in unknown.stderr
