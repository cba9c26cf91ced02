"""Everything a user can type gets one clear line naming the key: a table of bad values, and every experiment
composed with every model."""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest
import torch
from omegaconf import OmegaConf

from conftest import CONF_DIR, compose_cfg
from inbetweening.data.datasets import DatasetError, resolve_path
from inbetweening.training.config import ConfigError, validate
from inbetweening.training.module import load_module
from inbetweening.training.schedules import SCHEDULE_TARGET, build_optimizers, lr_factor, upgrade_optim, warmup_decay

ROOT = Path(__file__).resolve().parents[1]
REFERENCE_CKPT = ROOT / "models" / "bn2_reference" / "model.ckpt"
EXPERIMENTS = sorted(p.stem for p in (Path(CONF_DIR) / "experiment").glob("*.yaml"))
MODELS = sorted(p.stem for p in (Path(CONF_DIR) / "model").glob("*.yaml") if p.stem != "retarget_lstm")  # task=retarget's

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
    (["optim.optimizer.lr=0"], r"^optim.optimizer.lr: must be > 0"),
    (["optim.freeze=layers"], r"^optim.freeze: must be a list of parameter-name patterns \(e.g. \['layers.\[0-2\].\*'\]\)"),
    (["centre=middle"], r"^centre: must be one of \['known', 'last', 'window'\]"),
    (["mask.name=blur"], r"^mask.name: unknown mask 'blur'"),
    (["+optim.lr=1e-3"], r"^optim.lr: not a setting of optim; set optim.optimizer.\* \(e.g. optim.optimizer.lr\)"),
    (["optim=sgd", "+optim.optimizer.betas=[0.9,0.99]"], r"^optim.optimizer.betas: not an argument of torch.optim.SGD"),
    (["optim.optimizer._target_=torch.nn.Linear"], r"^optim.optimizer._target_: torch.nn.Linear is not a torch optimiser"),
    (["optim.optimizer._target_=torch.optim.Nope"], r"^optim.optimizer._target_: cannot import 'torch.optim.Nope'"),
    (["optim.scheduler.decay=exponential"], r"^optim.scheduler.decay: must be one of \['cosine', 'linear', 'constant'\]"),
    (["optim.scheduler.warmup_steps=-1"], r"^optim.scheduler.warmup_steps: must be an integer >= 0"),
    (["optim.scheduler.min_lr_ratio=2"], r"^optim.scheduler.min_lr_ratio: must be in \[0, 1\]"),
    (["~optim.scheduler.decay"], r"^optim.scheduler.decay: missing \(a required argument of "),
    (["+data.foo=1"], r"^data.foo: not an argument of inbetweening.training.datamodule.InbetweenDataModule"),
    (["+data.shuffle_seed=1"], r"^data.shuffle_seed: not an argument of .*InbetweenDataModule; its settings are "
                                 r"\['batch_size'"),
    (["~data.batch_size"], r"^data.batch_size: missing \(a required argument of "),
    (["data.split=content"], r"^data.split: dataset 'synthetic' has no split 'content'; its splits are \['standard'\]$"),
    (["data=lafan1", "data.split=content"], r"^data.split: dataset 'lafan1' has no split 'content'; its splits are "
                                            r"\['standard'\]$"),
    (["data=bandai_namco", "data.split=takes"], r"^data.split: dataset 'bandai_namco' has no split 'takes'; its splits "
                                               r"are \['standard', 'content'\] and holdout-<content> for the contents "
                                               r"raise-up-both-hands, .*, wave-right-hand and the folds fold-1, .*, fold-5$"),
    (["data=bandai_namco", "data.split=null"], r"^data.split: dataset 'bandai_namco' has no split None"),
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


def test_an_unknown_split_is_one_line_and_exit_2_before_data_loads(tmp_path, capsys):
    from inbetweening.training.evaluate import evaluate
    from inbetweening.training.job import run_cli

    # the path does not exist either: the split is checked first, from the spec, before anything is read
    cfg = compose_cfg("eval", ["data=lafan1", "data.split=content", "model=interpolation",
                               f"data.path={tmp_path / 'missing.zip'}"], tmp_path, tmp_path)
    with pytest.raises(SystemExit) as e:
        run_cli(evaluate, cfg)
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert err == "error: data.split: dataset 'lafan1' has no split 'content'; its splits are ['standard']\n"
    validate(compose_cfg("train", ["data=bandai_namco", "data.split=content"], tmp_path, tmp_path))  # offered: fine


