"""What a run writes to TensorBoard (issue 14): groups, interpolation references and ratios, figures, HParams.

The fast tests read the event files with TensorBoard's own reader; the slow one runs a real sweep through the CLI,
starts TensorBoard on 127.0.0.1 and reads its HTTP API like the browser does."""
from __future__ import annotations

import json
import os
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
from inbetweening.training.figures import frames_to_draw, per_joint_figure, transition_figure
from inbetweening.training.tb_logging import curated_hparams, hparams_metrics, resumed_version, run_label, tb_scalars
from inbetweening.training.train import train

ROOT = Path(__file__).resolve().parents[1]
FIT = [o for o in TINY if "max_steps" not in o and "max_epochs" not in o] + [
    "trainer.max_epochs=2", "callbacks.progress_bar=null", "callbacks.skeleton_figure.every_n_epochs=5"]


def _events(run_dir: Path):
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    dirs = sorted({p.parent for p in run_dir.rglob("events.out.tfevents.*")})
    assert len(dirs) == 1, dirs
    ea = EventAccumulator(str(dirs[0]), size_guidance={"scalars": 0, "images": 0, "tensors": 0})
    ea.Reload()
    return dirs[0], ea


# ------------------------------------------------------------------ pure pieces
def test_scalars_give_interpolation_reference_and_ratio():
    logs = tb_scalars("val", {"l2p@5": 1.0, "l2p@15": 3.0, "l2q@15": 0.5}, {"l2p@5": 2.0, "l2p@15": 2.0, "l2q@15": 0.0,
                                                                            "l2p@30": 9.0}, 12.5)
    assert logs["val/l2p_ratio@5"] == 0.5 and logs["val/l2p_ratio@15"] == 1.5
    assert logs["val/interp_l2p@15"] == 2.0 and logs["val/l2p_mean"] == 2.0 and logs["val/pos_rmse_cm"] == 12.5
    assert "val/l2q_ratio@15" not in logs  # interpolation scored 0: no ratio rather than inf
    assert "val/interp_l2p@30" not in logs  # a length the model was not scored at


def test_curated_hparams_put_swept_keys_first_with_the_budget(tmp_path, cache_dir):
    cfg = compose_cfg("train", ["model.depth=2", "mask=zero", "optim.optimizer.lr=0.01"], tmp_path, cache_dir)
    hp, shown = curated_hparams(cfg, ["model.depth=2", "mask=zero", "optim.optimizer.lr=0.01", "seed=3",
                                      "hydra.run.dir=/x", "ckpt_path=a.ckpt"])
    assert list(hp)[:4] == ["model/depth", "mask/name", "optim/optimizer/lr", "seed"]
    assert hp["model/depth"] == 2 and hp["mask/name"] == "zero" and hp["optim/optimizer/lr"] == 0.01
    assert shown[:4] == ["model/depth", "mask/name", "optim/optimizer/lr", "seed"] and len(shown) == 5
    assert {"trainer/max_epochs", "trainer/max_steps", "trainer/max_time", "data/name", "model/name"} <= set(hp)
    assert hp["trainer/max_time"] == "none" and hp["optim/optimizer"] == "AdamW"
    assert not any(k.startswith(("hydra", "ckpt_path", "paths")) for k in hp)
    assert all(isinstance(v, (bool, int, float, str)) for v in hp.values())
    assert run_label(cfg, ["model.depth=2", "hydra.run.dir=/x", "data.path=/a/b"]) == "graph_transformer model.depth=2"
    # in a sweep: the swept keys come first, are the ones shown, and name the run
    hp, shown = curated_hparams(cfg, ["model.depth=2", "mask=zero", "seed=3"], swept=["seed"])
    assert list(hp)[0] == "seed" and shown == ["seed", "model/name", "trainer/max_epochs", "data/name", "mask/name"]
    assert run_label(cfg, ["model.depth=2", "seed=3"], swept=["seed"]) == "seed=3 - graph_transformer"
    # what distinguishes the run leads (the example: a mask x norm sweep), the model last unless swept
    assert run_label(cfg, ["data=synthetic", "mask=zero", "model.norm=layer"], swept=["mask", "model.norm"]) == \
        "mask=zero model.norm=layer - graph_transformer"
    assert run_label(cfg, ["model=unet1d", "seed=3"], swept=["model", "seed"]) == "model=unet1d seed=3"
    assert hparams_metrics([5, 45], [5])[:3] == ["val/l2p_mean_best", "test/l2p_ratio@5", "test/l2p_ratio@45"]


