"""Motion datasets behind one interface: ``load_dataset(name, path=..., ...) -> MotionData``.

* ``lafan1``       - Ubisoft LAFAN1, 77 BVH files ``<name>_subjectN.bvh`` (folder or ``lafan1.zip``);
                     train = subject1-4, test = subject5; forward = root local +Y.
* ``bandai_namco`` - Bandai-Namco-Research-Motiondataset-1/-2 (folder or zip).  The static
                     ``joint_Root`` is folded into ``Hips``, which becomes the root; test = takes whose
                     3-digit take number is divisible by 10, train = the rest.
* ``synthetic``    - procedurally generated LAFAN-format BVH files (see :mod:`inbetweening.data.synthetic`),
                     read back through the same BVH reader; test = subject5.

Prepared data (clips, benchmark windows, statistics) is cached as ``.npy`` files (memory-mapped on load)
in a folder keyed by a hash of the
source files' bytes and of every preprocessing setting, so a changed file or setting never
serves stale data.
"""
from __future__ import annotations

import hashlib
import os
import re
import shutil
import urllib.request
import warnings
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from inbetweening.data.bvh import BVH, BVHError, iter_bvh_sources, parse_bvh
from inbetweening.data.cache import CacheCorrupt, default_cache_dir, hash_source, load_entry, save_entry, settings_key
from inbetweening.evaluation import benchmark as B
from inbetweening.geometry.quaternion import qmul, qrot, remove_discontinuities
from inbetweening.geometry.skeleton import Skeleton

CACHE_VERSION = 4  # 4: checksums in meta.json
LAFAN1_URL = "https://github.com/ubisoft/ubisoft-laforge-animation-dataset/raw/master/lafan1/lafan1.zip"
LAFAN1_SIZE = 144_051_503
LAFAN1_SHA256 = "ea918082b500a5d158e9d3aa39039df04cd42e25f5c02fe8f7e88e8e9365a977"

# Root-local direction that is "forward" for each dataset (see README: Bandai-Namco measured on walk clips)
FORWARD_AXES = {"lafan1": (0.0, 1.0, 0.0), "bandai_namco": (0.0, 0.0, 1.0), "synthetic": (0.0, 0.0, 1.0)}


class DatasetError(RuntimeError):
    """A dataset could not be found or prepared; the message says which path and what to do."""


@dataclass
class Clip:
    """One motion clip: local quaternions ``(F, J, 4)`` wxyz and root positions ``(F, 3)`` (float64)."""

    name: str
    local_q: np.ndarray
    root_pos: np.ndarray

    @property
    def num_frames(self) -> int:
        return int(self.root_pos.shape[0])


@dataclass
class MotionData:
    """A prepared dataset: skeleton, clips per split, normalised benchmark windows and statistics."""

    name: str
    skeleton: Skeleton
    fps: float
    forward_axis: tuple[float, float, float]
    train: list[Clip]
    test: list[Clip]
    pos_mean: np.ndarray  # (J*3,) mean of global positions over the training windows
    pos_std: np.ndarray  # (J*3,)
    test_X: np.ndarray = field(repr=False)  # (N, 65, J, 3) normalised benchmark windows
    test_Q: np.ndarray = field(repr=False)  # (N, 65, J, 4)
    source: str = ""

    def benchmark_set(self) -> B.BenchmarkSet:
        return B.BenchmarkSet(self.test_X, self.test_Q, self.skeleton, self.pos_mean, self.pos_std)

    def summary(self) -> dict:
        return {
            "dataset": self.name,
            "joints": self.skeleton.num_joints,
            "train_clips": len(self.train),
            "test_clips": len(self.test),
            "train_frames": int(sum(c.num_frames for c in self.train)),
            "test_frames": int(sum(c.num_frames for c in self.test)),
            "test_windows": int(self.test_X.shape[0]),
        }