def test_reference_experiment_composes_with_another_model(tmp_path):
    cfg = compose_cfg("train", ["experiment=bn2_reference", "model=unet1d"], tmp_path, tmp_path)
    validate(cfg)
    assert cfg.model.name == "unet1d" and cfg.optim.scheduler.warmup_steps == 200 and cfg.optim.optimizer.lr == 1e-3


# ------------------------------------------------------------------------------------------ optimiser and schedule
OPTIMS = {"adamw": torch.optim.AdamW, "adam": torch.optim.Adam, "sgd": torch.optim.SGD}


def _optimizers(optim: dict, total_steps: int = 20):
    out = build_optimizers(optim, [torch.nn.Parameter(torch.zeros(3))], lambda: total_steps)
    return (out["optimizer"], out["lr_scheduler"]["scheduler"]) if isinstance(out, dict) else (out, None)


def _lrs(opt, sched, steps: int) -> list[float]:
    lrs = []
    for _ in range(steps):
        lrs.append(opt.param_groups[0]["lr"])
        opt.step()
        sched.step()
    return lrs


def test_every_optim_yaml_is_listed():
    assert sorted(p.stem for p in (Path(CONF_DIR) / "optim").glob("*.yaml")) == sorted(OPTIMS)


@pytest.mark.parametrize("name", sorted(OPTIMS))
def test_optim_yaml_instantiates_its_torch_optimiser_with_its_values(name, tmp_path):
    cfg = compose_cfg("train", [f"optim={name}"], tmp_path, tmp_path)
    validate(cfg)
    optim = OmegaConf.to_container(cfg.optim, resolve=True)
    opt, sched = _optimizers(optim)
    assert type(opt) is OPTIMS[name]
    given = {k: v for k, v in optim["optimizer"].items() if not k.startswith("_")}
    assert given["lr"] > 0 and len(given) >= 2
    group = opt.param_groups[0]
    for k, v in given.items():
        got = group["initial_lr"] if k == "lr" else group[k]  # (the schedule scales the current lr)
        assert (tuple(got) if isinstance(got, (list, tuple)) else got) == (tuple(v) if isinstance(v, list) else v), k
    assert isinstance(sched, torch.optim.lr_scheduler.LambdaLR)
    s = optim["scheduler"]
    assert s["_target_"] == SCHEDULE_TARGET and s["warmup_steps"] == 100 and s["decay"] == "cosine"
    assert opt.param_groups[0]["lr"] == pytest.approx(given["lr"] / 100)  # warm-up starts at lr / warmup_steps


def test_command_line_overrides_of_the_optimiser_compose(tmp_path):
    over = ["optim=sgd", "optim.optimizer.lr=0.1", "optim.optimizer.momentum=0.5", "optim.scheduler.warmup_steps=0",
            "optim.scheduler.decay=linear", "optim.scheduler.min_lr_ratio=0.2"]
    cfg = compose_cfg("train", over, tmp_path, tmp_path)
    validate(cfg)
    opt, sched = _optimizers(OmegaConf.to_container(cfg.optim, resolve=True), total_steps=5)
    assert type(opt) is torch.optim.SGD and opt.param_groups[0]["momentum"] == 0.5
    assert _lrs(opt, sched, 7) == pytest.approx([0.1, 0.084, 0.068, 0.052, 0.036, 0.02, 0.02])
    off = compose_cfg("train", ["optim.scheduler=null"], tmp_path, tmp_path)
    validate(off)
    opt, sched = _optimizers(OmegaConf.to_container(off.optim, resolve=True))
    assert type(opt) is torch.optim.AdamW and sched is None  # a constant learning rate


def _old_factor(cfg: dict, total: int):
    """The schedule of ``InbetweenModule.configure_optimizers`` before the partials (the reference, verbatim)."""
    sched = cfg.get("scheduler", "cosine")
    warmup = int(cfg.get("warmup_steps", 0))
    floor = float(cfg.get("min_lr_ratio", 0.0))

    def factor(step: int) -> float:
        if warmup and step < warmup:
            return (step + 1) / warmup
        if sched in (None, "none", "constant"):
            return 1.0
        progress = min(1.0, (step - warmup) / max(total - warmup, 1))
        if sched == "linear":
            return floor + (1 - floor) * (1 - progress)
        return floor + (1 - floor) * 0.5 * (1 + math.cos(math.pi * progress))

    return factor


