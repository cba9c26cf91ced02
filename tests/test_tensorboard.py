"""What a run writes to TensorBoard (issue 14): groups, interpolation references and ratios, figures, HParams.

The fast tests read the event files with TensorBoard's own reader; the slow one runs a real sweep through the CLI,
starts TensorBoard on 127.0.0.1 and reads its HTTP API like the browser does."""
from __future__ import annotations

import json
import os
import re
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest
import torch

from conftest import TINY, compose_cfg
from inbetweening.training.builders import make_datamodule, make_module
from inbetweening.training.figures import HEIGHT_PX, WIDTH_PX, frames_to_draw, per_joint_figure, transition_figure
from inbetweening.training.tb_logging import BASELINE, custom_scalars_layout, hparams_metrics, tb_scalars
from inbetweening.training.tb_runs import curated_hparams, resumed_run, run_label, run_version, trial_id
from inbetweening.training.train import train

ROOT = Path(__file__).resolve().parents[1]
FIT = [o for o in TINY if "max_steps" not in o and "max_epochs" not in o] + [
    "trainer.max_epochs=2", "callbacks.progress_bar=null", "callbacks.skeleton_figure.every_n_epochs=5"]


def _events(run_dir: Path):
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    dirs = sorted({p.parent for p in run_dir.rglob("events.out.tfevents.*") if p.parent.name != "~columns"})
    assert len(dirs) == 1, dirs
    ea = EventAccumulator(str(dirs[0]), size_guidance={"scalars": 0, "images": 0, "tensors": 0})
    ea.Reload()
    return dirs[0], ea


# ------------------------------------------------------------------ pure pieces
def test_scalars_give_interpolation_reference_and_ratio():
    logs = tb_scalars("val", {"l2p@5": 1.0, "l2p@15": 3.0, "l2q@15": 0.5}, {"l2p@5": 2.0, "l2p@15": 2.0, "l2q@15": 0.0,
                                                                            "l2p@30": 9.0}, 12.5)
    assert logs["val/l2p_ratio@5"] == 0.5 and logs["val/l2p_ratio@15"] == 1.5
    assert logs["~interpolation/val/l2p@15"] == 2.0 and logs["val/l2p_mean"] == 2.0 and logs["val/pos_rmse_cm"] == 12.5
    assert "val/l2q_ratio@15" not in logs  # interpolation scored 0: no ratio rather than inf
    assert "~interpolation/val/l2p@30" not in logs  # a length the model was not scored at
    assert not any("interp" in k.split("/")[0] for k in logs if k.startswith("val/"))  # no baseline in the model's group


def test_curated_hparams_put_swept_keys_first_with_the_budget(tmp_path, cache_dir):
    cfg = compose_cfg("train", ["model.depth=2", "mask=zero", "optim.optimizer.lr=0.01"], tmp_path, cache_dir)
    hp, shown = curated_hparams(cfg, ["model.depth=2", "mask=zero", "optim.optimizer.lr=0.01", "seed=3",
                                      "hydra.run.dir=/x", "ckpt_path=a.ckpt"])
    assert list(hp)[:4] == ["model/depth", "mask/name", "optim/optimizer/lr", "seed"]
    assert hp["model/depth"] == 2 and hp["mask/name"] == "zero" and hp["optim/optimizer/lr"] == 0.01
    # the keys set, and always calibrate and the representation; nothing else constant
    assert shown == ["model/depth", "mask/name", "optim/optimizer/lr", "seed", "calibrate", "representation"]
    assert {"trainer/max_epochs", "trainer/max_steps", "trainer/max_time", "data/name", "model/name"} <= set(hp)
    assert hp["trainer/max_time"] == "none" and hp["optim/optimizer"] == "AdamW"
    assert not any(k.startswith(("hydra", "ckpt_path", "paths")) for k in hp)
    assert all(isinstance(v, (bool, int, float, str)) for v in hp.values())
    # what distinguishes the run leads, keys shortened, the model last
    assert run_label(cfg, ["model.depth=2", "hydra.run.dir=/x", "data.path=/a/b"]) == "depth=2 - graph_transformer"
    assert run_label(cfg, []) == "graph_transformer"
    # a group set to its default option says nothing about the run (the primary config's defaults list)
    assert run_label(cfg, ["data=synthetic", "model.depth=2"], defaults={"data": "synthetic"}) == \
        "depth=2 - graph_transformer"
    assert run_label(cfg, ["mask=lerp", "model.depth=2"], swept=["mask"], defaults={"mask": "lerp"}) == \
        "lerp (mask) - graph_transformer"  # in a sweep the default value is one of the values swept
    assert run_label(cfg, ["model.dropout=0.1", "loss.dropout=0"]) == "loss.dropout=0 model.dropout=0.1 - graph_transformer"
    long = run_label(cfg, [f"data.synthetic.key_{i}=value_{i}" for i in range(20)])
    assert len(long) <= 100 and long.endswith("more - graph_transformer") and long.startswith("key_0=value_0")
    # in a sweep: the swept keys come first, are the ones shown, and name the run
    hp, shown = curated_hparams(cfg, ["model.depth=2", "mask=zero", "seed=3"], swept=["seed"])
    assert list(hp)[0] == "seed" and shown == ["seed", "calibrate", "representation"]  # no model/name, data/name...
    assert run_label(cfg, ["model.depth=2", "seed=3"], swept=["seed"]) == "3 (seed) - graph_transformer"
    # what distinguishes the run leads (the example: a mask x norm sweep), the model last unless swept
    assert run_label(cfg, ["data=synthetic", "mask=zero", "model.norm=layer"], swept=["mask", "model.norm"]) == \
        "zero layer (mask norm) - graph_transformer"  # the values first: an image card shows ~16 characters
    assert run_label(cfg, ["model=unet1d", "seed=3"], swept=["model", "seed"]) == "unet1d 3 (model seed)"
    assert hparams_metrics([5, 45], [5])[:3] == ["val/l2p_mean_best", "test/l2p_ratio@5", "test/l2p_ratio@45"]