# ------------------------------------------------------------------------------------------
# BVH -> clips
# ------------------------------------------------------------------------------------------
def clip_from_bvh(bvh: BVH, name: str) -> tuple[Clip, Skeleton]:
    """Local quaternions of every joint and the root's position channels, LAFAN1 convention."""
    return Clip(name, bvh.local_rotations(), bvh.local_positions()[:, 0].copy()), bvh.skeleton()


def fold_static_root(bvh: BVH, name: str, root_name: str = "joint_Root") -> tuple[Clip, Skeleton]:
    """Drop a motionless top joint (Bandai-Namco's ``joint_Root``) by composing it into its child.

    The child (``Hips``) becomes the root: its global rotation = R_top ⊗ R_hips and its global
    position = p_top + R_top · p_hips, so the animation is unchanged.  Raises if the top joint is
    not ``root_name`` or has more than one child.
    """
    if bvh.names[0] != root_name:
        raise DatasetError(f"{name}: expected top joint {root_name!r}, found {bvh.names[0]!r}")
    kids = [j for j, p in enumerate(bvh.parents) if p == 0]
    if kids != [1]:
        raise DatasetError(f"{name}: {root_name} must have exactly one child (joint 1), has {kids}")
    q = bvh.local_rotations()
    p = bvh.channel_positions()
    hips_q = qmul(q[:, 0], q[:, 1])
    hips_p = p[:, 0] + qrot(q[:, 0], p[:, 1])
    local_q = np.concatenate([hips_q[:, None], q[:, 2:]], axis=1)
    local_q = remove_discontinuities(local_q, axis=0)
    skel = Skeleton(tuple(bvh.names[1:]), tuple(int(x) - 1 for x in bvh.parents[1:]), bvh.offsets[1:])
    return Clip(name, local_q, hips_p), skel


def _check_skeleton(ref: Skeleton | None, skel: Skeleton, name: str) -> Skeleton:
    if ref is None:
        return skel
    if not ref.same_topology(skel):
        raise DatasetError(f"{name}: skeleton differs from the dataset's first file ({skel.names[:3]}... vs {ref.names[:3]}...)")
    return ref


# ------------------------------------------------------------------------------------------
# Per-dataset file selection and split
# ------------------------------------------------------------------------------------------
_LAFAN_RE = re.compile(r"^(?P<seq>.+)_(?P<subject>subject\d+)\.bvh$", re.IGNORECASE)
_BN_RE = re.compile(r"^dataset-(?P<ds>[12])_(?P<content>.+?)_(?P<style>[^_]+)_(?P<take>\d{3})\.bvh$", re.IGNORECASE)


def lafan_split(fname: str, train_subjects=("subject1", "subject2", "subject3", "subject4"), test_subjects=("subject5",)):
    m = _LAFAN_RE.match(fname)
    if not m:
        return None
    subj = m.group("subject").lower()
    return "train" if subj in train_subjects else "test" if subj in test_subjects else None


def bandai_namco_split(fname: str):
    m = _BN_RE.match(fname)
    if not m:
        return None
    return "test" if int(m.group("take")) % 10 == 0 else "train"


# ------------------------------------------------------------------------------------------
# Cache entries (the format lives in :mod:`inbetweening.data.cache`)
# ------------------------------------------------------------------------------------------
def _save_cache(path: Path, data: MotionData) -> None:
    arrays = {
        "pos_mean": data.pos_mean,
        "pos_std": data.pos_std,
        "test_X": data.test_X,
        "test_Q": data.test_Q,
        "offsets": data.skeleton.offsets,
    }
    meta = {
        "name": data.name,
        "fps": data.fps,
        "forward_axis": list(data.forward_axis),
        "names": list(data.skeleton.names),
        "parents": list(data.skeleton.parents),
        "source": data.source,
    }
    for split in ("train", "test"):
        clips = getattr(data, split)
        meta[f"{split}_names"] = [c.name for c in clips]
        meta[f"{split}_lengths"] = [c.num_frames for c in clips]
        j = data.skeleton.num_joints
        arrays[f"{split}_q"] = np.concatenate([c.local_q for c in clips]) if clips else np.zeros((0, j, 4))
        arrays[f"{split}_root"] = np.concatenate([c.root_pos for c in clips]) if clips else np.zeros((0, 3))
    save_entry(path, arrays, meta)


