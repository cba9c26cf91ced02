"""Everything a user can type gets one clear line naming the key: a table of bad values, and every experiment
composed with every model."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from conftest import CONF_DIR, compose_cfg
from inbetweening.data.datasets import DatasetError, resolve_path
from inbetweening.training.config import ConfigError, validate

ROOT = Path(__file__).resolve().parents[1]
EXPERIMENTS = sorted(p.stem for p in (Path(CONF_DIR) / "experiment").glob("*.yaml"))
MODELS = sorted(p.stem for p in (Path(CONF_DIR) / "model").glob("*.yaml"))

BAD = [
    (["model.d_model=0"], r"^model.d_model: must be an integer >= 1, got 0$"),
    (["model.depth=-2"], r"^model.depth: must be an integer >= 1"),
    (["model.heads=3"], r"^model.heads: 3 must divide model.d_model=64"),
    (["model.hops=-1"], r"^model.hops: must be an integer >= 0"),
    (["model.max_frames=20"], r"^model.max_frames: 20 is shorter than the 56-frame windows"),
    (["model=unet1d", "model.levels=0"], r"^model.levels: must be an integer >= 1"),
    (["model=unet1d", "+model.d_model=64"], r"^model.d_model: not a setting of model 'unet1d'"),
    (["model.dropout=1.5"], r"^model.dropout: must be in \[0, 1\)"),
    (["data.batch_size=0"], r"^data.batch_size: must be an integer >= 1"),
    (["data.num_workers=-1"], r"^data.num_workers: must be an integer >= 0"),
    (["data.val_fraction=1.0"], r"^data.val_fraction: must be in \[0, 1\)"),
    (["data.test_lengths=[5,60]"], r"^data.test_lengths: lengths must be integers in 1..45"),
    (["data.transition_max=70"], r"^data.transition_max: 70 \+ 10 context \+ 1 target exceeds data.train_window=50"),
    (["data.synthetic.num_clips=3"], r"^data.synthetic.num_clips: need at least 5 clips"),
    (["data.synthetic.min_frames=30"], r"^data.synthetic.min_frames/max_frames: need 66 <= min <= max"),
    (["data.path=/nonexistent"], r"^data.path: data=synthetic generates its clips and reads no path"),
    (["optim.lr=0"], r"^optim.lr: must be > 0"),
    (["centre=middle"], r"^centre: must be 'known' or 'window'"),
    (["mask.name=blur"], r"^mask.name: unknown mask 'blur'"),
]


@pytest.mark.parametrize("overrides, match", BAD, ids=[" ".join(o) for o, _ in BAD])
def test_bad_values_are_one_line_naming_the_key(overrides, match, tmp_path):
    cfg = compose_cfg("train", overrides, tmp_path, tmp_path)
    with pytest.raises(ConfigError, match=match) as e:
        validate(cfg)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("experiment", EXPERIMENTS)
@pytest.mark.parametrize("model", MODELS)
def test_every_experiment_composes_with_every_model(experiment, model, tmp_path):
    cfg = compose_cfg("train", [f"experiment={experiment}", f"model={model}"], tmp_path, tmp_path)
    validate(cfg)  # every combination is valid (or would say why in one line)
    assert cfg.model.name == model


def test_relative_dataset_path_says_relative_to_what(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(DatasetError, match=rf"relative to the working directory {tmp_path}"):
        resolve_path("bandai_namco", "../nowhere/bandai-namco-2.zip")


@pytest.mark.slow
@pytest.mark.parametrize("overrides, match", [BAD[0], BAD[4], BAD[13], BAD[15]])
def test_cli_exits_2_with_one_line(overrides, match, tmp_path):
    r = subprocess.run([sys.executable, "train.py", *overrides, f"hydra.run.dir={tmp_path}"], cwd=ROOT,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2, r.stderr[-1500:]
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), r.stderr