def test_figures_are_thumbnail_sized_and_draw_what_they_say():
    names = ["Hips", "Spine", "Head"]
    model = {5: {"pos": np.array([1.0, 2.0, 3.0]), "rot": np.array([4.0, 5.0, 6.0])}}
    fig = per_joint_figure(names, model, {5: {"pos": np.ones(3), "rot": np.ones(3)}})
    (ax,) = fig.axes
    assert [t.get_text() for t in ax.get_xticklabels()] == names  # skeleton order, not alphabetical
    assert "cm" in ax.get_ylabel() and len(ax.get_lines()) == 2  # model and interpolation
    assert np.allclose(ax.get_lines()[0].get_ydata(), [1.0, 2.0, 3.0])
    rot = per_joint_figure(names, model, key="rot").axes[0]
    assert "deg" in rot.get_ylabel() and np.allclose(rot.get_lines()[0].get_ydata(), [4.0, 5.0, 6.0])
    t, j = 26, 3
    gt = np.zeros((t, j, 3))
    gt[:, 1, 1], gt[:, 2, 1] = 50.0, 100.0
    pred = gt + np.linspace(0, 1, t)[:, None, None]
    frames = frames_to_draw(10, 15, 6)
    assert frames[0] == 9 and frames[-1] == 25 and len(frames) == 6
    fig = transition_figure(gt, pred, gt, [-1, 0, 1], 10, 15, frames, title="x")
    w, h = fig.get_size_inches() * fig.dpi
    assert (w, h) == (WIDTH_PX, HEIGHT_PX)  # drawn for the card: tests/test_figures.py checks the text and legends
    err = fig.axes[len(frames)]
    model_line, interp_line = err.get_lines()[:2]
    assert np.allclose(model_line.get_ydata(), np.linspace(0, 1, t)[10:25] * np.sqrt(3))
    assert np.allclose(interp_line.get_ydata(), 0.0)
    assert [a.get_title() for a in fig.axes[:len(frames)]][0] == "9 key"


def test_validation_skips_lengths_its_windows_are_too_short_for(tmp_path, cache_dir):
    cfg = compose_cfg("train", TINY, tmp_path, cache_dir)
    dm = make_datamodule(cfg)
    dm.prepare_data()
    dm.setup("fit")
    module = make_module(cfg, dm).eval()
    assert 45 in module.val_bench.lengths
    batch = next(iter(dm.val_dataloader()))
    short = {"root": batch["root"][:, :50], "q": batch["q"][:, :50]}  # 10 + 45 + 1 = 56 frames would be needed
    with torch.no_grad():
        module._bench_step(short, "val")
    res = module.val_bench.compute()
    assert {"l2p@5", "l2p@15", "l2p@30"} <= set(res) and "l2p@45" not in res


# ------------------------------------------------------------------ a tiny run read back
@pytest.fixture(scope="module")
def fitted(tmp_path_factory, cache_dir):
    out = tmp_path_factory.mktemp("tb_run")
    cfg = compose_cfg("train", FIT, out, cache_dir)
    metrics = train(cfg)
    return out, metrics


