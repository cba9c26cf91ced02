"""The do-no-harm blend (predictor/calibration.py, calibrate.py, train's calibration): fitted per gap length on
held-out windows, never worse there than the network or the interpolation, carried by the checkpoint, and what
the blended predictor then produces."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from conftest import TINY, compose_cfg
from inbetweening.data import windows as W
from inbetweening.data.datasets import load_dataset
from inbetweening.predictor.calibration import calibrated_checkpoint, fit_blend, gap_range
from inbetweening.predictor.checkpoint import load_predictor, read_checkpoint
from inbetweening.training.calibrate import calibrate

ROOT = Path(__file__).resolve().parents[1]
DATA = [o for o in TINY if o.startswith("data.")]


@pytest.fixture(scope="module")
def held_out(cache_dir):
    """Benchmark-form windows of the synthetic data's test clips (as the validation windows look)."""
    data = load_dataset("synthetic", cache_dir=cache_dir, synthetic={"num_clips": 10, "min_frames": 120,
                                                                      "max_frames": 160})
    X, Q = W.prepare_windows(data.test, data.skeleton, W.TEST_WINDOW, W.TEST_OFFSET, data.forward_axis)
    return X[:24, :, 0], Q[:24]


def _errors(pred, root, q, gap):
    """Mean joint position error of the predictor's fills (through ``predict_windows``) and of the interpolation."""
    t = pred.n_past + gap + 1
    r, lq = root[:, :t], q[:, :t]
    out = pred.predict_windows(r, lq, pred.transition_known(len(r), t, gap))
    truth = pred.skeleton.pose(r, lq)[1]
    err = []
    for rr, qq in ((out.root, out.local_q), (out.interp_root, out.interp_q)):
        p = pred.skeleton.pose(rr.numpy(), qq.numpy())[1]
        err.append(np.linalg.norm(p - truth, axis=-1)[:, pred.n_past : pred.n_past + gap].mean())
    return err


def test_fit_blend_is_never_worse_than_network_or_interpolation_and_is_what_the_predictor_does(
        tiny_checkpoint, held_out):
    pred = load_predictor(tiny_checkpoint)
    torch.manual_seed(0)
    with torch.no_grad():  # a network with a sizeable, mostly wrong correction
        for p in pred.net.parameters():
            p.add_(0.05 * torch.randn_like(p))
    root, q = held_out
    fit = fit_blend(pred, root, q, max_gap=6)
    assert len(fit.weights) == 6 == len(fit.rows) and fit.windows == len(root)
    assert all(0.0 <= w <= 1.0 for w in fit.weights)
    for r in fit.rows:
        assert r["blended"] <= min(r["network"], r["interpolation"]) + 1e-9
    assert any(r["blended"] < r["network"] - 1e-6 for r in fit.rows)  # the blend changed something
    blended = load_predictor(tiny_checkpoint)
    blended.load_state_dict(pred.state_dict())
    blended.blend = tuple(fit.weights)
    for r in fit.rows:  # the fit's figures are what the blended predictor produces on those windows (up to the
        model, interp = _errors(blended, root, q, r["gap"])  # float32 rounding of the features)
        assert model == pytest.approx(r["blended"], rel=1e-4) and interp == pytest.approx(r["interpolation"], rel=1e-4)
    assert "gap  weight" in fit.table() and len(fit.table().splitlines()) == 2 + 6
    assert gap_range(pred, 65) == min(pred.train_window - pred.n_past - 1, 54)
    with pytest.raises(ValueError, match="blend: windows of 11 frames leave no gap"):
        fit_blend(pred, root[:, :11], q[:, :11])


def test_calibrated_checkpoint_carries_the_blend_and_loads(tiny_checkpoint, tmp_path):
    ckpt = read_checkpoint(tiny_checkpoint)
    out = calibrated_checkpoint(ckpt, [0.0, 0.5, 1.0])
    assert ckpt["hyper_parameters"].get("blend") is None and out["state_dict"] is ckpt["state_dict"]
    torch.save(out, tmp_path / "c.ckpt")
    assert load_predictor(tmp_path / "c.ckpt").blend == (0.0, 0.5, 1.0)
    assert load_predictor(tiny_checkpoint).blend is None


