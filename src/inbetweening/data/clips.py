"""Clips and prepared datasets: the :class:`Clip`/:class:`MotionData` classes and BVH -> clip conversion.

:func:`read_bvh_clips` is the default reader of a :class:`~inbetweening.data.specs.DatasetSpec`: it yields
one clip per BVH file of a folder or zip whose name one of the spec's split rules accepts, folding a top joint into
its child where the spec asks (:func:`fold_static_root`: by composition, lossless whether the top joint holds still
or carries the locomotion).
"""
from __future__ import annotations

import dataclasses
import multiprocessing
import os
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import numpy as np

from inbetweening.data.bvh import BVH, parse_bvh
from inbetweening.data.contacts import FootContact
from inbetweening.data.convention import PROJECT, FileConvention
from inbetweening.data.errors import BVHError, DatasetError
from inbetweening.data.sources import list_bvh_sources, read_bvh_sources
from inbetweening.data.windows import BenchmarkSet
from inbetweening.geometry.interp import interpolate_pose
from inbetweening.geometry.quaternion import qinv, qmul, qrot, remove_discontinuities
from inbetweening.geometry.skeleton import Skeleton


class ReadSpec(Protocol):
    """What the default reader needs of a :class:`~inbetweening.data.specs.DatasetSpec`."""

    pattern: str
    fold_root: str | None

    def reads(self, name: str) -> bool: ...

__all__ = ["FOLD_AUTO", "FOLD_TOP", "Clip", "MotionData", "check_skeleton", "clip_from_bvh", "clip_in_skeleton",
           "fold_static_root", "motion_in_file", "read_bvh_clips", "top_folds", "top_is_static"]


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
    # left/right joint-name pairs (left first) of the skeleton, validated against it: see inbetweening.data.mirror
    mirror: tuple[tuple[str, str], ...] = ()
    split: str = "standard"  # the spec's split rule that made train/test (DatasetSpec.splits)
    contact: FootContact = field(default_factory=FootContact)  # the feet and the foot-contact rule
    convention: FileConvention = PROJECT  # the files' up axis and unit (the clips are in the project's frame)
    derived: dict | None = None  # data=bvh: what was derived from the files and how (inbetweening.data.bvh_folder)

    def benchmark_set(self) -> BenchmarkSet:
        return BenchmarkSet(self.test_X, self.test_Q, self.skeleton, self.pos_mean, self.pos_std)

    def in_joint_order(self, names) -> MotionData:
        """This dataset with its joints in the order ``names`` (the same joints, by name, e.g. a checkpoint's): clips,
        skeleton, statistics and test windows permuted alike, the motion unchanged.  :class:`DatasetError` naming
        both skeletons when the joints or their hierarchy (parent of each joint, by name) differ, or when the order
        would put a child before its parent."""
        sk, names = self.skeleton, tuple(names)
        if names == sk.names:
            return self
        mine = {n: (sk.names[p] if p >= 0 else None) for n, p in zip(sk.names, sk.parents)}
        if set(names) != set(sk.names) or len(names) != len(sk.names):
            missing, extra = sorted(set(names) - set(sk.names)), sorted(set(sk.names) - set(names))
            raise DatasetError(f"{self.name}: another skeleton ({len(sk.names)} joints; missing {missing[:5]}, "
                               f"not expected {extra[:5]}) than the {len(names)}-joint one asked for")
        perm = [sk.names.index(n) for n in names]
        parents = tuple(names.index(mine[n]) if mine[n] is not None else -1 for n in names)
        if any(p >= j for j, p in enumerate(parents)) or parents[0] != -1:
            raise DatasetError(f"{self.name}: the joint order {list(names[:4])}... puts a joint before its parent")
        def stats(a):
            return np.asarray(a).reshape(-1, 3)[perm].reshape(-1)

        def reorder(clips):
            return [Clip(c.name, np.asarray(c.local_q)[:, perm], c.root_pos) for c in clips]

        return dataclasses.replace(
            self, skeleton=Skeleton(names, parents, sk.offsets[perm]), train=reorder(self.train),
            test=reorder(self.test), pos_mean=stats(self.pos_mean), pos_std=stats(self.pos_std),
            test_X=np.asarray(self.test_X)[:, :, perm], test_Q=np.asarray(self.test_Q)[:, :, perm])

    def summary(self) -> dict:
        return {
            "dataset": self.name,
            "split": self.split,
            "joints": self.skeleton.num_joints,
            "train_clips": len(self.train),
            "test_clips": len(self.test),
            "train_frames": int(sum(c.num_frames for c in self.train)),
            "test_frames": int(sum(c.num_frames for c in self.test)),
            "test_windows": int(self.test_X.shape[0]),
        }