def test_groups_read_train_val_test(fitted):
    out, metrics = fitted
    run, ea = _events(out / "tensorboard")
    assert run.parent.name == "graph_transformer"  # <label>/<start time>: named after the configuration
    scalars = set(ea.Tags()["scalars"])
    # no "epoch", "hp", per-joint; the baseline in a group of its own that TensorBoard lists after the model's
    assert {t.split("/")[0] for t in scalars} == {"train", "val", "test", "test_network", BASELINE}, scalars
    assert sorted(["val", "test", "test_network", "train", BASELINE])[-1] == BASELINE  # compared by character code
    # test/: the calibrated fill (what the tools deliver); test_network/: the network alone, beside it
    for n in (5, 15, 30, 45):
        net = ea.Scalars(f"test_network/l2p@{n}")[-1].value
        assert ea.Scalars(f"test_network/l2p_ratio@{n}")[-1].value == pytest.approx(
            net / ea.Scalars(f"{BASELINE}/test/l2p@{n}")[-1].value, rel=1e-5)
    assert any(ea.Scalars(f"test_network/l2p@{n}")[-1].value != ea.Scalars(f"test/l2p@{n}")[-1].value
               for n in (5, 15, 30, 45))
    assert {"train/lr", "train/windows_per_s", "train/epoch_time_s", "train/grad_norm", "train/epoch",
            "train/sampled_transition_frames", "val/l2p@45", "val/l2p_mean_best", "test/l2p@45"} <= scalars
    for n in (5, 15, 30, 45):
        for stage in ("val", "test"):
            assert {f"{stage}/l2p_ratio@{n}", f"{BASELINE}/{stage}/l2p@{n}", f"{stage}/l2q_ratio@{n}"} <= scalars
        assert ea.Scalars(f"test/l2p@{n}")[-1].value == pytest.approx(metrics[f"l2p@{n}"], rel=1e-6)
        model, interp = ea.Scalars(f"val/l2p@{n}"), ea.Scalars(f"{BASELINE}/val/l2p@{n}")
        ratio = ea.Scalars(f"val/l2p_ratio@{n}")
        assert len(model) == len(interp) == 2 and interp[0].value == interp[1].value  # cached, deterministic
        assert ratio[-1].value == pytest.approx(model[-1].value / interp[-1].value, rel=1e-5)
    # the test values sit where the validation curves end, not alone one step further
    assert {e.step for t in scalars if t.startswith(("test/", "test_network/", f"{BASELINE}/test/"))
            for e in ea.Scalars(t)} == \
        {ea.Scalars("val/l2p@15")[-1].step}
    best = [e.value for e in ea.Scalars("val/l2p_mean_best")]
    assert best == [min(e.value for e in ea.Scalars("val/l2p_mean")[: i + 1]) for i in range(2)]
    assert all(e.value > 0 for e in ea.Scalars("train/grad_norm"))


def test_figures_are_logged_at_the_validation_steps(fitted):
    out, _ = fitted
    _, ea = _events(out / "tensorboard")
    val_steps = [e.step for e in ea.Scalars("val/l2p@15")]
    assert [e.step for e in ea.Images("val/per_joint")] == val_steps == [e.step for e in ea.Images("val/per_joint_rotation")]
    skel = [e.step for e in ea.Images("val/skeleton")]
    assert skel == val_steps  # epoch 0 (every 5) and the last (also the best) epoch, nothing off by one
    img = ea.Images("val/skeleton")[-1]
    assert (img.width, img.height) == (WIDTH_PX, HEIGHT_PX) and img.encoded_image_string[:4] == b"\x89PNG"


def test_hparams_session_starts_with_the_fit(fitted):
    """The session is written when fitting starts (running runs appear) and ended after the test; no run writes an
    HParams experiment of its own: the folder's columns are in the run ``~columns`` (see the test below), with
    ``calibrate`` and the representation among them."""
    from tensorboard.plugins.hparams import metadata

    out, _ = fitted
    _, ea = _events(out / "tensorboard")
    tensors = set(ea.Tags()["tensors"])
    assert {metadata.SESSION_START_INFO_TAG, metadata.SESSION_END_INFO_TAG} <= tensors
    assert metadata.EXPERIMENT_TAG not in tensors
    assert "custom_scalars__config__" in tensors
    start = ea.Tensors(metadata.SESSION_START_INFO_TAG)[0].wall_time
    assert start < ea.Scalars("train/loss")[0].wall_time  # written when fitting starts: running runs appear
    content = ea.SummaryMetadata(metadata.SESSION_START_INFO_TAG).plugin_data.content
    names = set(metadata.parse_session_start_info_plugin_data(content).hparams)
    assert "trainer/max_epochs" in names and "hp_metric" not in names
    columns = json.loads((out / "tensorboard" / "~columns" / "columns.json").read_text())
    assert {"calibrate", "representation"} <= set(columns["hparams"])
    assert "test_network/l2p_ratio@15" in columns["metrics"]


