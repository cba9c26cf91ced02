"""The jobs behind train.py / eval.py (``inbetweening.training.train``, ``.evaluate``, ``.calibrate``, ``.job``):
faults that must be one line and exit 2, and configurations that must compose, as a table run through the real
command line."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from conftest import TINY_CKPT_OVERRIDES

ROOT = Path(__file__).resolve().parents[1]
SMALL = [o for o in TINY_CKPT_OVERRIDES if not o.startswith(("trainer.max_steps", "callbacks=", "logger=", "model.d_model"))]

# (case, overrides ({ckpt}: the tiny checkpoint, trained with model.d_model=16), exit code, stderr pattern or None)
CLI_CASES = [
    ("resume with another model size names both architectures",
     [*SMALL, "model.d_model=32", "trainer.max_steps=4", "callbacks=none", "logger=none", "ckpt_path='{ckpt}'"], 2,
     r"^error: ckpt_path: \S+ holds another architecture: graph_transformer \(.*d_model=16.*\); this run builds "
     r"graph_transformer \(.*d_model=32.*\)"),
    ("resume with another model names both",
     [*[o for o in SMALL if not o.startswith("model.")], "model=unet1d", "trainer.max_steps=4", "callbacks=none",
      "logger=none", "ckpt_path='{ckpt}'"], 2,
     r"^error: ckpt_path: \S+ holds another architecture: graph_transformer \(.*\); this run builds unet1d"),
    ("an experiment composes with callbacks=none",
     ["experiment=bn2_reference", "data=synthetic", *SMALL, "model.d_model=16", "trainer.max_steps=1",
      "trainer.max_time=null", "callbacks=none", "logger=none"], 0, None),
    ("an experiment composes with logger=none and its callbacks",
     ["experiment=bn2_reference", "data=synthetic", *SMALL, "model.d_model=16", "trainer.max_steps=1",
      "trainer.max_time=null", "logger=none"], 0, None),
]


@pytest.fixture(scope="module")
def d16_checkpoint(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("d16")
    r = subprocess.run([sys.executable, "train.py", *SMALL, "model.d_model=16", "trainer.max_steps=2", "callbacks=none",
                        "logger=none", f"hydra.run.dir={out}"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    ckpts = sorted((out / "checkpoints").glob("*.ckpt"))
    assert ckpts, r.stdout[-2000:]
    return ckpts[-1]


@pytest.mark.slow
@pytest.mark.parametrize("case, overrides, code, pattern", CLI_CASES, ids=[c[0] for c in CLI_CASES])
def test_train_cli_table(case, overrides, code, pattern, d16_checkpoint, tmp_path):
    import re

    args = [o.replace("{ckpt}", str(d16_checkpoint)) for o in overrides]
    r = subprocess.run([sys.executable, "train.py", *args, f"hydra.run.dir={tmp_path}"], cwd=ROOT, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == code, (case, r.stderr[-2000:])
    if pattern is not None:  # one error line, the last, no traceback (Lightning's notes on the set-up may come before)
        errors = [ln for ln in r.stderr.splitlines() if ln.startswith("error:")]
        assert len(errors) == 1 and "Traceback" not in r.stderr and r.stderr.strip().endswith(errors[0]), r.stderr[-2000:]
        assert re.search(pattern, errors[0]), errors[0]


# ------------------------------------------------------------------ init_from: fine-tuning from a checkpoint
def test_init_from_starts_from_the_checkpoints_network_and_weights(tiny_checkpoint, tmp_path, cache_dir):
    """With no step trained, a run started from a checkpoint scores exactly what eval.py scores for that checkpoint,
    whatever the config's model group says (the checkpoint's network is built, its weights loaded)."""
    from conftest import compose_cfg
    from inbetweening.training.evaluate import evaluate
    from inbetweening.training.train import train

    data = [o for o in TINY_CKPT_OVERRIDES if o.startswith("data.")]
    cfg = compose_cfg("train", ["experiment=finetune", "model=unet1d", *data, f"init_from='{tiny_checkpoint}'",
                                "init_stats=checkpoint", "trainer.max_steps=0", "callbacks=none", "logger=none"],
                      tmp_path / "ft", cache_dir)
    got = train(cfg)
    want = evaluate(compose_cfg("eval", [*data, f"ckpt_path='{tiny_checkpoint}'"], tmp_path / "ev", cache_dir))
    assert got and got == want


@pytest.mark.parametrize("init_stats", [None, "checkpoint"])
def test_init_stats_picks_the_datas_statistics_by_default_or_the_checkpoints(init_stats, tiny_checkpoint, tmp_path,
                                                                            cache_dir):
    """``init_stats: data`` (the default) estimates the new data's statistics; ``checkpoint`` keeps the checkpoint's
    (told apart here by a checkpoint whose statistics were shifted)."""
    import torch

    from conftest import compose_cfg
    from inbetweening.training.builders import make_datamodule, make_module
    from inbetweening.training.train import start_from

    ckpt = torch.load(tiny_checkpoint, map_location="cpu", weights_only=False)
    ckpt["hyper_parameters"]["pos_mean"] = [v + 7.0 for v in ckpt["hyper_parameters"]["pos_mean"]]
    shifted = tmp_path / "shifted.ckpt"
    torch.save(ckpt, shifted)
    overrides = [o for o in TINY_CKPT_OVERRIDES if o.startswith("data.")] + ([f"init_stats={init_stats}"]
                                                                             if init_stats else [])
    cfg = compose_cfg("train", overrides, tmp_path, cache_dir)
    dm = make_datamodule(cfg)
    init = start_from(str(shifted), dm)
    dm.setup("fit")
    module = make_module(cfg, dm, init)
    want = ckpt["hyper_parameters"]["pos_mean"] if init_stats == "checkpoint" else dm.model_kwargs()["pos_mean"]
    assert list(module.hparams["pos_mean"]) == list(want)


def test_init_keep_mixes_the_fitted_weights_with_the_starts_and_calibrates_those(tiny_checkpoint, tmp_path,
                                                                                           cache_dir):
    """``init_keep``: after the fit, the best checkpoint's network weights taken that share of the way back to
    init_from's (checked with the test's own arithmetic on the files); the calibrated checkpoint and the test use
    them; the settings it needs are one line each."""
    import torch

    from conftest import compose_cfg
    from inbetweening.training.config import ConfigError, validate
    from inbetweening.training.train import train

    data = [o for o in TINY_CKPT_OVERRIDES if o.startswith("data.")]
    base = ["experiment=finetune", *data, f"init_from='{tiny_checkpoint}'", "init_stats=checkpoint", "trainer.max_steps=3",
            "trainer.val_check_interval=3", "callbacks=default", "logger=none", "run_test=false"]
    out = tmp_path / "ft"
    train(compose_cfg("train", [*base, "init_keep=0.25"], out, cache_dir))
    ckpts = out / "checkpoints"
    (best,) = [p for p in ckpts.glob("epoch_*.ckpt")]
    load = lambda p: torch.load(p, map_location="cpu", weights_only=False)["state_dict"]  # noqa: E731
    fitted, start, kept, calibrated = load(best), load(tiny_checkpoint), load(ckpts / "kept_start.ckpt"), \
        load(ckpts / "calibrated.ckpt")
    start = {k if k.startswith("predictor.") else "predictor." + k: v for k, v in start.items()}
    nets = [k for k in fitted if k.startswith("predictor.net.") and fitted[k].is_floating_point()]
    moved = [k for k in nets if not torch.equal(fitted[k], start[k])]
    assert moved  # the fit changed the network
    for k in nets:
        assert torch.allclose(kept[k], 0.75 * fitted[k] + 0.25 * start[k], atol=1e-6)
        assert torch.equal(calibrated[k], kept[k])
    for bad, pattern in ((["init_keep=1.5"], "^init_keep: must be a number from 0 to 1"),
                         (["init_keep=0.5", "init_stats=data"], "^init_keep: .* set init_stats=checkpoint"),
                         (["init_from=null", "init_stats=data", "init_keep=0.5"], "^init_keep: .* give init_from")):
        with pytest.raises(ConfigError, match=pattern):
            validate(compose_cfg("train", [*base, *bad], tmp_path / "bad", cache_dir))


def test_init_layers_starts_a_shallower_network_from_some_of_the_checkpoints_layers(tmp_path, cache_dir):
    """``init_layers``: the checkpoint's network with only the layers named, in the order named (checked tensor by
    tensor against the file), every other weight as there and the depth their number; a layer it does not have, and
    the settings the option needs, are one line each."""
    import torch

    from conftest import _tiny_checkpoint, compose_cfg
    from inbetweening.predictor.checkpoint import CheckpointError
    from inbetweening.training.builders import make_datamodule, make_module
    from inbetweening.training.config import ConfigError, validate
    from inbetweening.training.train import start_from

    tiny_checkpoint = _tiny_checkpoint(tmp_path / "deep", cache_dir, [*TINY_CKPT_OVERRIDES, "model.depth=3"])
    theirs = torch.load(tiny_checkpoint, map_location="cpu", weights_only=False)
    depth = theirs["hyper_parameters"]["model"]["depth"]
    assert depth == 3
    data = [o for o in TINY_CKPT_OVERRIDES if o.startswith("data.")]
    base = [*data, f"init_from='{tiny_checkpoint}'"]

    def built(layers):
        cfg = compose_cfg("train", [*base, f"init_layers={layers}"], tmp_path / "run", cache_dir)
        validate(cfg)
        dm = make_datamodule(cfg)
        init = start_from(str(tiny_checkpoint), dm)
        dm.setup("fit")
        return make_module(cfg, dm, init)

    module = built(f"[{depth - 1},0]")
    assert module.hparams["model"]["depth"] == 2 and len(module.predictor.net.layers) == 2
    mine = module.predictor.state_dict()
    old = {k.split("predictor.", 1)[-1]: v for k, v in theirs["state_dict"].items()}
    renamed = {f"net.layers.{depth - 1}.": "net.layers.0.", "net.layers.0.": "net.layers.1."}
    checked = 0
    for k, v in old.items():
        if not k.startswith("net."):
            continue
        if k.startswith("net.layers."):
            head = ".".join(k.split(".")[:3]) + "."
            if head not in renamed:
                continue
            k = renamed[head] + k[len(head):]
        assert torch.equal(mine[k], v), k
        checked += 1
    assert checked == len(mine)  # every weight of the new network comes from the checkpoint

    with pytest.raises(CheckpointError, match=rf"^init_layers: init_from's network has layers 0-{depth - 1}, not \[{depth}\]"):
        built(f"[{depth}]")
    for bad, pattern in ((["init_layers=[0,0]"], "^init_layers: must be a list of distinct layer numbers"),
                         (["init_layers=3"], "^init_layers: must be a list"),
                         (["init_from=null", "init_layers=[0]"], "^init_layers: takes layers of init_from's network")):
        with pytest.raises(ConfigError, match=pattern):
            validate(compose_cfg("train", [*base, *bad], tmp_path / "bad", cache_dir))


def test_init_from_of_another_skeleton_names_both(tmp_path, cache_dir):
    import torch

    from conftest import compose_cfg
    from inbetweening.predictor.checkpoint import CheckpointError
    from inbetweening.training.builders import make_datamodule
    from inbetweening.training.train import start_from

    other = tmp_path / "other.ckpt"
    torch.save({"hyper_parameters": {"model": {"name": "interpolation"}, "skeleton": {
        "names": ["root", "arm"], "parents": [-1, 0], "offsets": [[0.0, 0, 0], [1.0, 0, 0]]}}, "state_dict": {}}, other)
    dm = make_datamodule(compose_cfg("train", [o for o in TINY_CKPT_OVERRIDES if o.startswith("data.")], tmp_path,
                                     cache_dir))
    with pytest.raises(CheckpointError, match=r"^init_from: \S+other.ckpt was trained on a 2-joint skeleton \(root, "
                                              r"arm, \.\.\.\); data 'synthetic' has 22 joints \(Hips, "):
        start_from(str(other), dm)


def test_init_from_and_ckpt_path_are_exclusive(tmp_path):
    from conftest import compose_cfg
    from inbetweening.training.config import ConfigError, validate

    with pytest.raises(ConfigError, match="^init_from: starts a new run"):
        validate(compose_cfg("train", ["init_from=a.ckpt", "ckpt_path=b.ckpt"], tmp_path, tmp_path))
    with pytest.raises(ConfigError, match="^init_stats: must be"):
        validate(compose_cfg("train", ["init_stats=mine"], tmp_path, tmp_path))


@pytest.mark.parametrize("config", ["train", "eval", "calibrate"])
def test_every_job_takes_threads(config, tmp_path):
    """``threads`` is a key of train.py, eval.py and calibrate.py alike (jobs share the CPU), checked the same way,
    and sets the process's torch threads."""
    import torch
    from omegaconf import OmegaConf

    from conftest import compose_cfg
    from inbetweening.training.config import ConfigError, validate
    from inbetweening.training.job import use_threads

    cfg = compose_cfg(config, ["threads=1"], tmp_path, tmp_path)
    validate(cfg)
    before = torch.get_num_threads()
    try:
        use_threads(cfg)
        assert torch.get_num_threads() == 1
    finally:
        torch.set_num_threads(before)
    OmegaConf.update(cfg, "threads", 0)
    with pytest.raises(ConfigError, match="threads: must be an integer >= 1"):
        validate(cfg)
