"""Shared fixtures: a per-session dataset cache and Hydra config composition."""
from __future__ import annotations

import os
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from hydra.core.global_hydra import GlobalHydra
from omegaconf import open_dict

CONF_DIR = str(Path(__file__).resolve().parents[1] / "conf")

# tiny model/data settings for fast CPU tests
TINY = [
    "model.d_model=16", "model.depth=1", "model.heads=2", "data.synthetic.num_clips=10",
    "data.synthetic.min_frames=120", "data.synthetic.max_frames=160", "data.batch_size=8",
    "data.max_eval_windows=8", "trainer.max_steps=3", "trainer.max_epochs=1", "trainer.log_every_n_steps=1",
    "trainer.enable_model_summary=false",
]


@pytest.fixture(scope="session")
def cache_dir(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("cache")
    os.environ["INBETWEENING_CACHE"] = str(d)
    return d


def compose_cfg(config_name: str, overrides: list[str], out_dir: Path, cache: Path):
    """Compose a config like the command line would, with outputs in ``out_dir``."""
    GlobalHydra.instance().clear()
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose(config_name, overrides=overrides, return_hydra_config=False)
    with open_dict(cfg):
        cfg.paths.output_dir = str(out_dir)
        cfg.paths.cache_dir = str(cache)
        cfg.paths.log_dir = str(out_dir / "logs")
    return cfg


# ------------------------------------------------------------------ animator tools (predict / export / notebook)
TINY_CKPT_OVERRIDES = [
    "model.d_model=16", "model.depth=1", "model.heads=2", "data.synthetic.num_clips=10",
    "data.synthetic.min_frames=120", "data.synthetic.max_frames=160", "data.batch_size=8",
    "data.max_eval_windows=8", "trainer.max_steps=3", "trainer.max_epochs=1",
    "trainer.enable_model_summary=false", "+trainer.enable_progress_bar=false",
    "callbacks=none", "logger=none", "run_test=false",
]


@pytest.fixture(scope="session")
def tiny_checkpoint(tmp_path_factory, cache_dir) -> Path:
    """A real training checkpoint: a tiny graph_transformer trained 3 steps on synthetic data (~10 s)."""
    from inbetweening.training.train import train

    out = tmp_path_factory.mktemp("tiny_checkpoint")
    GlobalHydra.instance().clear()
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose("train", overrides=TINY_CKPT_OVERRIDES)
    with open_dict(cfg):
        cfg.paths.output_dir = str(out)
        cfg.paths.cache_dir = str(cache_dir)
        cfg.paths.log_dir = str(out / "logs")
    train(cfg)
    ckpts = sorted((out / "checkpoints").glob("*.ckpt"))
    assert ckpts, f"training wrote no checkpoint under {out}"
    return ckpts[-1]


def sinusoid_batch(joints: int, b: int = 16, t: int = 12, seed: int = 1, island: bool = False):
    """A smooth regression task for tiny training tests: sinusoid positions/rotations per joint, the middle
    frames masked.  Returns ``(masked x, known, target)`` with shapes ``(b, t, joints, 7)``, ``(b, t, joints)``."""
    import math

    import torch

    g = torch.Generator().manual_seed(seed)
    phase = torch.rand(b, 1, 1, 1, generator=g) * 2 * math.pi
    freq = 0.3 + 0.3 * torch.rand(b, 1, 1, 1, generator=g)
    tt = torch.arange(t, dtype=torch.float32)[None, :, None, None]
    jj = torch.arange(joints, dtype=torch.float32)[None, None, :, None]
    pos = torch.sin(freq * tt + phase + 0.5 * jj + torch.arange(3.0))
    half = 0.4 * torch.sin(freq * tt + phase + jj)
    quat = torch.cat([torch.cos(half), torch.zeros_like(half), torch.zeros_like(half), torch.sin(half)], dim=-1)
    y = torch.cat([pos, quat], dim=-1)
    known = torch.zeros(b, t, joints, dtype=torch.bool)
    known[:, :3] = True
    known[:, -2:] = True
    if island:
        known[:, 5:7, :3] = True  # a per-joint island inside the gap
    return y * known[..., None], known, y