def test_logging_leaves_the_results_and_the_rng_alone(tmp_path, cache_dir, fitted):
    """The same run without any TensorBoard output gives the same numbers (figures and references draw no
    random numbers and change no state)."""
    _, metrics = fitted
    quiet = compose_cfg("train", FIT + ["logger=none", "callbacks.skeleton_figure=null"], tmp_path, cache_dir)
    assert train(quiet) == metrics


def test_resume_with_logging_equals_the_uninterrupted_run(tmp_path, cache_dir):
    """With every TensorBoard output on (figures each epoch), 1 epoch + resume = 2 epochs at once: same weights
    (nothing logged draws from the RNG), and the resumed run keeps the best ``val/l2p_mean`` of its first part."""
    over = [o for o in FIT if not o.startswith(("trainer.max_epochs", "callbacks.skeleton_figure"))] + [
        "callbacks.skeleton_figure.every_n_epochs=1", "run_test=false", "model.dropout=0.1"]
    train(compose_cfg("train", over + ["trainer.max_epochs=2"], tmp_path / "full", cache_dir))
    train(compose_cfg("train", over + ["trainer.max_epochs=1"], tmp_path / "part", cache_dir))
    last = tmp_path / "part" / "checkpoints" / "last.ckpt"
    first_best = torch.load(last, map_location="cpu", weights_only=True)["val_l2p_mean_best"]
    assert first_best is not None
    train(compose_cfg("train", over + ["trainer.max_epochs=2", f"ckpt_path={last}"], tmp_path / "part", cache_dir))
    a, b = (torch.load(d / "checkpoints" / "last.ckpt", map_location="cpu", weights_only=True)
            for d in (tmp_path / "full", tmp_path / "part"))
    assert a["state_dict"].keys() == b["state_dict"].keys()
    assert all(torch.equal(a["state_dict"][k], b["state_dict"][k]) for k in a["state_dict"])
    assert b["val_l2p_mean_best"] == a["val_l2p_mean_best"] <= first_best


def test_a_resumed_fit_continues_its_tensorboard_run(tmp_path):
    """Resuming (python train.py ... ckpt_path=<run>/checkpoints/last.ckpt, in that run directory or a new one)
    continues the TensorBoard run the checkpoint's run logged to: the ``tensorboard`` link of its run directory, or the
    one run folder under it (runs logged before the link); a fresh fit gets a run of its own."""
    from omegaconf import OmegaConf

    run, new = tmp_path / "logs/train/runs/a", tmp_path / "logs/train/runs/b"
    cfg = OmegaConf.create({"ckpt_path": str(run / "checkpoints/last.ckpt"), "paths": {"output_dir": str(new)}})
    assert resumed_run(cfg) is None  # nothing logged yet
    events = tmp_path / "logs/tensorboard/depth=2 - graph_transformer/2026-01-01_00-00-00"
    events.mkdir(parents=True)
    from inbetweening.training.tb_runs import link_run

    link_run(run, events)
    assert (run / "tensorboard").is_symlink()
    assert resumed_run(cfg) == events.resolve()
    assert resumed_run(OmegaConf.merge(cfg, {"ckpt_path": None})) is None
    old = tmp_path / "old"  # the layout before: <run>/tensorboard/<label>/events...
    (old / "tensorboard/graph_transformer").mkdir(parents=True)
    (old / "tensorboard/graph_transformer/events.out.tfevents.1").write_bytes(b"")
    cfg = OmegaConf.create({"ckpt_path": str(old / "checkpoints/last.ckpt"), "paths": {"output_dir": str(old)}})
    assert resumed_run(cfg) == old / "tensorboard/graph_transformer"
    (old / "tensorboard/other").mkdir()
    (old / "tensorboard/other/events.out.tfevents.2").write_bytes(b"")
    assert resumed_run(cfg) is None  # several: a run of its own


# ------------------------------------------------------------------ which experiment TensorBoard serves
def _served_experiment(logdir: Path, runs: list[Path]):
    """The HParams experiment TensorBoard's own plugin backend serves for ``logdir`` (what the dashboard asks for:
    ``/data/plugin/hparams/experiment`` with its hparams limit), the runs found in the order given."""
    from tensorboard import context
    from tensorboard.backend.event_processing import data_provider, plugin_event_multiplexer
    from tensorboard.plugins import base_plugin
    from tensorboard.plugins.hparams import api_pb2, backend_context, get_experiment

    mux = plugin_event_multiplexer.EventMultiplexer()
    for run in runs:
        mux.AddRun(str(run), str(run.relative_to(logdir)))
    mux.Reload()
    tb = base_plugin.TBContext(logdir=str(logdir), multiplexer=mux,
                               data_provider=data_provider.MultiplexerDataProvider(mux, str(logdir)))
    request = api_pb2.GetExperimentRequest(experiment_name="", hparams_limit=1000)
    return get_experiment.Handler(context.RequestContext(), backend_context.Context(tb), "", request).run()


