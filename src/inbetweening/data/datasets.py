"""Motion datasets behind one interface: ``load_dataset(name, path=..., ...) -> MotionData``.

What a name means (files, named splits, forward axis, root folding, mirror map, reader) is its
:class:`~inbetweening.data.specs.DatasetSpec` in :data:`~inbetweening.data.specs.DATASETS`; this module
only runs the steps every dataset shares: find the files (:func:`resolve_path`), read and split the clips,
cut and normalise the benchmark windows, compute the training statistics, and cache the result.

Prepared data (clips, benchmark windows, statistics) is cached as ``.npy`` files (memory-mapped on load)
in a folder keyed by a hash of the source files' bytes and of every preprocessing setting (the split
included), so a changed file or setting never serves stale data (:mod:`inbetweening.data.cache`).
"""
from __future__ import annotations

import dataclasses
import hashlib
import os
import shutil
import warnings
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from inbetweening.data import windows as W
from inbetweening.data.bvh_folder import BVH_DATASET, DERIVATION, FolderOptions, derive_spec, source_paths
from inbetweening.data.cache import CacheCorrupt, default_cache_dir, hash_source, load_entry, save_entry, settings_key
from inbetweening.data.clips import Clip, MotionData, check_skeleton, clip_from_bvh, fold_static_root, read_workers
from inbetweening.data.contacts import FootContact
from inbetweening.data.convention import FileConvention
from inbetweening.data.errors import BVHError, DatasetError
from inbetweening.data.lafan1 import download_lafan1, verify_lafan1
from inbetweening.data.mirror import derive_mirror, validate_mirror
from inbetweening.data.specs import (
    DATASETS,
    DEFAULT_SPLIT,
    DatasetSpec,
    SplitRule,
    bandai_namco_content_split,
    bandai_namco_split,
    get_spec,
    lafan_split,
    register,
)
from inbetweening.geometry.skeleton import Skeleton

CACHE_VERSION = 4  # 4: checksums in meta.json


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
        "split": data.split,
        "contact": data.contact.to_dict(),
        "convention": data.convention.to_dict(),
        "derived": data.derived,
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
        meta["source"], split=meta.get("split", DEFAULT_SPLIT), contact=FootContact.from_dict(meta.get("contact")),
        convention=FileConvention.from_dict(meta.get("convention")), derived=meta.get("derived"),
    )


# ------------------------------------------------------------------------------------------
# Preparation
# ------------------------------------------------------------------------------------------
def _read_clips(spec: DatasetSpec, path: Path, rule: SplitRule) -> tuple[Skeleton, float, dict[str, list[Clip]]]:
    """The spec's reader over ``path``: one skeleton, the first file's frame rate, clips per split of ``rule``."""
    skel: Skeleton | None = None
    fps = None
    splits: dict[str, list[Clip]] = {"train": [], "test": []}
    for fname, clip, s, rate in spec.reader(spec, path):
        split = rule(fname)
        if split is None:
            continue
        skel = check_skeleton(skel, s, fname)
        fps = fps or rate or spec.fps
        splits[split].append(clip)
    if skel is None:
        raise DatasetError(f"{path}: no file matching the dataset's naming scheme ({spec.pattern}) was found")
    if abs(fps - spec.fps) > 0.01 * spec.fps:
        warnings.warn(f"{spec.name}: {path} runs at {fps:.6g} fps, the dataset spec says {spec.fps:g}", stacklevel=3)
    return skel, float(round(fps, 6)), splits