def test_calibrate_job_writes_a_new_checkpoint_and_eval_scores_it(tiny_checkpoint, tmp_path, cache_dir):
    cfg = compose_cfg("calibrate", [*DATA, f"ckpt_path='{tiny_checkpoint}'", f"out={tmp_path / 'cal.ckpt'}",
                                    "calibrate_windows=2"], tmp_path / "run", cache_dir)
    got = calibrate(cfg)
    pred = load_predictor(tmp_path / "cal.ckpt")
    assert pred.blend is not None and list(got.values()) == list(pred.blend)
    assert len(pred.blend) == cfg.data.transition_max
    assert read_checkpoint(tmp_path / "cal.ckpt")["blend_fit"]["windows"] == 2


@pytest.mark.slow
def test_calibrate_cli_refuses_to_overwrite_its_input_and_needs_a_checkpoint(tiny_checkpoint, tmp_path):
    before = Path(tiny_checkpoint).read_bytes()
    for extra, msg in (([f"ckpt_path='{tiny_checkpoint}'", f"out='{tiny_checkpoint}'"], "is the input checkpoint"),
                       ([], "ckpt_path: required")):
        r = subprocess.run([sys.executable, str(ROOT / "calibrate.py"), *extra, f"hydra.run.dir={tmp_path}"],
                           capture_output=True, text=True, cwd=tmp_path)
        assert r.returncode == 2 and msg in r.stderr and "Traceback" not in r.stderr, r.stderr
        assert len(r.stderr.strip().splitlines()) == 1
    assert Path(tiny_checkpoint).read_bytes() == before


def test_train_calibrates_the_best_checkpoint_tests_it_and_eval_reproduces_it(tmp_path, cache_dir):
    from inbetweening.training.evaluate import evaluate
    from inbetweening.training.train import train

    over = [o for o in TINY if "max_steps" not in o] + [
        "callbacks=default", "callbacks.progress_bar=null", "callbacks.skeleton_figure=null", "logger=none",
        "+trainer.enable_progress_bar=false", "optim.optimizer.lr=1e-2", "optim.scheduler.warmup_steps=0",
        "calibrate_windows=3"]
    cfg = compose_cfg("train", over, tmp_path / "run", cache_dir)
    want = train(cfg)
    ckpts = tmp_path / "run" / "checkpoints"
    best = sorted(ckpts.glob("epoch_*.ckpt"))
    cal = read_checkpoint(ckpts / "calibrated.ckpt")
    assert cal["blend_fit"]["source"] == str(best[0]) and cal["blend_fit"]["windows"] == 3
    assert len(cal["hyper_parameters"]["blend"]) == cfg.data.transition_max  # gaps 1..transition_max
    assert read_checkpoint(best[0])["hyper_parameters"].get("blend") is None  # the best checkpoint is left as it was
    got = evaluate(compose_cfg("eval", [*DATA, f"ckpt_path={ckpts / 'calibrated.ckpt'}"], tmp_path / "eval",
                               cache_dir))
    assert got.keys() == want.keys()
    for k in want:
        assert got[k] == pytest.approx(want[k], rel=1e-6), k
    # benchmark.json holds the network alone beside the blended fill: eval.py of the best checkpoint (no blend)
    import json

    res = json.loads((tmp_path / "run" / "benchmark.json").read_text())
    net = evaluate(compose_cfg("eval", [*DATA, f"ckpt_path={best[0]}"], tmp_path / "eval_net", cache_dir))
    assert res["network"].keys() == net.keys() and res["metrics"] == pytest.approx(want, rel=1e-6)
    for k in net:
        assert res["network"][k] == pytest.approx(net[k], rel=1e-6), k
    assert res["network"] != res["metrics"]
