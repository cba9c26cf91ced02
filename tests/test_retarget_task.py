"""``task=retarget`` end to end (src/inbetweening/retarget/task.py): ``train.py`` and ``eval.py`` on a folder
of generated source clips (the shipped model's skeleton, Bandai-Namco-style names; no dataset needed) onto a generated
CMU-like rig, with the default callbacks and TensorBoard, and with ``callbacks=none logger=none``."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from inbetweening.data.bvh import BVH
from inbetweening.data.bvh_writer import write_bvh
from retarget_fixtures import ROOT, rig_of, source_clips, source_skeleton


@pytest.mark.parametrize("config, extra", [("train", ["callbacks=none", "logger=none"]), ("train", []), ("eval", [])])
def test_the_task_composes(config, extra, tmp_path):
    from conftest import compose_cfg

    cfg = compose_cfg(config, ["task=retarget", "data=bandai_namco", *extra], tmp_path, tmp_path)
    assert cfg.task == "retarget" and cfg.model.name == "retarget_lstm" and cfg.retarget.train_fraction == 0.6
    assert set(cfg.retarget.loss) == {"mse", "smooth", "bone"}


def test_an_in_betweening_model_or_no_rig_is_one_line(tmp_path):
    from conftest import compose_cfg
    from inbetweening.retarget.task import train_retarget
    from inbetweening.training.config import ConfigError

    cfg = compose_cfg("train", ["task=retarget", "model=resnet_lstm"], tmp_path, tmp_path)
    with pytest.raises(ConfigError, match="model.name: 'resnet_lstm' is an in-betweening network"):
        train_retarget(cfg)
    cfg = compose_cfg("train", ["task=retarget"], tmp_path, tmp_path)
    with pytest.raises(ConfigError, match="target_rig: required with task=retarget"):
        train_retarget(cfg)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    d = tmp_path_factory.mktemp("retarget_task")
    sk = source_skeleton()
    (d / "clips").mkdir()
    chans = [("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")] * sk.num_joints
    empty = BVH(list(sk.names), list(sk.parents), sk.offsets, chans, {}, 1 / 30, np.zeros((1, 6 * sk.num_joints)))
    for c in source_clips(sk, 12, frames=90):
        write_bvh(empty.with_motion(c.local_q, sk.local_positions(c.root_pos)), d / "clips" / f"{c.name}.bvh")
    write_bvh(rig_of(sk, "cmu"), d / "cmu.bvh")
    write_bvh(rig_of(sk, "extras"), d / "other.bvh")
    return d


def _run(script, *args, cwd=ROOT):
    return subprocess.run([sys.executable, script, *args], cwd=cwd, capture_output=True, text=True, timeout=600)


@pytest.mark.slow
def test_train_then_eval(folder, tmp_path):
    common = ["task=retarget", "data=bvh", f"data.path={folder / 'clips'}", f"paths.log_dir={tmp_path / 'logs'}",
              f"paths.cache_dir={tmp_path / 'cache'}", "threads=1", "retarget.window=32", "retarget.batch_size=4"]
    run = tmp_path / "run"
    r = _run("train.py", *common, f"target_rig={folder / 'cmu.bvh'}", "trainer.max_steps=20", "model.hidden_dim=32",
             "model.lstm_hidden=32", f"hydra.run.dir={run}")
    assert r.returncode == 0, r.stderr[-2000:]
    res = json.loads((run / "retarget.json").read_text())
    assert set(res["sets"]) == {"walk+run", "all"} and res["steps"] == 20
    walk = res["sets"]["walk+run"]
    assert walk["analytic"]["pos_err"] == 0 and walk["learned"]["pos_err"] > 0 and walk["copy"]["pos_err"] > 0
    assert (run / "retarget.png").stat().st_size > 10_000
    assert list(tmp_path.rglob("events.out.tfevents*"))  # TensorBoard (test/... scalars and the figure)
    ckpt = run / "checkpoints" / "retarget.ckpt"
    r = _run("eval.py", *common, f"ckpt_path={ckpt}", f"hydra.run.dir={tmp_path / 'eval'}")
    assert r.returncode == 0, r.stderr[-2000:]
    again = json.loads((tmp_path / "eval" / "retarget.json").read_text())
    assert again["sets"]["walk+run"]["learned"]["pos_err"] == pytest.approx(walk["learned"]["pos_err"], rel=1e-5)
    r = _run("eval.py", *common, f"ckpt_path={ckpt}", f"target_rig={folder / 'other.bvh'}",
             f"hydra.run.dir={tmp_path / 'eval2'}")
    assert r.returncode == 2 and r.stderr.strip().count("\n") == 0 and "is not the target rig" in r.stderr, r.stderr


@pytest.mark.slow
def test_no_callbacks_no_logger_and_a_missing_rig(folder, tmp_path):
    common = ["task=retarget", "data=bvh", f"data.path={folder / 'clips'}", f"paths.log_dir={tmp_path / 'logs'}",
              f"paths.cache_dir={tmp_path / 'cache'}", "threads=1", "retarget.window=32", "callbacks=none",
              "logger=none", "trainer.max_steps=3", f"hydra.run.dir={tmp_path / 'run'}"]
    r = _run("train.py", *common, f"target_rig={folder / 'cmu.bvh'}", "retarget.contents=null")
    assert r.returncode == 0, r.stderr[-2000:]
    first = json.loads((tmp_path / "run" / "retarget.json").read_text())
    assert set(first["sets"]) == {"all"}
    r = _run("train.py", *common[:-1], f"hydra.run.dir={tmp_path / 'again'}", f"target_rig={folder / 'cmu.bvh'}",
             "retarget.contents=null")
    again = json.loads((tmp_path / "again" / "retarget.json").read_text())
    assert again["sets"]["all"]["learned"]["pos_err"] == first["sets"]["all"]["learned"]["pos_err"]  # same seed
    r = _run("train.py", *common, f"target_rig={folder / 'nowhere.bvh'}")
    assert r.returncode == 2 and r.stderr.strip() .startswith("error: target_rig:") and r.stderr.count("\n") == 1