def _default_columns(exp) -> list[str]:
    """The hparam columns the HParams dashboard shows before any click: the first 5 once those marked ``differs``
    are put first (tf-hparams-query-pane's ``_computeHParams``)."""
    infos = sorted(exp.hparam_infos, key=lambda h: not h.differs)  # stable, as the dashboard's sort
    return [h.name for h in infos[:5]]


def _session(logdir: Path, cfg, overrides: list[str], swept: list[str], version: str) -> Path:
    """One run's HParams session written as a fit writes it (:func:`make_trainer`'s wiring: curated hparams, the
    folder's columns updated) and a few of its scalars; returns the run's folder."""
    import lightning as L

    from inbetweening.training.tb_logging import HParamsSession, RunLogger

    logger = RunLogger(save_dir=str(logdir), name="", version=version)
    hp, shown = curated_hparams(cfg, overrides, swept)
    session = HParamsSession(hp, shown, [5, 15], [5, 15])
    trainer = L.Trainer(logger=logger, enable_checkpointing=False, enable_progress_bar=False,
                        enable_model_summary=False)
    session.start(trainer)
    logger.log_metrics({"val/l2p_mean_best": 0.5, "test/l2p_ratio@15": 0.9, "train/loss": 1.0}, step=1)
    logger.end_session("success")
    logger.finalize("success")
    return logdir / version


def _rows(logdir: Path) -> dict[str, dict[str, object]]:
    """The HParams table as TensorBoard's plugin backend serves it: ``{trial id: {column: value}}``."""
    from tensorboard import context
    from tensorboard.backend.event_processing import data_provider, plugin_event_multiplexer
    from tensorboard.plugins import base_plugin
    from tensorboard.plugins.hparams import api_pb2, backend_context, list_session_groups

    mux = plugin_event_multiplexer.EventMultiplexer()
    mux.AddRunsFromDirectory(str(logdir))
    mux.Reload()
    tb = base_plugin.TBContext(logdir=str(logdir), multiplexer=mux,
                               data_provider=data_provider.MultiplexerDataProvider(mux, str(logdir)))
    request = api_pb2.ListSessionGroupsRequest(
        experiment_name="", allowed_statuses=[api_pb2.STATUS_UNKNOWN, api_pb2.STATUS_SUCCESS, api_pb2.STATUS_RUNNING],
        aggregation_type=api_pb2.AGGREGATION_AVG, start_index=0, slice_size=100)
    groups = list_session_groups.Handler(context.RequestContext(), backend_context.Context(tb), "", request).run()
    from google.protobuf.json_format import MessageToDict

    return {g.name: {k: MessageToDict(v) for k, v in g.hparams.items()} for g in groups.session_groups}


@pytest.mark.parametrize("single_first", [True, False])
def test_every_sweeps_keys_are_columns_with_every_runs_value(tmp_path, cache_dir, single_first):
    """One --logdir holding two single runs and two sweeps (``mask=zero,lerp model.norm=layer,batch``, then
    ``model.depth=2,4``), in either order: TensorBoard's plugin serves one experiment whose columns are every swept
    key of both sweeps (and the single runs' keys, calibrate and the representation), and every run's row has a
    value in each (before: the second sweep's experiment hid the first sweep's columns)."""
    logdir = tmp_path / "logs"
    singles = [(["data.batch_size=8", "seed=1"], [], "single/a"), (["data.batch_size=8", "seed=1"], [], "single/b")]
    first = [([f"mask={m}", f"model.norm={n}"], ["mask", "model.norm"], f"s1/{m}-{n}")
             for m in ("zero", "lerp") for n in ("layer", "batch")]
    second = [([f"model.depth={d}"], ["model.depth"], f"s2/{d}") for d in (2, 4)]
    for over, swept, version in (singles + first + second) if single_first else (second + first + singles):
        cfg = compose_cfg("train", over, tmp_path / version, cache_dir)
        _session(logdir, cfg, over, swept, version)
    runs = sorted(p.parent for p in logdir.rglob("events.out.tfevents.*"))
    exp = _served_experiment(logdir, runs)
    columns = [h.name for h in exp.hparam_infos]
    assert {"mask/name", "model/norm", "model/depth", "data/batch_size", "seed", "calibrate", "representation"} \
        <= set(columns)
    assert len(columns) == len(set(columns))
    differs = {h.name for h in exp.hparam_infos if h.differs}  # shown first: what the runs vary
    assert differs == {"mask/name", "model/norm", "model/depth", "data/batch_size", "seed"}, differs
    assert [m.name.tag for m in exp.metric_infos][:3] == ["val/l2p_mean_best", "test/l2p_ratio@5", "test/l2p_ratio@15"]
    rows = _rows(logdir)
    assert len(rows) == 8  # one row per run
    for trial, row in rows.items():
        assert {"mask/name", "model/norm", "model/depth"} <= set(row), trial  # every run: a value in every swept column
    depth = {t: r["model/depth"] for t, r in rows.items()}
    assert depth["s2/2"] == 2 and depth["s2/4"] == 4 and depth["s1/zero-layer"] == 6  # not swept there: its value
    assert rows["s1/zero-batch"]["model/norm"] == "batch" and rows["single/a"]["mask/name"] == "lerp"
    assert (logdir / "~columns" / "columns.json").exists()


