"""eval.py end to end: a trained checkpoint's benchmark equals the training run's test benchmark, scoring uses
the dataset's statistics (not the checkpoint's), and a checkpoint of another skeleton is one clear error."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from conftest import TINY, compose_cfg
from inbetweening.data import windows as W
from inbetweening.data.bvh import read_bvh
from inbetweening.data.bvh_writer import write_bvh
from inbetweening.data.datasets import load_dataset
from inbetweening.data.synthetic import generate_dataset
from inbetweening.evaluation import benchmark as B
from inbetweening.predictor.checkpoint import CheckpointError
from inbetweening.predictor.predictor import Predictor
from inbetweening.training.evaluate import evaluate
from inbetweening.training.module import load_module
from inbetweening.training.train import train

ROOT = Path(__file__).resolve().parents[1]
DATA = [o for o in TINY if o.startswith("data.")]
SYNTH = {"num_clips": 10, "min_frames": 120, "max_frames": 160}
LENGTHS = (5, 15, 30, 45)


@pytest.fixture(scope="module")
def trained(tmp_path_factory, cache_dir):
    """One epoch of a tiny graph_transformer: the checkpoint train() tested and the metrics it reported."""
    out = tmp_path_factory.mktemp("eval_trained")
    over = [o for o in TINY if "max_steps" not in o] + [
        "callbacks=default", "callbacks.progress_bar=null", "callbacks.skeleton_figure=null", "logger=none",
        "+trainer.enable_progress_bar=false", "optim.optimizer.lr=1e-2", "optim.scheduler.warmup_steps=0",
        "calibrate=false"]  # the network as trained (one epoch: its blend would be the interpolation at most gaps;
    # test_calibration.py checks that eval.py reproduces a calibrated run too)
    metrics = train(compose_cfg("train", over, out / "run", cache_dir))
    ckpts = sorted((out / "run" / "checkpoints").glob("epoch_*.ckpt"))
    assert len(ckpts) == 1  # one epoch, one validation: this is the checkpoint train() tested
    return ckpts[0], metrics, out


def _eval_cfg(tmp_path, cache_dir, *extra):
    return compose_cfg("eval", [*DATA, *extra], tmp_path, cache_dir)


def test_eval_reproduces_the_training_runs_test_metrics(trained, tmp_path, cache_dir):
    ckpt, want, _ = trained
    got = evaluate(_eval_cfg(tmp_path / "eval", cache_dir, f"ckpt_path={ckpt}"))
    assert got.keys() == want.keys() and len(got) == 3 * len(LENGTHS)
    for k in want:
        assert got[k] == pytest.approx(want[k], rel=1e-6), k
    res = json.loads((tmp_path / "eval" / "benchmark.json").read_text())
    assert res["model"] == "graph_transformer" and res["dataset"] == "synthetic"
    assert res["metrics"] == pytest.approx(want, rel=1e-6)
    # not any model's score: the interpolation baseline scores differently on these windows
    base = evaluate(_eval_cfg(tmp_path / "base", cache_dir, "model=interpolation"))
    assert base["l2p@15"] != pytest.approx(want["l2p@15"], rel=1e-3)


def test_eval_scores_with_the_datasets_statistics(trained, tmp_path, cache_dir):
    """A checkpoint whose pos_mean/pos_std differ from the dataset's: the network still sees its own normalisation,
    but L2P is computed with the dataset's statistics (the benchmark protocol)."""
    ckpt, _, _ = trained
    c = torch.load(ckpt, map_location="cpu", weights_only=True)
    hp = c["hyper_parameters"]
    hp["pos_mean"] = [v + 3.0 for v in hp["pos_mean"]]
    hp["pos_std"] = [v * 1.5 for v in hp["pos_std"]]
    edited = tmp_path / "edited.ckpt"
    torch.save(c, edited)

    got = evaluate(_eval_cfg(tmp_path / "eval", cache_dir, f"ckpt_path={edited}"))

    data = load_dataset("synthetic", cache_dir=cache_dir, synthetic=SYNTH)
    n = 8  # data.max_eval_windows
    module = load_module(edited)
    assert not np.allclose(module.std, data.pos_std)

    def predictor(root, q, k):  # the network with the checkpoint's own normalisation, as eval.py runs it
        return Predictor(module.net, module.skeleton, module.mean, module.std, mask=module.mask_name,
                         centre=module.centre, n_past=module.n_past,
                         forward_axis=module.forward_axis).predict_transitions(root, q, k)

    X, Q = data.test_X[:n], data.test_Q[:n]
    with_data = B.evaluate_transitions(W.BenchmarkSet(X, Q, data.skeleton, data.pos_mean, data.pos_std), predictor,
                                       LENGTHS)
    with_ckpt = B.evaluate_transitions(W.BenchmarkSet(X, Q, data.skeleton, module.mean, module.std), predictor,
                                       LENGTHS)
    for k in with_data:
        assert got[k] == pytest.approx(with_data[k], rel=1e-4, abs=1e-6), k
    for n_ in LENGTHS:  # the two statistics give clearly different L2P (and the same L2Q / NPSS)
        assert with_ckpt[f"l2p@{n_}"] != pytest.approx(with_data[f"l2p@{n_}"], rel=1e-2)
        assert with_ckpt[f"l2q@{n_}"] == pytest.approx(with_data[f"l2q@{n_}"], rel=1e-9)