def test_figures_are_thumbnail_sized_and_draw_what_they_say():
    names = ["Hips", "Spine", "Head"]
    model = {5: {"pos": np.array([1.0, 2.0, 3.0]), "rot": np.array([4.0, 5.0, 6.0])}}
    fig = per_joint_figure(names, model, {5: {"pos": np.ones(3), "rot": np.ones(3)}})
    top, bottom = fig.axes[:2]
    assert [t.get_text() for t in bottom.get_xticklabels()] == names  # skeleton order, not alphabetical
    assert "cm" in top.get_ylabel() and "deg" in bottom.get_ylabel()
    assert len(top.get_lines()) == 3  # model, interpolation and the legend's dashed sample
    t, j = 26, 3
    gt = np.zeros((t, j, 3))
    gt[:, 1, 1], gt[:, 2, 1] = 50.0, 100.0
    pred = gt + np.linspace(0, 1, t)[:, None, None]
    frames = frames_to_draw(10, 15, 6)
    assert frames[0] == 9 and frames[-1] == 25 and len(frames) == 6
    fig = transition_figure(gt, pred, gt, [-1, 0, 1], 10, 15, frames, title="x")
    w, h = fig.get_size_inches() * fig.dpi
    assert w <= 1000 and h <= 450
    err = fig.axes[len(frames)]
    model_line, interp_line = err.get_lines()[:2]
    assert np.allclose(model_line.get_ydata(), np.linspace(0, 1, t)[10:25] * np.sqrt(3))
    assert np.allclose(interp_line.get_ydata(), 0.0)
    assert [a.get_title() for a in fig.axes[:len(frames)]][0] == "frame 9 (key)"


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
    assert run.name == "graph_transformer"  # named after the configuration, not "tensorboard"
    scalars = set(ea.Tags()["scalars"])
    assert {t.split("/")[0] for t in scalars} == {"train", "val", "test"}, scalars  # no "epoch", "hp", per-joint
    assert {"train/lr", "train/windows_per_s", "train/epoch_time_s", "train/grad_norm", "train/epoch",
            "train/sampled_transition_frames", "val/l2p@45", "val/l2p_mean_best", "test/l2p@45"} <= scalars
    for n in (5, 15, 30, 45):
        for stage in ("val", "test"):
            assert {f"{stage}/l2p_ratio@{n}", f"{stage}/interp_l2p@{n}", f"{stage}/l2q_ratio@{n}"} <= scalars
        assert ea.Scalars(f"test/l2p@{n}")[-1].value == pytest.approx(metrics[f"l2p@{n}"], rel=1e-6)
        model, interp = ea.Scalars(f"val/l2p@{n}"), ea.Scalars(f"val/interp_l2p@{n}")
        ratio = ea.Scalars(f"val/l2p_ratio@{n}")
        assert len(model) == len(interp) == 2 and interp[0].value == interp[1].value  # cached, deterministic
        assert ratio[-1].value == pytest.approx(model[-1].value / interp[-1].value, rel=1e-5)
    best = [e.value for e in ea.Scalars("val/l2p_mean_best")]
    assert best == [min(e.value for e in ea.Scalars("val/l2p_mean")[: i + 1]) for i in range(2)]
    assert all(e.value > 0 for e in ea.Scalars("train/grad_norm"))


def test_figures_are_logged_at_the_validation_steps(fitted):
    out, _ = fitted
    _, ea = _events(out / "tensorboard")
    val_steps = [e.step for e in ea.Scalars("val/l2p@15")]
    assert [e.step for e in ea.Images("val/per_joint")] == val_steps
    skel = [e.step for e in ea.Images("val/skeleton")]
    assert skel == val_steps  # epoch 0 (every 5) and the last (also the best) epoch, nothing off by one
    img = ea.Images("val/skeleton")[-1]
    assert img.width <= 1000 and img.height <= 450 and img.encoded_image_string[:4] == b"\x89PNG"


def test_hparams_session_starts_with_the_fit(fitted):
    """The session is written when fitting starts (running runs appear) and ended after the test; a single run
    writes no HParams experiment of its own (a sweep's job does: see the test below)."""
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
    """Resuming with other compute settings (python train.py ... threads=2 ckpt_path=...) continues the one run of
    the run directory; a fresh fit, or a directory with several runs, is named after its configuration."""
    tb = tmp_path / "tensorboard"
    assert resumed_version(tb, True) is None  # nothing logged yet
    (tb / "graph_transformer threads=1").mkdir(parents=True)
    assert resumed_version(tb, True) == "graph_transformer threads=1"
    assert resumed_version(tb, False) is None
    (tb / "graph_transformer").mkdir()
    assert resumed_version(tb, True) is None


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
    """One run's HParams session written as a fit writes it (:func:`make_trainer`'s wiring: curated hparams, an
    experiment only in a sweep's job) and a few of its scalars; returns the run's folder."""
    import lightning as L

    from inbetweening.training.tb_logging import HParamsSession, RunLogger

    logger = RunLogger(save_dir=str(logdir), name="", version=version)
    hp, shown = curated_hparams(cfg, overrides, swept)
    session = HParamsSession(hp, shown, [5, 15], [5, 15], experiment=bool(swept))
    trainer = L.Trainer(logger=logger, enable_checkpointing=False, enable_progress_bar=False,
                        enable_model_summary=False)
    session.start(trainer)
    logger.log_metrics({"val/l2p_mean_best": 0.5, "test/l2p_ratio@15": 0.9, "train/loss": 1.0}, step=1)
    logger.end_session("success")
    logger.finalize("success")
    return logdir / version