def _session_groups(logdir: Path):
    """The HParams table's rows as TensorBoard's own plugin backend serves them for ``logdir`` (the runs it finds
    itself): ``{session group name: [session names]}``."""
    from tensorboard import context
    from tensorboard.backend.event_processing import data_provider, plugin_event_multiplexer
    from tensorboard.plugins import base_plugin
    from tensorboard.plugins.hparams import api_pb2, backend_context, list_session_groups

    mux = plugin_event_multiplexer.EventMultiplexer()
    mux.AddRunsFromDirectory(str(logdir))
    mux.Reload()
    tb = base_plugin.TBContext(logdir=str(logdir), multiplexer=mux,
                               data_provider=data_provider.MultiplexerDataProvider(mux, str(logdir)))
    ctx = backend_context.Context(tb)
    request = api_pb2.ListSessionGroupsRequest(
        experiment_name="", allowed_statuses=[api_pb2.STATUS_UNKNOWN, api_pb2.STATUS_SUCCESS, api_pb2.STATUS_RUNNING],
        aggregation_type=api_pb2.AGGREGATION_AVG, start_index=0, slice_size=100)
    groups = list_session_groups.Handler(context.RequestContext(), ctx, "", request).run().session_groups
    return {g.name: [x.name for x in g.sessions] for g in groups}, sorted(mux.Runs())


def test_rerunning_the_same_command_is_a_row_of_its_own(tmp_path, cache_dir):
    """The same single-run command twice into one log folder: two TensorBoard runs (``<label>/<start time>``, the
    second never written into the first), each its own HParams trial, so the table shows two rows instead of
    averaging the re-run with the earlier run; each run directory links to its events."""
    logs = tmp_path / "logs"
    outs = [logs / "train" / "runs" / f"2026-01-01_00-00-0{i}" for i in range(2)]
    for out in outs:
        cfg = compose_cfg("train", TINY + ["run_test=false", "callbacks.skeleton_figure=null"], out, cache_dir)
        cfg.paths.log_dir = str(logs)  # the default layout: the run directory inside the log folder
        train(cfg)
    root = logs / "tensorboard"
    runs = sorted(d for d in root.glob("*/*") if d.is_dir())
    assert [r.parent.name for r in runs] == ["graph_transformer"] * 2 and runs[0] != runs[1]
    assert sorted((o / "tensorboard").resolve() for o in outs) == [r.resolve() for r in runs]
    groups, names = _session_groups(root)
    assert len(groups) == 2 and all(len(v) == 1 for v in groups.values()), groups  # one row per run
    assert names == sorted(str(r.relative_to(root)) for r in runs) + ["~columns"]  # the runs, and the columns' run
    # trial ids: the start time first (a re-run differs within the ~15 characters the table shows), label, date
    assert sorted(groups) == sorted(trial_id(r.parent.name, r.name) for r in runs)
    assert all(re.match(r"^\d\d:\d\d:\d\d graph_transformer \(\d{4}-\d\d-\d\d(_\d+)?\)$", g) for g in groups), groups
    assert trial_id("depth=2 - graph_transformer", "2026-11-25_19-21-49") == "19:21:49 2 (2026-11-25)"
    assert trial_id("zero layer (mask norm) - graph_transformer", "2026-11-25_19-21-49_2") == \
        "19:21:49 zero layer (2026-11-25_2)"
    # a version is never reused, even within the same second
    (root / "graph_transformer" / run_version(root, "graph_transformer", when=0)).mkdir()
    assert run_version(root, "graph_transformer", when=0).endswith("_2")