def test_warmup_decay_gives_the_exact_lr_sequence():
    opt = torch.optim.SGD([torch.nn.Parameter(torch.zeros(1))], lr=2.0)
    sched = warmup_decay(opt, total_steps=11, warmup_steps=4, decay="cosine", min_lr_ratio=0.1)
    lrs = _lrs(opt, sched, 14)
    assert lrs[:4] == [0.5, 1.0, 1.5, 2.0]  # linear warm-up: lr * (step + 1) / warmup
    assert lrs[4] == 2.0  # the peak, then cosine down to the floor
    assert lrs[7] == pytest.approx(2.0 * (0.1 + 0.9 * 0.5 * (1 + math.cos(math.pi * 3 / 7))), rel=1e-15)
    assert all(a > b for a, b in zip(lrs[4:11], lrs[5:11]))
    assert lrs[11:] == pytest.approx([0.2] * 3, rel=1e-15)  # the floor, held after the last step
    # bit-identical to the schedule before the partials, for each decay and with / without warm-up
    for decay, warmup, floor in [("cosine", 100, 0.05), ("linear", 3, 0.05), ("constant", 5, 0.0), ("cosine", 0, 0.0)]:
        total = 137
        old = _old_factor({"scheduler": decay, "warmup_steps": warmup, "min_lr_ratio": floor}, total)
        want = [lr_factor(s, total, warmup, decay, floor) for s in range(total + 5)]
        assert want == [old(s) for s in range(total + 5)], (decay, warmup, floor)


OLD = {  # the optim groups of checkpoints made before the partials (conf/optim/*.yaml of that version)
    "adamw": {"name": "adamw", "lr": 1e-3, "weight_decay": 1e-4, "betas": [0.9, 0.999], "warmup_steps": 100,
              "scheduler": "cosine", "min_lr_ratio": 0.05},
    "adam": {"name": "adam", "lr": 1e-3, "weight_decay": 0.0, "betas": [0.9, 0.999], "warmup_steps": 100,
             "scheduler": "cosine", "min_lr_ratio": 0.05},
    "sgd": {"name": "sgd", "lr": 1e-2, "momentum": 0.9, "nesterov": False, "weight_decay": 0.0, "warmup_steps": 100,
            "scheduler": "cosine", "min_lr_ratio": 0.05},
}


@pytest.mark.parametrize("name", sorted(OLD))
def test_old_optim_dicts_upgrade_to_the_same_optimiser_and_schedule(name, tmp_path):
    new = OmegaConf.to_container(compose_cfg("train", [f"optim={name}"], tmp_path, tmp_path).optim, resolve=True)
    assert upgrade_optim(OLD[name]) == new  # the old yaml is the new yaml
    assert upgrade_optim(new) == new
    a, b = _optimizers(OLD[name], 300), _optimizers(new, 300)
    assert type(a[0]) is type(b[0]) is OPTIMS[name] and a[0].param_groups[0].keys() == b[0].param_groups[0].keys()
    assert _lrs(*a, 300) == _lrs(*b, 300)


def test_old_optim_dicts_keep_their_defaults_and_constant_schedules():
    up = upgrade_optim({"name": "adamw", "lr": 2e-3, "scheduler": "linear", "warmup_steps": 5})
    assert up["optimizer"] == {"_target_": "torch.optim.AdamW", "_partial_": True, "lr": 2e-3, "weight_decay": 0.0,
                               "betas": [0.9, 0.999]}
    assert up["scheduler"] == {"_target_": SCHEDULE_TARGET, "_partial_": True, "warmup_steps": 5, "decay": "linear",
                               "min_lr_ratio": 0.0}
    assert upgrade_optim({"name": "sgd", "scheduler": "constant"})["scheduler"] is None  # no warm-up: no schedule
    assert upgrade_optim({"scheduler": "none", "warmup_steps": 3})["scheduler"]["decay"] == "constant"
    assert upgrade_optim(None) == upgrade_optim({"name": "adamw", "lr": 1e-3})  # a module built without optim
    with pytest.raises(ValueError, match="optim.name: unknown optimiser 'rmsprop'"):
        upgrade_optim({"name": "rmsprop"})