def _load_cache(path: Path) -> MotionData:
    arrays, meta = load_entry(path)
    skel = Skeleton(tuple(meta["names"]), tuple(meta["parents"]), arrays["offsets"])
    splits = {}
    for split in ("train", "test"):
        bounds = np.cumsum([0] + meta[f"{split}_lengths"])
        q, r = arrays[f"{split}_q"], arrays[f"{split}_root"]
        splits[split] = [Clip(n, q[a:b], r[a:b]) for n, a, b in zip(meta[f"{split}_names"], bounds[:-1], bounds[1:])]
    return MotionData(
        meta["name"], skel, meta["fps"], tuple(meta["forward_axis"]), splits["train"], splits["test"],
        arrays["pos_mean"], arrays["pos_std"], np.asarray(arrays["test_X"]), np.asarray(arrays["test_Q"]),
        meta["source"],
    )


# ------------------------------------------------------------------------------------------
# Preparation
# ------------------------------------------------------------------------------------------
def _read_clips(path: Path, split_fn, fold_root: str | None) -> tuple[Skeleton, float, dict[str, list[Clip]]]:
    skel: Skeleton | None = None
    fps = None
    splits: dict[str, list[Clip]] = {"train": [], "test": []}
    for fname, raw in iter_bvh_sources(path):
        split = split_fn(fname)
        if split is None:
            continue
        bvh = parse_bvh(raw, source=fname)
        stem = fname[:-4]
        clip, s = fold_static_root(bvh, stem, fold_root) if fold_root else clip_from_bvh(bvh, stem)
        skel = _check_skeleton(skel, s, fname)
        fps = fps or (1.0 / bvh.frame_time if bvh.frame_time > 0 else 30.0)
        splits[split].append(clip)
    if skel is None:
        raise DatasetError(f"{path}: no BVH file matching the dataset's naming scheme was found")
    return skel, float(round(fps, 6)), splits


def prepare(name: str, path: Path, split_fn, fold_root: str | None, forward_axis) -> MotionData:
    """Read every file, split, cut/normalise the benchmark windows, compute training statistics."""
    skel, fps, splits = _read_clips(path, split_fn, fold_root)
    trX, trQ = B.prepare_windows(splits["train"], skel, B.TRAIN_WINDOW, B.TRAIN_OFFSET, forward_axis)
    if len(trX) == 0:
        raise DatasetError(f"{path}: no training window of {B.TRAIN_WINDOW} frames could be cut")
    mean, std = B.position_stats(trX, trQ, skel.parents)
    teX, teQ = B.prepare_windows(splits["test"], skel, B.TEST_WINDOW, B.TEST_OFFSET, forward_axis)
    return MotionData(name, skel, fps, tuple(float(a) for a in forward_axis), splits["train"], splits["test"],
                      mean, std, teX, teQ, str(path))


DATASETS = {
    "lafan1": {"split": lafan_split, "fold_root": None},
    "bandai_namco": {"split": bandai_namco_split, "fold_root": "joint_Root"},
    "synthetic": {"split": lafan_split, "fold_root": None},
}


def resolve_path(name: str, path: str | os.PathLike | None, download: bool = False) -> Path:
    """Find a dataset's files: explicit path, else env var (``LAFAN1_PATH``, ``BANDAI_NAMCO_PATH``)."""
    env = {"lafan1": "LAFAN1_PATH", "bandai_namco": "BANDAI_NAMCO_PATH"}.get(name)
    if not path and env:
        path = os.environ.get(env)
    if not path:
        raise DatasetError(f"data.path is not set for dataset {name!r} (set data.path=... or ${env})")
    p = Path(path).expanduser()
    if not p.exists():
        if name == "lafan1" and download:
            return download_lafan1(p)
        hint = {
            "lafan1": "download lafan1.zip from the ubisoft-laforge-animation-dataset repository and pass its path "
            "(or the folder of extracted .bvh files) as data.path=... or $LAFAN1_PATH",
            "bandai_namco": "pass the Bandai-Namco-Research-Motiondataset zip or its data/ folder as data.path=...",
        }.get(name, "")
        where = "" if p.is_absolute() else f" (relative to the working directory {Path.cwd()})"
        raise DatasetError(f"{name}: {p} does not exist{where}; {hint}")
    return p