def test_sweep_runs_are_named_by_their_swept_values(tmp_path, cache_dir, monkeypatch):
    """A sweep's job writes to ``<log dir>/tensorboard/<swept values> - <model>/<start time>``: the run names
    TensorBoard shows (paths under its --logdir) begin with what distinguishes the jobs, not the Hydra folder."""
    from inbetweening.training import builders

    monkeypatch.setattr(builders, "task_overrides", lambda: ["mask=zero", "model.norm=layer", "trainer.max_steps=3"])
    monkeypatch.setattr(builders, "swept_keys", lambda: ["mask", "model.norm"])
    logs = tmp_path / "logs"
    cfg = compose_cfg("train", TINY, logs / "train/multiruns/2026-01-01_00-00-00/0", cache_dir)
    cfg.paths.log_dir = str(logs)
    logger = builders.make_logger(cfg, cfg.logger.tensorboard)
    run = Path(logger.log_dir)
    assert run.relative_to(logs / "tensorboard").parts[0] == "zero layer (mask norm) - graph_transformer"
    assert logger.trial_id == trial_id("zero layer (mask norm) - graph_transformer", run.name)
    assert logger.trial_id.split(" ")[1:3] == ["zero", "layer"]
    assert (Path(cfg.paths.output_dir) / "tensorboard").resolve() == run.resolve()
    # a run given a directory of its own outside the log folder keeps its events in it
    cfg = compose_cfg("train", TINY, tmp_path / "elsewhere", cache_dir)
    assert Path(builders.make_logger(cfg, cfg.logger.tensorboard).log_dir).parent.parent == tmp_path / "elsewhere/tensorboard"


def test_custom_scalars_keep_model_and_baseline_apart():
    """TensorBoard colours Custom Scalars lines by run only: no chart may hold two quantities of one run (the model
    and its interpolation, train/loss and val/loss), or they share a colour."""
    import re

    layout = custom_scalars_layout([5, 15, 30, 45], [5, 15, 30, 45])
    tags = ["train/loss", "val/loss", "train/lr", "train/windows_per_s", "train/grad_norm", "val/l2p_mean",
            "val/pos_rmse_cm",
            *[f"{p}val/{m}@{n}" for p in ("", f"{BASELINE}/") for m in ("l2p", "l2q", "npss") for n in (5, 15, 30, 45)],
            *[f"val/{m}_ratio@{n}" for m in ("l2p", "l2q", "npss") for n in (5, 15, 30, 45)],
            *[f"{p}/l2p_ratio@{n}" for p in ("test", "test_network") for n in (5, 15, 30, 45)]]
    ones = [f"{BASELINE}/val/ratio", f"{BASELINE}/test/ratio"]  # the constant 1 (interpolation) in ratio charts
    for charts in layout.values():
        for title, (_, patterns) in charts.items():
            matched = {t for t in tags for pat in patterns if re.search(pat, t)}
            if title.startswith("L2P@") and "test_network" in title:  # the fill and the network: two, named apart
                assert len(matched) == 2 and {t.split("/")[0] for t in matched} == {"test", "test_network"}, title
            else:
                assert len(matched) == 1, (title, matched)  # one quantity per chart: its lines are the runs
            if "ratio" in " ".join(patterns):
                assert sum(bool(re.search(p, o)) for p in patterns for o in ones) == 1, title  # and the line at 1
    assert list(layout)[0].startswith("1 val: model / interpolation")  # the ratios first: below 1 beats the baseline


# ------------------------------------------------------------------ the TensorBoard server, as the browser reads it
def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _get(port: int, path: str, body: dict | None = None):
    req = urllib.request.Request(f"http://127.0.0.1:{port}{path}", data=None if body is None else json.dumps(body).encode(),
                                 headers={"Content-Type": "application/json"})
    with urllib.request.urlopen(req, timeout=30) as r:
        data = r.read()
    return data if path.startswith("/data/plugin/images/individualImage") else json.loads(data)


