"""Training through Hydra configs: every model, user commands, multirun, resume, checkpoints, seeds, errors."""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from conftest import TINY, compose_cfg, model_overrides
from inbetweening.evaluation import benchmark as B
from inbetweening.evaluation.collect import collect
from inbetweening.evaluation.collect import main as collect_main
from inbetweening.models import MODELS
from inbetweening.predictor.checkpoint import CheckpointError, load_predictor, predictor_state
from inbetweening.predictor.masks import apply_mask, transition_known
from inbetweening.predictor.predictor import Predictor
from inbetweening.representation import GlobalPosLocalQuat
from inbetweening.training.builders import make_datamodule, make_module
from inbetweening.training.config import ConfigError, validate
from inbetweening.training.module import InbetweenModule, load_module
from inbetweening.training.train import train

ROOT = Path(__file__).resolve().parents[1]
MODEL_TINY = {name: model_overrides(name) for name in MODELS}  # every registered model, its declared TINY sizes
BASE = [o for o in TINY if not o.startswith("model.")] + ["callbacks=none", "logger=none"]


def run_train(tmp_path, cache_dir, overrides, name="run"):
    cfg = compose_cfg("train", overrides, tmp_path / name, cache_dir)
    return train(cfg), cfg


@pytest.mark.parametrize("model", sorted(MODEL_TINY))
def test_fast_dev_run_every_model(model, tmp_path, cache_dir):
    metrics, cfg = run_train(tmp_path, cache_dir, BASE + [f"model={model}", *MODEL_TINY[model], "trainer.fast_dev_run=true"])
    res = json.loads((tmp_path / "run" / "benchmark.json").read_text())
    assert res["model"] == model and res["dataset"] == "synthetic" and res["n_windows"] > 0
    assert set(res["metrics"]) == {f"{m}@{n}" for m in ("l2q", "l2p", "npss") for n in (5, 15, 30, 45)}
    assert all(np.isfinite(v) for v in res["metrics"].values())
    if model in B.BASELINES:  # nothing trained: the Lightning test loop scores like the numpy reference baseline
        dm = make_datamodule(cfg)
        dm.setup("test")
        want = B.evaluate_transitions(dm.test_benchmark_set(), B.BASELINES[model], (5, 15, 30, 45))
        assert metrics.keys() == want.keys()
        for k in want:
            assert metrics[k] == pytest.approx(want[k], rel=1e-4, abs=1e-6), k


@pytest.mark.parametrize("model", ["graph_transformer", "unet1d"])
def test_reported_test_metrics_equal_the_checkpoint_scored_by_the_numpy_benchmark(model, tmp_path, cache_dir):
    """What ``train()`` returns and writes to benchmark.json is the trained checkpoint's score, recomputed here by
    another path: the checkpoint loaded on its own, predictions through ``predict_transitions`` and the numpy
    benchmark (:func:`~inbetweening.evaluation.benchmark.evaluate_transitions`) on the same test windows."""
    over = [o for o in BASE if "max_steps" not in o and not o.startswith("callbacks")] + [
        f"model={model}", *MODEL_TINY[model], "callbacks=default", "callbacks.progress_bar=null",
        "callbacks.skeleton_figure=null",
        "optim.optimizer.lr=1e-2", "optim.scheduler.warmup_steps=0",  # trained well away from init
        "calibrate=false"]  # the network's own score (the blend's: test_calibration.py)
    metrics, cfg = run_train(tmp_path, cache_dir, over)  # one epoch: validation, then the best checkpoint is tested
    ckpts = sorted((tmp_path / "run" / "checkpoints").glob("epoch_*.ckpt"))
    assert len(ckpts) == 1
    module = InbetweenModule.load_from_checkpoint(ckpts[0], map_location="cpu").eval()
    assert module.hparams.model["name"] == model
    dm = make_datamodule(cfg)
    dm.setup("test")
    bench = dm.test_benchmark_set()

    def bare(net):  # a Predictor built from the bare network and the checkpoint's plain values
        return Predictor(net, module.skeleton, module.mean, module.std, mask=module.mask_name, centre=module.centre,
                         n_past=module.n_past, forward_axis=module.forward_axis)

    def predictor(root, q, n):
        return bare(module.net).predict_transitions(root, q, n)

    want = B.evaluate_transitions(bench, predictor, (5, 15, 30, 45))
    assert metrics.keys() == want.keys()
    for k in want:
        assert metrics[k] == pytest.approx(want[k], rel=1e-4, abs=1e-6), k
    assert json.loads((tmp_path / "run" / "benchmark.json").read_text())["metrics"] == pytest.approx(want, rel=1e-4)
    # the score is the trained network's, not an untrained one's nor a baseline's
    untrained = InbetweenModule(**{**module.hparams}).eval()
    for name, predict in (("untrained", lambda r, q, n: bare(untrained.net).predict_transitions(r, q, n)),
                          ("interpolation", B.interpolation)):
        other = B.evaluate_transitions(bench, predict, (15,))
        assert other["l2p@15"] != pytest.approx(want["l2p@15"], rel=1e-3), name  # 10x the tolerance above