def download_lafan1(dest: Path, url: str = LAFAN1_URL, timeout: float = 30.0) -> Path:
    """Download the official ``lafan1.zip`` to ``dest`` and verify its size and sha256."""
    dest = dest if dest.suffix == ".zip" else dest / "lafan1.zip"
    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = dest.with_suffix(".part")
    try:
        with urllib.request.urlopen(url, timeout=timeout) as r, open(tmp, "wb") as f:
            while chunk := r.read(1 << 20):
                f.write(chunk)
    except OSError as e:  # URLError is an OSError
        tmp.unlink(missing_ok=True)
        raise DatasetError(
            f"lafan1: could not download {url} ({e}); this machine seems offline. Put lafan1.zip "
            f"({LAFAN1_SIZE} bytes) at {dest} or pass data.path=<zip or folder of .bvh>"
        ) from None
    return verify_lafan1(tmp, final=dest)


def verify_lafan1(path: Path, final: Path | None = None) -> Path:
    size = path.stat().st_size
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    if size != LAFAN1_SIZE or digest != LAFAN1_SHA256:
        raise DatasetError(f"lafan1: {path} has size {size} and sha256 {digest}; expected {LAFAN1_SIZE} / {LAFAN1_SHA256}")
    if final is not None:
        os.replace(path, final)
        return final
    return path


def load_dataset(
    name: str,
    path: str | os.PathLike | None = None,
    cache_dir: str | os.PathLike | None = None,
    forward_axis: Iterable[float] | None = None,
    use_cache: bool = True,
    download: bool = False,
    synthetic: dict | None = None,
) -> MotionData:
    """Load (or prepare and cache) a dataset by name.  See the module docstring for names."""
    if name not in DATASETS:
        raise DatasetError(f"unknown dataset {name!r}; choose one of {sorted(DATASETS)}")
    cache_root = Path(cache_dir) if cache_dir else default_cache_dir()
    if name == "synthetic":
        from inbetweening.data.synthetic import generate_dataset

        src = generate_dataset(cache_root / "synthetic", **(synthetic or {}))
    else:
        src = resolve_path(name, path, download)
    axis = tuple(float(a) for a in (forward_axis if forward_axis is not None else FORWARD_AXES[name]))
    spec = DATASETS[name]
    settings = {
        "v": CACHE_VERSION, "name": name, "axis": axis, "fold": spec["fold_root"],
        "train": (B.TRAIN_WINDOW, B.TRAIN_OFFSET), "test": (B.TEST_WINDOW, B.TEST_OFFSET),
    }
    if not use_cache:
        return prepare(name, src, spec["split"], spec["fold_root"], axis)
    key = f"{name}-{hash_source(src, cache_root)[:16]}-{settings_key(settings)}"
    cache_file = cache_root / "prepared" / key
    if (cache_file / "meta.json").exists():
        try:
            return _load_cache(cache_file)
        except (CacheCorrupt, OSError, ValueError, KeyError) as e:  # corrupt entry: say so, rebuild it
            warnings.warn(f"dataset cache entry {cache_file} is unreadable or corrupt ({e}); rebuilding it", stacklevel=2)
            shutil.rmtree(cache_file, ignore_errors=True)
    data = prepare(name, src, spec["split"], spec["fold_root"], axis)
    _save_cache(cache_file, data)
    return data


__all__ = [
    "FORWARD_AXES",
    "BVHError",
    "Clip",
    "DatasetError",
    "MotionData",
    "bandai_namco_split",
    "clip_from_bvh",
    "fold_static_root",
    "lafan_split",
    "load_dataset",
]