@pytest.mark.slow
def test_tensorboard_server_shows_groups_hparams_and_figures(tmp_path, cache_dir):
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "OMP_NUM_THREADS": "1"}
    tiny = [o for o in FIT if not o.startswith("model.depth")]
    sweep = subprocess.run([sys.executable, "train.py", "-m", "model.depth=1,2", *tiny, f"hydra.sweep.dir={tmp_path}/logs/sweep",
                            "hydra.sweep.subdir=${hydra.job.num}", f"paths.log_dir={tmp_path}/logs",
                            f"paths.cache_dir={cache_dir}"], cwd=ROOT, capture_output=True, text=True, env=env, timeout=900)
    assert sweep.returncode == 0, sweep.stderr[-3000:]
    single = subprocess.run([sys.executable, "train.py", *tiny, "run_test=false", f"hydra.run.dir={tmp_path}/logs/fit_only",
                             f"paths.log_dir={tmp_path}/logs",
                             f"paths.cache_dir={cache_dir}"], cwd=ROOT, capture_output=True, text=True, env=env, timeout=900)
    assert single.returncode == 0, single.stderr[-3000:]
    port = _free_port()
    tb = subprocess.Popen([sys.executable, "-m", "tensorboard.main", "--logdir", str(tmp_path / "logs/tensorboard"), "--host",
                           "127.0.0.1", "--port", str(port), "--load_fast=true", "--reload_interval=1"],
                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    try:
        deadline = time.time() + 120
        runs: list = []
        while time.time() < deadline and len(runs) < 4:  # the three runs and ~columns (the HParams columns)
            try:
                runs = _get(port, "/data/runs")
            except OSError:
                pass
            time.sleep(1)
        assert "~columns" in runs
        names = sorted(r.split("/")[0] for r in runs if r != "~columns")  # <what distinguishes the run>/<start time>
        assert names[:2] == ["1 (depth) - graph_transformer", "2 (depth) - graph_transformer"], runs
        assert names[2].startswith("batch_size=8 ") and names[2].endswith(" - graph_transformer")  # the overrides
        tags = _get(port, "/data/plugin/scalars/tags")
        groups = {t.split("/")[0] for run_tags in tags.values() for t in run_tags}
        assert groups == {"train", "val", "test", "test_network", "~interpolation"}, groups
        exp = _get(port, "/data/plugin/hparams/experiment", {"experimentName": "", "includeMetrics": True,
                                                              "hparamsLimit": 1000})
        shown = sorted(h["name"] for h in exp["hparamInfos"] if h.get("differs"))
        # one experiment for the folder (~columns): the swept key differs; the single run's keys and calibrate /
        # the representation are columns too, constant here, so not among those shown first
        assert shown == ["model/depth"], shown
        assert {"calibrate", "representation", "data/batch_size"} <= {h["name"] for h in exp["hparamInfos"]}
        first = sorted(exp["hparamInfos"], key=lambda h: not h.get("differs"))[:5]  # the dashboard's default columns
        assert "model/depth" in [h["name"] for h in first]
        metrics = [m["name"]["tag"] for m in exp["metricInfos"]]
        assert metrics[0] == "val/l2p_mean_best" and "test/l2p@15" in metrics
        groups_req = {"experimentName": "", "allowedStatuses": ["STATUS_UNKNOWN", "STATUS_SUCCESS", "STATUS_FAILURE",
                                                                 "STATUS_RUNNING"],
                      "colParams": [{"hparam": "model/depth"}] + [{"metric": {"group": "", "tag": m}} for m in metrics[:5]],
                      "aggregationType": "AGGREGATION_AVG", "startIndex": 0, "sliceSize": 10}
        sessions = _get(port, "/data/plugin/hparams/session_groups", groups_req)["sessionGroups"]
        assert len(sessions) == 3
        by_depth: dict = {}
        for g in sessions:
            values = {m["name"]["tag"]: m["value"] for m in g.get("metricValues", [])}
            assert "val/l2p_mean_best" in values  # also the run that never reached a test
            by_depth.setdefault(g["hparams"].get("model/depth"), []).append(values)
        assert {1.0, 2.0} <= set(by_depth)
        assert all("test/l2p_ratio@15" in v for d in (1.0, 2.0) for v in by_depth[d])
        images = _get(port, "/data/plugin/images/tags")
        run = next(r for r in images if r.startswith("2 (depth) - graph_transformer/"))
        assert {"val/skeleton", "val/per_joint"} <= set(images[run])
        imgs = _get(port, f"/data/plugin/images/images?run={urllib.request.quote(run)}&tag=val/skeleton")
        png = _get(port, "/data/plugin/images/individualImage?" + imgs[-1]["query"])
        assert png[:4] == b"\x89PNG"
        layout = _get(port, "/data/plugin/custom_scalars/layout")
        titles = [c["title"] for c in layout["category"]]
        assert titles[0].startswith("1 val: model / interpolation") and titles[1].startswith("2 test")
        assert len(titles) == 5
        chart = layout["category"][0]["chart"][0]["multiline"]["tag"]
        assert chart == [r"^val/l2p_ratio@5$", r"^\~interpolation/val/ratio$"]
    finally:
        tb.terminate()
        tb.wait(timeout=30)