def prepare(spec: DatasetSpec, path: Path, forward_axis, split: str = DEFAULT_SPLIT) -> MotionData:
    """Read every file, split (by the spec's split ``split``), cut/normalise the benchmark windows, compute
    training statistics."""
    skel, fps, splits = _read_clips(spec, path, spec.split_rule(split))
    stats = W.training_stats(splits["train"], skel, W.TRAIN_WINDOW, W.TRAIN_OFFSET, forward_axis,
                             threads=read_workers())
    if stats is None:
        raise DatasetError(f"{path}: no training window of {W.TRAIN_WINDOW} frames could be cut: the longest training "
                           f"clip has {max((c.num_frames for c in splits['train']), default=0)} frames")
    mean, std = stats
    teX, teQ = W.prepare_windows(splits["test"], skel, W.TEST_WINDOW, W.TEST_OFFSET, forward_axis)
    if len(teX) == 0:
        raise DatasetError(f"{path}: no test window of {W.TEST_WINDOW} frames (the benchmark's) could be cut: the "
                           f"longest test clip has {max((c.num_frames for c in splits['test']), default=0)} frames")
    return MotionData(spec.name, skel, fps, tuple(float(a) for a in forward_axis), splits["train"], splits["test"],
                      mean, std, teX, teQ, str(path), split=split, contact=spec_contact(spec))


def spec_contact(spec: DatasetSpec) -> FootContact:
    """The spec's feet and contact rule."""
    return FootContact(spec.feet, spec.contact_height, spec.contact_speed)


def resolve_path(name: str, path: str | os.PathLike | None, download: bool = False) -> Path:
    """Find a dataset's files: explicit path, else the spec's env var (``LAFAN1_PATH``, ``BANDAI_NAMCO_PATH``)."""
    spec = DATASETS.get(name)
    env = spec.env_var if spec else None
    if not path and env:
        path = os.environ.get(env)
    if not path:
        raise DatasetError(f"data.path is not set for dataset {name!r} (set data.path=...{f' or ${env}' if env else ''})")
    p = Path(path).expanduser()
    if not p.exists():
        if download and spec is not None and spec.download is not None:
            return spec.download(p)
        where = "" if p.is_absolute() else f" (relative to the working directory {Path.cwd()})"
        raise DatasetError(f"{name}: {p} does not exist{where}; {spec.path_hint if spec else ''}")
    return p


def mirror_map(spec: DatasetSpec, skeleton: Skeleton) -> tuple[tuple[str, str], ...]:
    """The spec's mirror map (derived from the joint names when it declares none), validated against ``skeleton``."""
    pairs = derive_mirror(skeleton.names) if spec.mirror is None else spec.mirror
    return validate_mirror(pairs, skeleton.names, f"dataset {spec.name!r} mirror map")


def load_dataset(
    name: str,
    path: str | os.PathLike | None = None,
    cache_dir: str | os.PathLike | None = None,
    forward_axis: Iterable[float] | None = None,
    use_cache: bool = True,
    download: bool = False,
    synthetic: dict | None = None,
    split: str = DEFAULT_SPLIT,
    folder: FolderOptions | None = None,
) -> MotionData:
    """Load (or prepare and cache) a registered dataset (:data:`~inbetweening.data.specs.DATASETS`) by name.

    ``synthetic`` holds the options of a generated dataset's ``generate`` (ignored by the others);
    ``forward_axis`` overrides the spec's; ``split`` names one of the spec's split rules (``DatasetSpec.splits``,
    :class:`DatasetError` for another name).  ``name="bvh"``: any folder of BVH files, its spec derived from the files
    (:mod:`inbetweening.data.bvh_folder`; ``folder`` holds the ``data.<key>`` overrides, which only it takes).
    """
    folder = folder or FolderOptions()
    if name == BVH_DATASET:
        if forward_axis is not None:
            folder = dataclasses.replace(folder, forward_axis=tuple(float(a) for a in forward_axis))
        return load_bvh_folder(path, cache_dir, folder, use_cache, split)
    if folder.given():
        raise DatasetError(f"data.{folder.given()[0]}: only data=bvh derives its spec from the files; dataset "
                           f"{name!r} states its own (set it back to null)")
    spec = get_spec(name)
    spec.split_rule(split)  # an unknown split fails before any file is read
    cache_root = Path(cache_dir) if cache_dir else default_cache_dir()
    if spec.generate is not None:
        src = spec.generate(cache_root / spec.name, **(synthetic or {}))
    else:
        src = resolve_path(name, path, download)
    axis = tuple(float(a) for a in (forward_axis if forward_axis is not None else spec.forward_axis))
    settings = {
        "v": CACHE_VERSION, "name": name, "axis": axis, "fold": spec.fold_root,
        "train": (W.TRAIN_WINDOW, W.TRAIN_OFFSET), "test": (W.TEST_WINDOW, W.TEST_OFFSET),
    }
    if split != DEFAULT_SPLIT:  # the standard split keeps the key it had before splits had names (entries stay valid)
        settings["split"] = split
    if not use_cache:
        data = prepare(spec, src, axis, split)
        data.mirror = mirror_map(spec, data.skeleton)
        data.contact = spec_contact(spec)
        return data
    key = f"{name}-{hash_source(src, cache_root, spec.pattern)[:16]}-{settings_key(settings)}"
    cache_file = cache_root / "prepared" / key
    data = None
    if (cache_file / "meta.json").exists():
        try:
            data = _load_cache(cache_file)
        except (CacheCorrupt, OSError, ValueError, KeyError) as e:  # corrupt entry: say so, rebuild it
            warnings.warn(f"dataset cache entry {cache_file} is unreadable or corrupt ({e}); rebuilding it", stacklevel=2)
            shutil.rmtree(cache_file, ignore_errors=True)
    if data is None:
        data = prepare(spec, src, axis, split)
        _save_cache(cache_file, data)
    data.mirror = mirror_map(spec, data.skeleton)
    data.contact = spec_contact(spec)
    return data