@pytest.mark.parametrize("single_first", [True, False])
def test_a_sweeps_keys_stay_the_default_columns_next_to_a_single_run(tmp_path, cache_dir, single_first):
    """One --logdir holding a single run and a 2-job sweep over model.norm: whichever run TensorBoard lists first,
    the HParams experiment it serves is the sweep's, with model/norm among the columns shown by default and the
    curated metric columns first (before the fix the single run's experiment could win: its overrides shown, the
    swept model/norm not)."""
    logdir = tmp_path / "logs"
    single_over = ["data.batch_size=8", "trainer.max_steps=3", "seed=1"]
    single = _session(logdir, compose_cfg("train", single_over, tmp_path / "s", cache_dir), single_over, [],
                      "graph_transformer data.batch_size=8 seed=1 trainer.max_steps=3")
    sweep = []
    for norm in ("layer", "batch"):
        over = [f"model.norm={norm}", "trainer.max_steps=3"]
        cfg = compose_cfg("train", over, tmp_path / norm, cache_dir)
        sweep.append(_session(logdir, cfg, over, ["model.norm"], f"multiruns/{norm}/model.norm={norm}"))
    exp = _served_experiment(logdir, [single, *sweep] if single_first else [*sweep, single])
    assert "model/norm" in _default_columns(exp), _default_columns(exp)
    assert sum(h.differs for h in exp.hparam_infos) == 5  # the swept key, then 4 essentials
    assert "trainer/max_epochs" in {h.name for h in exp.hparam_infos}
    assert [m.name.tag for m in exp.metric_infos][:3] == ["val/l2p_mean_best", "test/l2p_ratio@5",
                                                          "test/l2p_ratio@15"]
    # the single run alone: no experiment of its own; the plugin builds one from its session
    alone = _served_experiment(logdir, [single])
    assert {"data/batch_size", "seed", "model/norm"} <= {h.name for h in alone.hparam_infos}


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
                            "hydra.sweep.subdir=${hydra.job.num}",
                            f"paths.cache_dir={cache_dir}"], cwd=ROOT, capture_output=True, text=True, env=env, timeout=900)
    assert sweep.returncode == 0, sweep.stderr[-3000:]
    single = subprocess.run([sys.executable, "train.py", *tiny, "run_test=false", f"hydra.run.dir={tmp_path}/logs/fit_only",
                             f"paths.cache_dir={cache_dir}"], cwd=ROOT, capture_output=True, text=True, env=env, timeout=900)
    assert single.returncode == 0, single.stderr[-3000:]
    port = _free_port()
    tb = subprocess.Popen([sys.executable, "-m", "tensorboard.main", "--logdir", str(tmp_path / "logs"), "--host",
                           "127.0.0.1", "--port", str(port), "--load_fast=true", "--reload_interval=1"],
                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    try:
        deadline = time.time() + 120
        runs: list = []
        while time.time() < deadline and len(runs) < 3:
            try:
                runs = _get(port, "/data/runs")
            except OSError:
                pass
            time.sleep(1)
        names = sorted(r.rsplit("/", 1)[-1] for r in runs)
        assert names[1:] == ["model.depth=1 - graph_transformer", "model.depth=2 - graph_transformer"], runs
        assert names[0].startswith("graph_transformer ") and "data.batch_size=8" in names[0]  # the overrides
        tags = _get(port, "/data/plugin/scalars/tags")
        groups = {t.split("/")[0] for run_tags in tags.values() for t in run_tags}
        assert groups == {"train", "val", "test"}, groups
        exp = _get(port, "/data/plugin/hparams/experiment", {"experimentName": "", "includeMetrics": True,
                                                              "hparamsLimit": 1000})
        shown = sorted(h["name"] for h in exp["hparamInfos"] if h.get("differs"))
        # only the sweep's jobs write an experiment, so TensorBoard serves the sweep's (the swept key, then 4
        # essentials) whichever run it reads first
        assert "model/depth" in shown and len(shown) == 5, shown
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
        run = next(r for r in images if r.endswith("model.depth=2 - graph_transformer"))
        assert {"val/skeleton", "val/per_joint"} <= set(images[run])
        imgs = _get(port, f"/data/plugin/images/images?run={urllib.request.quote(run)}&tag=val/skeleton")
        png = _get(port, "/data/plugin/images/individualImage?" + imgs[-1]["query"])
        assert png[:4] == b"\x89PNG"
        layout = _get(port, "/data/plugin/custom_scalars/layout")
        titles = [c["title"] for c in layout["category"]]
        assert titles == ["1 train", "2 val", "3 test"]
        chart = layout["category"][1]["chart"][0]["multiline"]["tag"]
        assert chart == [r"^val/l2p@\d+$", r"^val/interp_l2p@\d+$"]
    finally:
        tb.terminate()
        tb.wait(timeout=30)