def clip_from_bvh(bvh: BVH, name: str) -> tuple[Clip, Skeleton]:
    """Local quaternions of every joint and the root's position channels, LAFAN1 convention."""
    return Clip(name, bvh.local_rotations(), bvh.local_positions()[:, 0].copy()), bvh.skeleton()


def fold_static_root(bvh: BVH, name: str, root_name: str = "joint_Root") -> tuple[Clip, Skeleton]:
    """Drop the top joint (Bandai-Namco's ``joint_Root``) by composing it into its child, frame by frame.

    The child (``Hips``) becomes the root: its global rotation = R_top(f) ⊗ R_hips(f) and its global
    position = p_top(f) + R_top(f) · p_hips(f), so the animation is unchanged whether the top joint holds still
    (the name's origin) or moves (a take whose top joint carries the locomotion: its translation and rotation
    channels are composed into the root's motion).  Raises if the top joint is not ``root_name`` or has more than
    one child.  :func:`motion_in_file` writes such a clip back.
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


def clip_in_skeleton(bvh: BVH, skeleton: Skeleton) -> tuple[bool, np.ndarray, np.ndarray]:
    """``(folded?, root (F, 3), local_q (F, J, 4))`` of a file's motion in ``skeleton``'s joints: the same joint names
    in the same order, or one extra top joint above the skeleton's root (Bandai-Namco's ``joint_Root``, still or
    moving), folded into it (:func:`fold_static_root`).  :class:`DatasetError` naming the first joint that differs
    otherwise."""
    names, ck = list(bvh.names), list(skeleton.names)
    if names == ck:
        return False, bvh.local_positions()[:, 0].copy(), bvh.local_rotations()
    if names[1:] == ck:
        clip, _ = fold_static_root(bvh, bvh.source, root_name=names[0])
        return True, clip.root_pos, clip.local_q
    i = next((i for i, (a, b) in enumerate(zip(names, ck, strict=False)) if a != b), min(len(names), len(ck)))
    here = repr(names[i]) if i < len(names) else "(none)"
    there = repr(ck[i]) if i < len(ck) else "(none)"
    raise DatasetError(
        f"skeleton mismatch: {bvh.source} has {len(names)} joints, the checkpoint's skeleton has {len(ck)}; "
        f"first difference at joint {i}: file {here}, checkpoint {there}")


def motion_in_file(bvh: BVH, folded: bool, root: np.ndarray, q: np.ndarray, rows: np.ndarray,
                   top_from: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> BVH:
    """The inverse of :func:`clip_in_skeleton`: a BVH of ``bvh``'s hierarchy and channels whose frames carry
    ``root (F, 3), q (F, J, 4)`` (the skeleton's joints).  The channels the skeleton does not hold are taken from
    ``bvh``'s frames: non-root position channels from ``rows (F,)``; a folded top joint from ``rows`` too, or, with
    ``top_from = (before (F,), after (F,), w (F,))``, moved from row ``before`` to row ``after`` by the weight ``w``
    (position lerp, rotation slerp: a top joint that carries the locomotion moves smoothly between two keys).  The
    top joint's channels are copied raw (no Euler round trip) wherever its two rows hold the same values or ``w``
    is 0 (``before``'s) or 1 (``after``'s): a motionless top joint, a key.  The skeleton's root then gets the given
    global motion expressed under that top joint (``R_top⁻¹ R_root``, ``R_top⁻¹ (p_root - p_top)``), so the world
    motion is ``root, q`` whatever the top joint does; where the child has no position channels the translation goes
    on the top joint's position channels (``p_root - R_top · offset``).  :class:`BVHError` when no joint can carry
    the root translation."""
    rows = np.asarray(rows)
    all_q, all_p = bvh.local_rotations(), bvh.channel_positions()
    file_q, pos = all_q[rows], all_p[rows]
    if not folded:
        file_q[:] = q
        pos[:, 0] = root
        return bvh.with_motion(file_q, pos)
    n_top = len(bvh.channels[0])
    if top_from is None:
        top_from = (rows, rows, np.zeros(len(rows)))
    before, after, w = (np.asarray(a) for a in top_from)
    raw = np.where((w >= 1)[:, None], bvh.motion[after, :n_top], bvh.motion[before, :n_top])
    is_raw = (w <= 0) | (w >= 1) | np.all(bvh.motion[before, :n_top] == bvh.motion[after, :n_top], axis=1)
    all_q, all_p = all_q[:, 0], all_p[:, 0]
    top_p, top_q = interpolate_pose(all_p[before], all_q[before][:, None], all_p[after], all_q[after][:, None], w)
    top_q = top_q[:, 0]
    top_q[is_raw] = np.where((w >= 1)[is_raw, None], all_q[after[is_raw]], all_q[before[is_raw]])
    top_p[is_raw] = np.where((w >= 1)[is_raw, None], all_p[after[is_raw]], all_p[before[is_raw]])
    file_q[:, 0], pos[:, 0] = top_q, top_p
    file_q[:, 1] = qmul(qinv(top_q), q[:, 0])
    file_q[:, 2:] = q[:, 1:]
    top_cols = np.arange(n_top)
    if sum(c.lower().endswith("position") for c in bvh.channels[1]) == 3:
        pos[:, 1] = qrot(qinv(top_q), root - top_p)
    elif sum(c.lower().endswith("position") for c in bvh.channels[0]) == 3:
        pos[:, 0] = root - qrot(top_q, bvh.offsets[1][None])  # the top joint carries the translation
        top_cols = np.array([i for i, c in enumerate(bvh.channels[0]) if not c.lower().endswith("position")], int)
    else:
        raise BVHError(f"neither {bvh.names[0]} nor {bvh.names[1]} has 3 position channels: "
                       "cannot write the root translation", bvh.source)
    out = bvh.with_motion(file_q, pos)
    out.motion[np.ix_(is_raw, top_cols)] = raw[np.ix_(is_raw, top_cols)]
    return out


def check_skeleton(ref: Skeleton | None, skel: Skeleton, name: str) -> Skeleton:
    """The dataset's skeleton so far (``ref``, ``None`` before the first file) after checking ``skel`` matches it."""
    if ref is None:
        return skel
    if not ref.same_topology(skel):
        raise DatasetError(f"{name}: skeleton differs from the dataset's first file ({skel.names[:3]}... vs {ref.names[:3]}...)")
    return ref


PARALLEL_MIN_FILES = 64  # fewer files are read in this process (starting workers would cost more than it saves)


def read_workers() -> int:
    """Processes the default reader uses: ``$INBETWEENING_WORKERS`` if set, else the CPUs this process may use."""
    env = os.environ.get("INBETWEENING_WORKERS", "").strip()
    if env:
        return max(1, int(env))
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


FOLD_AUTO = "<top joint above the hips>"  # ReadSpec.fold_root: fold the top joint of each file where top_folds says
FOLD_TOP = "<top joint>"  # ReadSpec.fold_root: fold the top joint of every file


def top_is_static(bvh: BVH, tol: float = 1e-6) -> bool:
    """Whether the file's top joint has exactly one child and channels that hold one value over every frame."""
    if [j for j, p in enumerate(bvh.parents) if p == 0] != [1]:
        return False
    top = bvh.motion[:, : len(bvh.channels[0])]
    return bool(top.size == 0 or np.all(np.ptp(top, axis=0) <= tol * np.maximum(1.0, np.abs(top).max(axis=0))))


def top_folds(bvh: BVH, tol: float = 1e-6) -> bool:
    """Whether the file's top joint is a wrapper to fold into its child (:data:`FOLD_AUTO`): it has exactly one child
    and either holds still (:func:`top_is_static`: an exporter's ``Armature``, a still ``joint_Root``) or sits above
    a hips-like root, a child where the body branches (two or more children: the legs and the spine), moving or not
    (a ``joint_Root`` or a game rig's ``root`` that carries the locomotion in some takes).  Folding composes the top
    joint into the child frame by frame, losslessly either way, so every take gets the child-rooted skeleton."""
    if [j for j, p in enumerate(bvh.parents) if p == 0] != [1]:
        return False
    return sum(int(p) == 1 for p in bvh.parents) >= 2 or top_is_static(bvh, tol)


def _clip_of(spec: ReadSpec, fname: str, raw: bytes) -> tuple[str, Clip, Skeleton, float | None]:
    bvh = parse_bvh(raw, source=fname)
    stem = fname.rsplit(".", 1)[0]
    top = spec.fold_root
    if top == FOLD_AUTO:
        top = bvh.names[0] if top_folds(bvh) else None
    elif top == FOLD_TOP:
        top = bvh.names[0]
    clip, skel = fold_static_root(bvh, stem, top) if top else clip_from_bvh(bvh, stem)
    return fname, clip, skel, 1.0 / bvh.frame_time


_WORKER_SPEC: ReadSpec | None = None


def _init_worker(spec: ReadSpec) -> None:
    global _WORKER_SPEC
    _WORKER_SPEC = spec


def _read_part(path: str, files: list[tuple[str, str]]) -> list[tuple[str, Clip, Skeleton, float | None]]:
    return [_clip_of(_WORKER_SPEC, name, raw) for name, raw in read_bvh_sources(path, files)]


def read_bvh_clips(spec: ReadSpec, path: Path) -> Iterator[tuple[str, Clip, Skeleton, float | None]]:
    """The default reader: ``(file name, clip, skeleton, frames per second)`` per BVH file of ``path``.

    Files are those matching ``spec.pattern``, sorted by name; a file no split rule of the spec uses is
    skipped before it is parsed.  The clip is named after the file without its extension.  With many files and
    more than one CPU (:func:`read_workers`), contiguous runs of files are inflated and parsed by a standard
    library process pool (forked workers) and the clips come back in the same order.
    """
    files = [(name, key) for name, key in list_bvh_sources(path, spec.pattern) if spec.reads(name)]
    workers = min(read_workers(), len(files) // PARALLEL_MIN_FILES)
    if workers < 2 or "fork" not in multiprocessing.get_all_start_methods():
        for name, raw in read_bvh_sources(path, files):
            yield _clip_of(spec, name, raw)
        return
    step = -(-len(files) // (4 * workers))  # a few parts per worker: the pool balances uneven files
    parts = [files[i : i + step] for i in range(0, len(files), step)]
    ctx = multiprocessing.get_context("fork")  # workers inherit the spec (its rules need not be picklable)
    with ProcessPoolExecutor(workers, mp_context=ctx, initializer=_init_worker, initargs=(spec,)) as pool:
        for part in pool.map(_read_part, [str(path)] * len(parts), parts):
            yield from part