def test_old_checkpoint_loads_and_trains_with_the_upgraded_optimiser(tmp_path):
    """A checkpoint saved with the old ``optim: {name: adamw, lr, ...}`` (the previous models/bn2_reference's,
    written back into the shipped checkpoint) loads with the same optimiser and schedule in the current form."""
    raw = torch.load(REFERENCE_CKPT, map_location="cpu", weights_only=True)
    raw["hyper_parameters"]["optim"] = {"name": "adamw", "lr": 1e-3, "weight_decay": 1e-4, "betas": [0.9, 0.999],
                                        "scheduler": "cosine", "warmup_steps": 200, "min_lr_ratio": 0.0}
    torch.save(raw, tmp_path / "old.ckpt")
    old = raw["hyper_parameters"]["optim"]
    module = load_module(str(tmp_path / "old.ckpt"))
    assert module.hparams.optim == upgrade_optim(old) and module.hparams.optim["optimizer"]["lr"] == old["lr"]
    assert module.hparams.optim["scheduler"]["warmup_steps"] == old["warmup_steps"] == 200
    out = module.configure_optimizers()  # no trainer: one total step
    assert type(out["optimizer"]) is torch.optim.AdamW and out["optimizer"].param_groups[0]["weight_decay"] == 1e-4


def test_experiments_and_ablations_override_the_top_level_defaults(tmp_path, cache_dir):
    """train.yaml's own values come first in its defaults list: an experiment's ``task_name``/``centre``/``threads``
    win (they were silently replaced by train.yaml's when ``_self_`` came last)."""
    cfg = compose_cfg("train", ["experiment=bn2_reference"], tmp_path, cache_dir)
    assert cfg.task_name == "bn2_reference"
    cfg = compose_cfg("train", ["ablation=recipe", "+recipe=last"], tmp_path, cache_dir)
    assert (cfg.task_name, cfg.centre, cfg.threads, list(cfg.test_keyframes)) == ("recipe_ablation", "last", 1, [15, 30])
    assert cfg.data.mirror and cfg.data.context_min == 1


def test_recipe_sweep_lists_every_recipe_and_single_levers_sit_on_base(tmp_path, cache_dir):
    """``ablation=recipe`` sweeps every ``conf/recipe`` file; rot6d / velocity / keyframe change only their own lever."""
    import yaml

    grid = yaml.safe_load((Path(CONF_DIR) / "ablation" / "recipe.yaml").read_text())["hydra"]["sweeper"]["params"]["+recipe"]
    assert sorted(grid.split(",")) == sorted(p.stem for p in (Path(CONF_DIR) / "recipe").glob("*.yaml"))
    base = compose_cfg("train", ["ablation=recipe", "+recipe=base", "model=frame_transformer"], tmp_path, cache_dir)
    for recipe, key, want in [("rot6d", "model.inputs", ["rot6d"]), ("velocity", "model.inputs", ["velocity"]),
                              ("keyframe", "loss.keyframe", 1.0)]:
        cfg = compose_cfg("train", ["ablation=recipe", f"+recipe={recipe}", "model=frame_transformer"], tmp_path,
                          cache_dir)
        got = OmegaConf.select(cfg, key)
        assert (list(got) if key == "model.inputs" else got) == want, recipe
        validate(cfg)
        for k in ("data", "centre", "loss", "model"):  # everything else as in base
            a, b = (OmegaConf.to_container(c[k], resolve=False) if OmegaConf.is_config(c[k]) else c[k]
                    for c in (cfg, base))
            if k == key.split(".")[0]:
                a.pop(key.split(".")[1]), b.pop(key.split(".")[1])
            assert a == b, (recipe, k)


def _flat(cfg) -> dict:
    """``data`` / ``centre`` / ``loss`` / ``model`` of a composed config as one flat ``{dotted key: value}``."""
    out = {"centre": cfg.centre}
    for k in ("data", "loss", "model"):
        for kk, v in OmegaConf.to_container(cfg[k], resolve=False).items():
            out[f"{k}.{kk}"] = v
    return out


@pytest.mark.parametrize("recipe, want", [
    ("vel_last", {"centre": "last"}),
    ("vel_mirror", {"data.mirror": True}),
    ("vel_foot", {"loss.foot": 1.0}),
    ("vel_fk", {"loss.fk_pos": 1.0}),
    ("vel_keyframe", {"loss.keyframe": 0.1}),
    ("vel_speed", {"data.speed": [1.0, 2.0]}),
])
def test_velocity_combinations_add_one_lever_to_velocity(recipe, want, tmp_path, cache_dir):
    """Round 3's combinations are ``velocity`` plus exactly their own lever (mirroring keeps base's stride of 20)."""
    def flat(r):
        return _flat(compose_cfg("train", ["ablation=recipe", f"+recipe={r}", "model=frame_transformer"], tmp_path,
                                 cache_dir))

    vel, cfg = flat("velocity"), flat(recipe)
    assert cfg["model.inputs"] == ["velocity"]
    assert {k: v for k, v in cfg.items() if vel.get(k) != v} == want
    assert cfg["data.train_offset"] == flat("base")["data.train_offset"] == 20  # vel_mirror: base's window starts
