"""Shared fixtures: a per-session dataset cache and Hydra config composition; :func:`benchmark_script`."""
from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from hydra.core.global_hydra import GlobalHydra
from omegaconf import open_dict

CONF_DIR = str(Path(__file__).resolve().parents[1] / "conf")
BENCHMARKS_DIR = Path(__file__).resolve().parents[1] / "benchmarks"


def benchmark_script(name: str):
    """``benchmarks/<name>.py`` loaded as a module (its sibling helpers, such as ``_report``, importable meanwhile)."""
    sys.path.insert(0, str(BENCHMARKS_DIR))
    try:
        spec = importlib.util.spec_from_file_location(name, BENCHMARKS_DIR / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module
    finally:
        sys.path.remove(str(BENCHMARKS_DIR))


# the start of a script run in a subprocess that must work without PyTorch (the fill runtime, as Blender bundles it)
BLOCK_TORCH = """
import importlib.abc, sys
class NoTorch(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name == "torch" or name.startswith("torch."):
            raise ImportError("no torch here")
sys.meta_path.insert(0, NoTorch())
"""


def model_overrides(name: str) -> list[str]:
    """Hydra overrides ``model.<key>=<value>`` of the small test sizes a model declares (``MODELS[name].TINY``)."""
    from inbetweening.models import MODELS

    def value(v) -> str:
        return "null" if v is None else str(v).lower() if isinstance(v, bool) else str(v)

    return [f"model.{k}={value(v)}" for k, v in MODELS[name].TINY.items()]


TINY_PARENTS = [-1, 0, 1, 2, 1, 4]  # small tree: 0-1-2-3 and 1-4-5
TINY_MAX_FRAMES = 16


def tiny_adjacency(parents=TINY_PARENTS) -> list[list[float]]:
    """The parent/child relation matrix with self-loops, from the project's Skeleton."""
    from inbetweening.geometry.skeleton import Skeleton

    return Skeleton([f"j{i}" for i in range(len(parents))], parents, [[0.0, 0.0, 0.0]] * len(parents)).adjacency(1).tolist()


def tiny_model(name: str, **kw):
    """``MODELS[name]`` with its TINY sizes on the 6-joint test skeleton, ``max_frames=16``, no dropout, predicting
    frames (not a correction to the interpolation: the output head keeps its random start); ``kw`` wins."""
    from inbetweening.models import MODELS

    args = {"num_joints": len(TINY_PARENTS), "adjacency": tiny_adjacency(), "max_frames": TINY_MAX_FRAMES,
            "dropout": 0.0, "residual_to_interpolation": False, **MODELS[name].TINY}
    return MODELS[name](**{**args, **kw})


# tiny model/data settings for fast CPU tests
TINY = [
    *model_overrides("graph_transformer"), "data.synthetic.num_clips=10",
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
    *model_overrides("graph_transformer"), "data.synthetic.num_clips=10",
    "data.synthetic.min_frames=120", "data.synthetic.max_frames=160", "data.batch_size=8",
    "data.max_eval_windows=8", "trainer.max_steps=3", "trainer.max_epochs=1",
    "trainer.enable_model_summary=false", "+trainer.enable_progress_bar=false",
    "callbacks=none", "logger=none", "run_test=false",
]


@pytest.fixture(scope="session")
def tiny_checkpoint(tmp_path_factory, cache_dir) -> Path:
    """A real training checkpoint: a tiny graph_transformer trained 3 steps on synthetic data (~10 s)."""
    return _tiny_checkpoint(tmp_path_factory.mktemp("tiny_checkpoint"), cache_dir, TINY_CKPT_OVERRIDES)


@pytest.fixture(scope="session")
def tiny_contact_checkpoint(tmp_path_factory, cache_dir) -> Path:
    """:func:`tiny_checkpoint` with foot contact channels and the gate (``representation=
    global_pos_local_quat_contact model.gate=true``)."""
    return _tiny_checkpoint(tmp_path_factory.mktemp("tiny_contact_checkpoint"), cache_dir,
                            [*TINY_CKPT_OVERRIDES, "representation=global_pos_local_quat_contact", "model.gate=true"])


def _tiny_checkpoint(out: Path, cache_dir: Path, overrides: list[str]) -> Path:
    from inbetweening.training.train import train

    GlobalHydra.instance().clear()
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose("train", overrides=overrides)
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