def load_bvh_folder(path, cache_dir=None, options: FolderOptions | None = None, use_cache: bool = True,
                    split: str = DEFAULT_SPLIT) -> MotionData:
    """``data=bvh``: the BVH files of ``path`` (a folder, zip or file, or a list of them) with their derived spec
    (:func:`~inbetweening.data.bvh_folder.derive_spec`), prepared like every dataset and cached under a key of the
    files' bytes and the options."""
    options = options or FolderOptions()
    paths = source_paths(path)
    cache_root = Path(cache_dir) if cache_dir else default_cache_dir()
    digest = hashlib.sha1("".join(hash_source(p, cache_root, "*.bvh") for p in paths).encode()).hexdigest()
    settings = {"v": CACHE_VERSION, "derivation": DERIVATION, "name": BVH_DATASET, "options": options.settings(),
                "split": split, "train": (W.TRAIN_WINDOW, W.TRAIN_OFFSET), "test": (W.TEST_WINDOW, W.TEST_OFFSET)}
    cache_file = cache_root / "prepared" / f"{BVH_DATASET}-{digest[:16]}-{settings_key(settings)}"
    if use_cache and (cache_file / "meta.json").exists():
        try:
            data = _load_cache(cache_file)
            data.mirror = tuple(tuple(p) for p in data.derived["mirror"])
            return data
        except (CacheCorrupt, OSError, ValueError, KeyError, TypeError) as e:
            warnings.warn(f"dataset cache entry {cache_file} is unreadable or corrupt ({e}); rebuilding it", stacklevel=2)
            shutil.rmtree(cache_file, ignore_errors=True)
    spec, report = derive_spec(paths, options)
    spec.split_rule(split)
    data = prepare(spec, paths[0], spec.forward_axis, split)
    data.source = ", ".join(str(p) for p in paths)
    data.convention = FileConvention(report["up_axis"], report["unit_cm"])
    data.mirror = spec.mirror
    data.derived = dict(report, mirror=[list(p) for p in spec.mirror])
    if use_cache:
        _save_cache(cache_file, data)
    return data


__all__ = [
    "BVHError",
    "CACHE_VERSION",
    "DATASETS",
    "Clip",
    "DatasetError",
    "DEFAULT_SPLIT",
    "DatasetSpec",
    "MotionData",
    "bandai_namco_content_split",
    "bandai_namco_split",
    "clip_from_bvh",
    "download_lafan1",
    "fold_static_root",
    "lafan_split",
    "load_bvh_folder",
    "load_dataset",
    "mirror_map",
    "register",
    "resolve_path",
    "verify_lafan1",
]