def _drop_last_joint(src: Path, dst: Path) -> Path:
    """A LAFAN-format dataset whose skeleton has one joint fewer (the last one, a leaf: RightHand)."""
    dst.mkdir(parents=True, exist_ok=True)
    for f in sorted(src.glob("*.bvh")):
        bvh = read_bvh(f)
        j = bvh.num_joints - 1
        assert j not in bvh.parents.tolist()  # a leaf
        ends = {k: v for k, v in bvh.end_sites.items() if k != j}
        ends[int(bvh.parents[j])] = bvh.offsets[j]
        bvh = type(bvh)(names=bvh.names[:j], parents=bvh.parents[:j], offsets=bvh.offsets[:j],
                        channels=bvh.channels[:j], end_sites=ends, frame_time=bvh.frame_time,
                        motion=bvh.motion[:, : -len(bvh.channels[j])], source=bvh.source)
        write_bvh(bvh, dst / f.name)
    return dst


@pytest.fixture(scope="module")
def other_skeleton(tmp_path_factory, cache_dir):
    src = generate_dataset(cache_dir / "synthetic", **SYNTH)
    return _drop_last_joint(src, tmp_path_factory.mktemp("joints21"))


def test_eval_refuses_a_checkpoint_of_another_skeleton(trained, other_skeleton, tmp_path, cache_dir):
    ckpt, _, _ = trained
    cfg = compose_cfg("eval", ["data=lafan1", f"data.path={other_skeleton}", "data.download=false",
                               f"ckpt_path={ckpt}"], tmp_path, cache_dir)
    with pytest.raises(CheckpointError, match=r"22-joint skeleton .* has 21 joints"):
        evaluate(cfg)
    assert not (tmp_path / "benchmark.json").exists()


@pytest.mark.slow
def test_eval_cli_skeleton_mismatch_is_one_error_line_exit_2(trained, other_skeleton, tmp_path, cache_dir):
    ckpt, _, _ = trained
    env = dict(os.environ, OMP_NUM_THREADS="1", INBETWEENING_CACHE=str(cache_dir), PYTHONUNBUFFERED="1")
    r = subprocess.run([sys.executable, "eval.py", "data=lafan1", f"data.path={other_skeleton}", "data.download=false",
                        f"ckpt_path={ckpt}", f"hydra.run.dir={tmp_path}/run", f"paths.cache_dir={cache_dir}"],
                       cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 2, r.stderr[-3000:]
    errors = [line for line in r.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and r.stderr.strip().splitlines()[-1] == errors[0]
    assert "22-joint skeleton" in errors[0] and "21 joints" in errors[0] and str(ckpt) in errors[0]
    assert "Traceback" not in r.stderr
    assert not (tmp_path / "run" / "benchmark.json").exists()


def test_an_ensemble_is_scored_through_the_runtime_as_one_model_is(trained, tiny_checkpoint, tmp_path, cache_dir):
    """``ckpt_path=[a,b]``: the LAFAN protocol scores the ensemble's windows through the fill runtime, the way a single
    model's are (that route gives one model its Lightning test metrics), and protocol=keyframes fills with it."""
    from inbetweening.training.evaluate import ensemble_transitions

    ckpt, want, _ = trained
    cfg = _eval_cfg(tmp_path / "one", cache_dir, f"ckpt_path={ckpt}")
    from inbetweening.training.builders import make_datamodule
    dm = make_datamodule(cfg)
    dm.prepare_data()
    dm.setup("test")
    alone, _ = ensemble_transitions([str(ckpt)])
    got = B.evaluate_transitions(dm.test_benchmark_set(), alone, LENGTHS)
    for k in want:
        assert got[k] == pytest.approx(want[k], rel=1e-4, abs=1e-6), k
    pair = evaluate(_eval_cfg(tmp_path / "pair", cache_dir, f"ckpt_path=['{ckpt}','{tiny_checkpoint}']"))
    res = json.loads((tmp_path / "pair" / "benchmark.json").read_text())
    assert res["model"] == "ensemble of 2" and res["metrics"] == pytest.approx(pair)
    assert pair["l2p@15"] != pytest.approx(want["l2p@15"], rel=1e-3)  # not the first model alone
    kf = evaluate(_eval_cfg(tmp_path / "kf", cache_dir, f"ckpt_path=['{ckpt}','{tiny_checkpoint}']", "protocol=keyframes",
                            "keyframe_intervals=[15]", "keyframe_clips=3"))
    assert np.isfinite(kf["ratio@15"])
    assert "ensemble of 2" in json.loads((tmp_path / "kf" / "benchmark.json").read_text())["model"]