def test_interpolation_model_matches_numpy_baseline(tmp_path, cache_dir):
    """The torch Interpolation model through the Lightning test loop scores like the numpy reference baseline."""
    torch_metrics, cfg = run_train(tmp_path, cache_dir, BASE + ["model=interpolation"])
    from inbetweening.training.evaluate import evaluate

    ecfg = compose_cfg("eval", ["model=interpolation", "data.synthetic.num_clips=10", "data.synthetic.min_frames=120",
                                "data.synthetic.max_frames=160"], tmp_path / "eval", cache_dir)
    np_metrics = evaluate(ecfg)
    for k in np_metrics:
        assert torch_metrics[k] == pytest.approx(np_metrics[k], rel=1e-3, abs=1e-4), k


def _net_state(ckpt: Path) -> dict:
    return predictor_state(torch.load(ckpt, map_location="cpu", weights_only=True)["state_dict"])


def _same_state(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


@pytest.mark.parametrize("data", [["data.transition_per=sample"],
                                  ["data.num_workers=1", "mask=joints", "mask.gap_min=5", "mask.gap_max=40"]],
                         ids=["per_sample", "workers_joints"])
def test_resume_at_an_epoch_boundary_equals_the_uninterrupted_run(data, tmp_path, cache_dir):
    """Train 2 epochs at once, or 1 epoch then resume from its last.ckpt for the 2nd: bit-identical weights (data
    order, transition lengths / joint masks, dropout, optimiser and LR schedule all carried over).  Dropout is on
    and the LR is still warming up, so any state the resume loses or re-draws shows in the weights."""
    over = [o for o in TINY if "max_steps" not in o and "max_epochs" not in o] + [
        "callbacks=default", "callbacks.progress_bar=null", "callbacks.skeleton_figure=null", "logger=none",
        "run_test=false", "+trainer.enable_progress_bar=false", *data]
    run_train(tmp_path, cache_dir, over + ["trainer.max_epochs=2"], "full")
    full = tmp_path / "full" / "checkpoints" / "last.ckpt"
    run_train(tmp_path, cache_dir, over + ["trainer.max_epochs=1"], "resumed")
    last = tmp_path / "resumed" / "checkpoints" / "last.ckpt"
    one_epoch = torch.load(last, map_location="cpu", weights_only=True)
    steps = torch.load(full, map_location="cpu", weights_only=True)["global_step"]
    assert one_epoch["global_step"] == steps // 2 and steps >= 8
    assert not _same_state(_net_state(last), _net_state(full))
    # the resume command: same run folder, max_epochs raised, ckpt_path=last.ckpt
    run_train(tmp_path, cache_dir, over + ["trainer.max_epochs=2", f"ckpt_path={last}"], "resumed")
    assert torch.load(last, map_location="cpu", weights_only=True)["global_step"] == steps
    assert _same_state(_net_state(last), _net_state(full)), "resumed run differs from the uninterrupted one"
    # and the comparison can tell runs apart: another seed trains other weights
    run_train(tmp_path, cache_dir, over + ["trainer.max_epochs=2", "seed=7"], "seed7")
    assert not _same_state(_net_state(tmp_path / "seed7" / "checkpoints" / "last.ckpt"), _net_state(full))


def test_load_from_checkpoint_without_hydra_and_keyframes_exact(tmp_path, cache_dir):
    over = TINY + ["callbacks=default", "callbacks.progress_bar=null", "callbacks.skeleton_figure=null", "logger=none"]
    run_train(tmp_path, cache_dir, over)
    ckpt = tmp_path / "run" / "checkpoints" / "last.ckpt"
    module = InbetweenModule.load_from_checkpoint(ckpt, map_location="cpu")  # no Hydra involved
    assert module.skeleton.num_joints == 22
    assert not any(isinstance(v, torch.nn.Module) for v in module.hparams.values())
    module.eval()
    root = torch.randn(2, 26, 3, dtype=torch.float64) * 10
    q = torch.nn.functional.normalize(torch.randn(2, 26, 22, 4, dtype=torch.float64), dim=-1)
    feats = GlobalPosLocalQuat(module.skeleton, module.mean, module.std).encode(root, q).float()
    known = transition_known(2, 26, 22, 10, 15)
    x, interp = apply_mask(module.mask_name, feats, known, module.predictor.representation)
    with torch.no_grad():
        out = module(x, known, interp)
    assert torch.equal(out[known], feats[known])  # keyframes and context pass through bit-exactly
    assert torch.allclose(out[..., 3:].norm(dim=-1), torch.ones(2, 26, 22), atol=1e-5)
    with pytest.raises(CheckpointError, match="does not exist"):
        load_module(str(tmp_path / "missing.ckpt"))
    bad = tmp_path / "bad.ckpt"
    bad.write_bytes(b"not a checkpoint")
    with pytest.raises(CheckpointError, match="not a readable"):
        load_module(str(bad))


def test_same_seed_same_metrics(tmp_path, cache_dir):
    a, _ = run_train(tmp_path, cache_dir, BASE + MODEL_TINY["graph_transformer"], "a")
    b, _ = run_train(tmp_path, cache_dir, BASE + MODEL_TINY["graph_transformer"], "b")
    assert a == b
    c, _ = run_train(tmp_path, cache_dir, BASE + MODEL_TINY["graph_transformer"] + ["seed=7"], "c")
    assert a != c


@pytest.mark.parametrize("norm", ["layer", "batch"])
def test_norms_train_loss_decreases(norm, tmp_path, cache_dir):
    cfg = compose_cfg("train", BASE + [f"model.norm={norm}", "model.d_model=32", "model.depth=2", "model.heads=2",
                                       "model.dropout=0.0", "model.residual_to_interpolation=false"], tmp_path, cache_dir)
    torch.manual_seed(0)
    dm = make_datamodule(cfg)
    dm.setup("fit")
    module = make_module(cfg, dm)
    opt = torch.optim.Adam(module.parameters(), lr=3e-3)
    batch = dm.collate_train(list(range(8)))

    def loss():
        return module._step_loss(batch, "train")

    module.train()
    first = float(loss())
    for _ in range(25):
        opt.zero_grad()
        loss().backward()
        opt.step()
    assert float(loss()) < 0.7 * first


def test_frozen_parameters_keep_their_values_and_the_rest_train(tmp_path, cache_dir):
    """``optim.freeze``: the parameters whose names match keep their values through optimiser steps, the others move;
    a pattern that matches nothing is one clear line naming the key."""
    cfg = compose_cfg("train", BASE + MODEL_TINY["graph_transformer"] + ["optim.freeze=['layers.0.*','in_*']"],
                      tmp_path, cache_dir)
    validate(cfg)
    dm = make_datamodule(cfg)
    dm.setup("fit")
    module = make_module(cfg, dm)
    before = {n: p.detach().clone() for n, p in module.net.named_parameters()}
    frozen = {n for n in before if re.match(r"layers\.0\.|in_", n)}  # the test's own reading of the patterns
    assert frozen and len(frozen) < len(before) and set(module.frozen) == frozen
    opt = module.configure_optimizers()["optimizer"]
    batch = dm.collate_train(list(range(8)))
    module.train()
    for _ in range(3):
        opt.zero_grad()
        module._step_loss(batch, "train").backward()
        opt.step()
    after = dict(module.net.named_parameters())
    assert all(torch.equal(after[n], before[n]) for n in frozen)
    assert all(not torch.equal(after[n], before[n]) for n in before if n not in frozen and n.endswith("weight")
               and n.startswith("layers."))
    bad = compose_cfg("train", BASE + MODEL_TINY["graph_transformer"] + ["optim.freeze=['encoder.*']"], tmp_path / "b",
                      cache_dir)
    with pytest.raises(ConfigError, match=r"^optim.freeze: 'encoder.\*' matches no parameter of the network "
                                          r"\(GraphTransformer.*layers.0"):
        make_module(bad, dm)


@pytest.mark.parametrize(
    "override,key",
    [("mask.name=bogus", "mask.name"), ("model.heads=3", "model.heads"), ("model.depth=0", "model.depth"),
     ("data.transition_min=20", "data.transition_min"), ("data.transition_max=60", "data.transition_max"),
     ("+loss.l3=1", "loss.l3"), ("optim.optimizer.lr=-1", "optim.optimizer.lr")],
)
def test_config_validation_names_the_key(override, key, tmp_path, cache_dir):
    extra = ["data.transition_max=10"] if override.startswith("data.transition_min") else []
    cfg = compose_cfg("train", [override, *extra], tmp_path, cache_dir)
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        validate(cfg)


def _cli(args, cwd, timeout=600):
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.run([sys.executable, *args], cwd=cwd, capture_output=True, text=True, timeout=timeout, env=env)


def test_user_command_single_run(tmp_path, cache_dir):
    r = _cli(["train.py", "model.depth=6", "mask=lerp", *[o for o in TINY if not o.startswith("model.depth")],
              "callbacks.progress_bar=null", f"hydra.run.dir={tmp_path}/run", f"paths.cache_dir={cache_dir}"], ROOT)
    assert r.returncode == 0, r.stderr[-3000:]
    res = json.loads((tmp_path / "run" / "benchmark.json").read_text())
    assert res["model"] == "graph_transformer"
    assert "| graph_transformer |" in r.stdout
    assert (tmp_path / "run" / "checkpoints" / "last.ckpt").exists()
    assert any((tmp_path / "run" / "tensorboard").iterdir())


def test_user_command_multirun_and_collect(tmp_path, cache_dir):
    r = _cli(["train.py", "-m", "mask=zero,lerp", *TINY, "callbacks=none", "logger=none",
              f"hydra.sweep.dir={tmp_path}/sweep", f"paths.cache_dir={cache_dir}"], ROOT)
    assert r.returncode == 0, r.stderr[-3000:]
    rows = collect(tmp_path / "sweep")
    assert len(rows) == 2 and {row["config"].split()[0] for row in rows} == {"mask=zero", "mask=lerp"}
    assert rows[0]["l2p@15"] <= rows[1]["l2p@15"]
    assert collect_main([str(tmp_path / "sweep")]) == 0
    md = (tmp_path / "sweep" / "results.md").read_text()
    assert "mask=zero" in md and "L2P@15" in md
    assert (tmp_path / "sweep" / "results.csv").read_text().count("\n") == 3


def test_cli_bad_config_is_one_clear_line(tmp_path, cache_dir):
    r = _cli(["train.py", "model.heads=3", f"hydra.run.dir={tmp_path}/run", f"paths.cache_dir={cache_dir}"], ROOT)
    assert r.returncode == 2
    assert r.stderr.strip().splitlines()[-1].startswith("error: model.heads")
    assert "Traceback" not in r.stderr


def test_ablation_config_declares_grid(tmp_path, cache_dir):
    cfg = compose_cfg("train", ["ablation=method"], tmp_path, cache_dir)
    from hydra import compose, initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    from conftest import CONF_DIR

    GlobalHydra.instance().clear()
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        full = compose("train", overrides=["ablation=method"], return_hydra_config=True)
    params = full.hydra.sweeper.params
    sizes = [len(str(v).split(",")) for v in params.values()]
    assert str(full.hydra.mode) == "RunMode.MULTIRUN" and int(np.prod(sizes)) == 32
    assert cfg.model.name == "graph_transformer"


@pytest.mark.parametrize("model", ["graph_transformer", "unet1d", "interpolation"])
def test_mocap_recovery_mask_trains_and_reports_rmse(model, tmp_path, cache_dir):
    metrics, _ = run_train(tmp_path, cache_dir, BASE + [f"model={model}", *MODEL_TINY[model], "mask=joints",
                                                        "mask.gap_min=5", "mask.gap_max=40"])
    assert metrics["recovery_rmse"] > 0 and np.isfinite(metrics["recovery_rmse"])
    assert json.loads((tmp_path / "run" / "benchmark.json").read_text())["metrics"]["recovery_rmse"] > 0


def test_all_loss_terms_train(tmp_path, cache_dir):
    metrics, _ = run_train(tmp_path, cache_dir, BASE + MODEL_TINY["graph_transformer"] + [
        "loss.fk_pos=0.5", "loss.quat=0.5", "loss.bone=0.1", "loss.smooth=0.1", "loss.foot=0.1", "loss.keyframe=0.5",
        "optim=sgd"])
    assert all(np.isfinite(v) for v in metrics.values())


def test_models_ablation_sweeps_every_registered_model():
    """``ablation=models`` sweeps ``glob(*)`` over conf/model: a new model (module + yaml + registry line) joins it;
    task=retarget's networks (:data:`~inbetweening.models.RETARGETERS`) are left out."""
    from hydra import compose, initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra
    from hydra.core.override_parser.overrides_parser import OverridesParser

    from conftest import CONF_DIR
    from inbetweening.models import MODELS, RETARGETERS

    GlobalHydra.instance().clear()
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        full = compose("train", overrides=["ablation=models"], return_hydra_config=True)
    (override,) = OverridesParser.create().parse_overrides([f"model={full.hydra.sweeper.params.model}"])
    yamls = sorted(p.stem for p in Path(CONF_DIR, "model").glob("*.yaml"))
    assert override.value().filter(yamls) == sorted(MODELS) == [y for y in yamls if y not in RETARGETERS]


@pytest.mark.parametrize("ablation,runs", [("axes", 6)])
def test_other_ablations_declare_grids(ablation, runs):
    from hydra import compose, initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    from conftest import CONF_DIR

    GlobalHydra.instance().clear()
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        full = compose("train", overrides=[f"ablation={ablation}"], return_hydra_config=True)
        params = full.hydra.sweeper.params
        assert int(np.prod([len(str(v).split(",")) for v in params.values()])) == runs
        if ablation == "axes":  # every variant composes
            for v in str(params["+variant"]).split(","):
                c = compose("train", overrides=[f"+variant={v}"])
                validate(c)


def test_experiment_configs_compose(tmp_path, cache_dir):
    for exp in ("quick", "bn2_ablation", "bn2_reference"):
        cfg = compose_cfg("train", [f"experiment={exp}"], tmp_path, cache_dir)
        validate(cfg)
    assert cfg.data.name == "bandai_namco" and cfg.trainer.max_time == "00:01:22:00"


@pytest.mark.parametrize("exp,target", [("joblib", "JoblibLauncher"), ("slurm", "SlurmLauncher")])
def test_launcher_experiments_compose(exp, target):
    from hydra import compose, initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    from conftest import CONF_DIR

    GlobalHydra.instance().clear()
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        full = compose("train", overrides=[f"experiment={exp}"], return_hydra_config=True)
    assert full.hydra.launcher._target_.endswith(target)


def test_ablation_name_launches_multirun(tmp_path, cache_dir):
    """`python train.py ablation=axes` runs its whole grid (hydra.mode MULTIRUN declared in the config)."""
    r = _cli(["train.py", "ablation=axes", *TINY, "callbacks=none", "logger=none",
              f"hydra.sweep.dir={tmp_path}/sweep", f"paths.cache_dir={cache_dir}"], ROOT)
    assert r.returncode == 0, r.stderr[-3000:]
    rows = collect(tmp_path / "sweep")
    assert sorted(row["config"] for row in rows) == sorted(
        f"+variant={v}" for v in ("base", "mask_zero", "graph_none", "norm_batch", "depth_12", "heads_8"))


@pytest.mark.parametrize("centre", ["known", "last", "window"])
def test_the_canonical_frame_removes_the_window_centring_leak(centre):
    """Moving a whole window in XZ and turning it about Y (what a different whole-window normalisation does) moves
    the prediction by exactly that rigid motion, whatever the centre mode (legacy ``window`` included: the one
    centring stage uses the known frames only); moving only the target keyframe changes the answer (the check can
    tell)."""
    from inbetweening.data.synthetic import NAMES, OFFSETS, PARENTS
    from inbetweening.geometry.quaternion import qmul, qrot
    from inbetweening.geometry.skeleton import Skeleton

    torch.manual_seed(0)
    sk = Skeleton(NAMES, PARENTS, OFFSETS)
    mean, std = np.zeros(66), np.full(66, 50.0)
    module = InbetweenModule(model={"name": "graph_transformer", "d_model": 16, "depth": 1, "heads": 2, "dropout": 0.0,
                                    "residual_to_interpolation": False},
                             skeleton=sk.to_dict(), pos_mean=mean.tolist(), pos_std=std.tolist(), centre=centre).eval()
    with torch.no_grad():  # a non-trivial head so the prediction depends on the input
        module.net.out_weight.normal_(0, 0.3)
    pr = module.predictor
    root = torch.randn(2, 21, 3, dtype=torch.float64) * 20
    q = torch.nn.functional.normalize(torch.randn(2, 21, 22, 4, dtype=torch.float64), dim=-1)
    known = transition_known(2, 21, 22, 10, 10)
    shift = torch.tensor([35.0, 0.0, -20.0], dtype=torch.float64)
    yaw = torch.tensor([np.cos(0.35), 0.0, np.sin(0.35), 0.0], dtype=torch.float64)  # 0.7 rad about +Y
    moved_q = q.clone()
    moved_q[:, :, 0] = qmul(yaw.expand(2, 21, 4), q[:, :, 0])
    outs = []
    for r, qq in ((root, q), (qrot(yaw.expand(2, 21, 4), root) + shift, moved_q)):
        out = pr.predict_windows(r, qq, known)
        assert torch.equal(out.root[known[..., 0]], r[known[..., 0]])  # keys bit-exact, in the input's frame
        assert torch.equal(out.local_q[known], qq[known])
        outs.append(pr.world_positions(out))
    want = qrot(yaw.expand(2, 21, 22, 4), outs[0]) + shift
    assert torch.allclose(outs[1], want, atol=1e-3)
    # control: moving the target keyframe alone is not a rigid motion of the window, and the answer changes
    r2 = root.clone()
    r2[:, 20] += shift
    other = pr.world_positions(pr.predict_windows(r2, q, known))
    assert not torch.allclose(other[:, 10:20], outs[0][:, 10:20], atol=1e-3)


def test_ddp_trainer_config_builds_a_ddp_trainer(tmp_path, cache_dir):
    """``trainer=ddp`` composes, validates and instantiates a Trainer with a DDP strategy (nothing is launched)."""
    from hydra.utils import instantiate
    from lightning.pytorch.strategies import DDPStrategy

    from inbetweening.training.builders import make_trainer

    cfg = compose_cfg("train", ["trainer=ddp", "trainer.accelerator=cpu", "trainer.devices=2", "logger=none"],
                      tmp_path, cache_dir)
    validate(cfg)
    assert cfg.trainer.strategy == "ddp" and cfg.trainer.sync_batchnorm is True
    for trainer in (instantiate(cfg.trainer, callbacks=[], logger=False), make_trainer(cfg)):
        assert isinstance(trainer.strategy, DDPStrategy), type(trainer.strategy)
        assert trainer.num_devices == 2 and trainer.world_size == 2 and trainer.num_nodes == 1
        assert trainer.max_epochs == cfg.trainer.max_epochs
    default = instantiate(compose_cfg("train", [], tmp_path, cache_dir).trainer, logger=False)
    assert not isinstance(default.strategy, DDPStrategy)  # the comparison can fail: the cpu trainer is not DDP


def test_recipe_levers_train_end_to_end_and_report_keyframes_and_ratios(tmp_path, cache_dir):
    """Clip sampling every 2 frames, mirroring, 1-10 context frames, intermediate keyframes, centre=last: the run
    trains, and benchmark.json holds the interpolation reference and the keyframes-only figures."""
    over = BASE + MODEL_TINY["graph_transformer"] + [
        "data.train_offset=2", "data.mirror=true", "data.context_min=1",
        "data.keyframes_max=2", "data.keyframe_prob=0.5", "centre=last", "test_keyframes=[5]", "threads=1",
        "model.inputs=[rot6d,velocity]", "loss.keyframe=0.5"]
    threads = torch.get_num_threads()
    try:
        metrics, cfg = run_train(tmp_path, cache_dir, over)
        assert torch.get_num_threads() == 1
    finally:
        torch.set_num_threads(threads)
    res = json.loads((Path(cfg.paths.output_dir) / "benchmark.json").read_text())
    assert set(res["interpolation"]) == set(res["metrics"]) and res["metrics"] == metrics
    row = res["keyframes"]["5"]
    assert row["model_cm"] > 0 and abs(row["ratio"] - row["model_cm"] / row["interp_cm"]) < 1e-9
    ckpt = sorted((Path(cfg.paths.output_dir) / "checkpoints").glob("*.ckpt"))[0]
    predictor = load_predictor(ckpt)  # the derived inputs are part of the checkpoint's model
    assert predictor.net.inputs == ("rot6d", "velocity") and predictor.net.input_dim == 16
