"""Any folder of BVH files as a dataset (``data=bvh data.path=<folder | zip | list of them>``): nothing to write.

:func:`derive_spec` reads every file once and derives what a :class:`~inbetweening.data.specs.DatasetSpec` holds,
each with a ``data.<key>`` override (``None`` = derive):

* **skeleton**: every file must have the same hierarchy (:class:`DatasetError` naming the first file that differs
  and how); a top joint with one child is folded into it by composition (``fold_root``: ``None`` = detect, ``True``
  = always, ``False`` = never), as Bandai-Namco's ``joint_Root``: detected per file where it holds still or sits
  above a hips-like child (one where the body branches), moving or not, so a folder whose top joint carries the
  locomotion in some takes (a dash) and is still in the others loads as one child-rooted skeleton
  (:func:`~inbetweening.data.clips.top_folds`);
* **frame rate** (``fps``): the most common rate; files at another rate are resampled to it through the project's
  one interpolation (:func:`~inbetweening.geometry.interp.interpolate_pose`), never silently mixed;
* **up axis** (``up_axis``: ``y`` | ``z``): the axis along which the joints spread most (median over frames);
* **length unit** (``unit``: ``mm`` | ``cm`` | ``inch`` | ``m`` | centimetres per unit): the unit that makes the
  body's median height closest to Bandai-Namco-2's (:data:`~inbetweening.data.contacts.REFERENCE_HEIGHT_CM`);
  the clips are then converted to the project's frame (Y up, cm; :mod:`inbetweening.data.convention`);
* **forward axis** of the root (``forward_axis``): measured from the direction of travel, in the root's local
  frame, over the clips that travel (at least one second faster than a fifth of the body height per second),
  snapped to the nearest axis; :class:`DatasetError` asking for ``data.forward_axis=`` when nothing travels;
* **feet** (``feet``) and the **contact rule** (``contact_height``, ``contact_speed``, cm and cm/s): foot joints
  from the names (:func:`~inbetweening.data.contacts.find_feet`), thresholds scaled with the body height;
* **mirror map** (``mirror_map``): the name-based derivation of :mod:`inbetweening.data.mirror`;
* **split**: a file is a test file when a stable hash of its name is 0 modulo 10 (every 10th file; the file of the
  smallest hash when none is), or when it matches ``test_pattern`` (a glob or a list of globs on the file name);
  validation is held out of the training files as for every dataset.

The result is printed once and recorded in the prepared data (``MotionData.derived``, saved as ``dataset.yaml``
next to a training run).
"""
from __future__ import annotations

import fnmatch
import hashlib
import math
import os
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from inbetweening.data.bvh import parse_bvh
from inbetweening.data.clips import FOLD_AUTO, FOLD_TOP, Clip, read_bvh_clips
from inbetweening.data.contacts import REFERENCE_HEIGHT_CM, FootContact, body_height, find_feet, scaled_contact
from inbetweening.data.convention import UNITS, FileConvention, parse_unit
from inbetweening.data.errors import BVHError, DatasetError
from inbetweening.data.mirror import derive_mirror, validate_mirror
from inbetweening.data.sources import list_bvh_sources, read_bvh_sources
from inbetweening.data.specs import DatasetSpec
from inbetweening.geometry.interp import interpolate_pose
from inbetweening.geometry.quaternion import qinv, qrot
from inbetweening.geometry.skeleton import Skeleton

__all__ = ["BVH_DATASET", "DERIVATION", "FolderOptions", "derive_spec", "hash_split", "pattern_split", "resample_clip",
           "source_paths"]

BVH_DATASET = "bvh"
DERIVATION = 2  # in the prepared-data cache key: 2: a moving top joint above a hips-like root folds too
TEST_EVERY = 10  # the hash split's share of test files: one in TEST_EVERY
TRAVEL_SPEED = 0.2  # a clip travels where its root moves faster than this many body heights per second ...
TRAVEL_SECONDS = 1.0  # ... for at least this long
POSE_EVERY = 5  # frames sampled for the up axis, the unit and the feet


@dataclass(frozen=True)
class FolderOptions:
    """The ``data.<key>`` overrides of the derived spec (``None``: derive it from the files)."""

    up_axis: str | None = None
    unit: str | float | None = None
    forward_axis: Sequence[float] | None = None
    fps: float | None = None
    feet: Sequence[str] | None = None
    fold_root: bool | None = None
    test_pattern: str | Sequence[str] | None = None
    mirror_map: Sequence[Sequence[str]] | None = None
    contact_height: float | None = None
    contact_speed: float | None = None

    def settings(self) -> dict:
        """Plain values (the prepared-data cache key)."""
        def plain(v):
            if isinstance(v, (list, tuple)):
                return [plain(x) for x in v]
            return v
        return {k: plain(v) for k, v in asdict(self).items()}

    def given(self) -> list[str]:
        return [k for k, v in asdict(self).items() if v is not None]


def source_paths(path) -> list[Path]:
    """``data.path`` of ``data=bvh`` as a list of existing paths (a folder, a zip or a file, or a list of them)."""
    if path is None or (isinstance(path, str) and not path.strip()):
        raise DatasetError("data.path is not set: data=bvh needs data.path=<folder | zip | [list, of, them]>")
    items = [path] if isinstance(path, (str, os.PathLike)) else list(path)
    if not items:
        raise DatasetError("data.path is an empty list: data=bvh needs at least one folder, zip or BVH file")
    out = []
    for p in items:
        q = Path(str(p)).expanduser()
        if not q.exists():
            where = "" if q.is_absolute() else f" (relative to the working directory {Path.cwd()})"
            raise DatasetError(f"data.path: {q} does not exist{where}")
        out.append(q)
    return out


def _stable_hash(name: str) -> int:
    return int.from_bytes(hashlib.sha1(name.lower().encode()).digest()[:8], "big")


def hash_split(names: Sequence[str]):
    """The default split rule over these file names: test when the name's stable hash is 0 modulo
    :data:`TEST_EVERY`; when that picks none (a small folder), the name of the smallest hash."""
    test = {n for n in names if _stable_hash(n) % TEST_EVERY == 0}
    if not test and len(names) >= 2:
        test = {min(names, key=_stable_hash)}

    def rule(fname: str):
        return "test" if fname in test else "train"
    return rule


def pattern_split(patterns: str | Sequence[str]):
    """Test when the file name matches one of the globs (case-insensitively), train otherwise."""
    pats = [patterns] if isinstance(patterns, str) else [str(p) for p in patterns]

    def rule(fname: str):
        return "test" if any(fnmatch.fnmatch(fname.lower(), p.lower()) for p in pats) else "train"
    return rule


@dataclass(frozen=True)
class _ReadSpec:
    """What :func:`~inbetweening.data.clips.read_bvh_clips` needs: every ``*.bvh``, folding as asked."""

    fold_root: str | None
    pattern: str = "*.bvh"

    def reads(self, name: str) -> bool:
        return True


def _read(paths: list[Path], fold) -> list[tuple[str, Clip, Skeleton, float]]:
    spec = _ReadSpec(FOLD_AUTO if fold is None else FOLD_TOP if fold else None)
    items, seen = [], {}
    for p in paths:
        try:
            for fname, clip, skel, rate in read_bvh_clips(spec, p):
                if fname in seen:
                    raise DatasetError(f"data.path: two files are called {fname} ({seen[fname]} and {p}); file names "
                                       "name the clips and decide the split, so they must differ")
                seen[fname] = p
                items.append((fname, clip, skel, float(rate)))
        except BVHError as e:
            if e.line is None and e.reason.startswith("no "):
                raise DatasetError(f"data.path: {p} holds no BVH file (*.bvh)") from None
            raise
    return items


def _check_skeletons(items, auto_fold: bool) -> Skeleton:
    """The first file's skeleton, after checking every other file has its hierarchy (names and parents)."""
    f0, _, ref, _ = items[0]
    for fname, _, sk, _ in items[1:]:
        if sk.same_topology(ref):
            continue
        a, b = list(sk.names), list(ref.names)
        if auto_fold and (a[1:] == b or b[1:] == a):  # folded in one file, not in the other (top_folds)
            moving, still = (fname, f0) if len(a) > len(b) else (f0, fname)
            top, child = max(a, b, key=len)[:2]
            raise DatasetError(f"{fname}: mixed skeletons: the top joint {top!r} moves in {moving} and its child "
                               f"{child!r} is not where the body branches, so it is not folded there, but it is in "
                               f"{still}; set data.fold_root=true (fold it everywhere) or false (never)")
        if len(a) != len(b):
            how = f"{len(a)} joints, {f0} has {len(b)}"
        else:
            i = next((i for i in range(len(a)) if a[i] != b[i] or sk.parents[i] != ref.parents[i]), 0)
            if a[i] != b[i]:
                how = f"joint {i} is {a[i]!r}, in {f0} it is {b[i]!r}"
            else:
                pa = lambda s, j: s.names[s.parents[j]] if s.parents[j] >= 0 else None  # noqa: E731
                how = f"joint {a[i]!r} has parent {pa(sk, i)!r}, in {f0} {pa(ref, i)!r}"
        raise DatasetError(f"{fname}: mixed skeletons: not the hierarchy of the folder's first file ({how}); "
                           "data=bvh trains on one skeleton")
    return ref


def resample_clip(clip: Clip, rate: float, fps: float) -> Clip:
    """``clip`` at ``rate`` fps played at ``fps``: frames at times ``k / fps`` by root lerp and per-joint slerp."""
    n = int(math.floor((clip.num_frames - 1) * fps / rate + 1e-9)) + 1
    t = np.arange(n) * rate / fps
    i0 = np.minimum(np.floor(t).astype(int), clip.num_frames - 1)
    i1 = np.minimum(i0 + 1, clip.num_frames - 1)
    w = t - i0
    root, q = interpolate_pose(clip.root_pos[i0], clip.local_q[i0], clip.root_pos[i1], clip.local_q[i1], w)
    return Clip(clip.name, q, root)


def _positions(skeleton: Skeleton, clips: Iterable[Clip]) -> list[np.ndarray]:
    return [skeleton.pose(c.root_pos[::POSE_EVERY], c.local_q[::POSE_EVERY])[1] for c in clips]


def _forward_axis(clips: list[Clip], fps: float, height: float) -> tuple[tuple[float, float, float], dict]:
    """The root's local axis that points where the clips travel (module docstring), and how it was measured."""
    step = max(1, round(fps / 6))  # travel over a sixth of a second
    total = np.zeros(3)
    used = 0
    for c in clips:
        if c.num_frames <= step:
            continue
        v = c.root_pos[step:] - c.root_pos[:-step]
        v[:, 1] = 0.0
        dist = np.linalg.norm(v, axis=-1)
        moving = dist * fps / step > TRAVEL_SPEED * height
        if moving.sum() < TRAVEL_SECONDS * fps:
            continue
        d = v[moving] / dist[moving, None]
        local = qrot(qinv(c.local_q[:-step][moving, 0]), d)
        total += local.mean(axis=0)
        used += 1
    if used == 0:
        raise DatasetError(f"data.forward_axis: no clip travels (root faster than {TRAVEL_SPEED:g} body heights/s for "
                           f"{TRAVEL_SECONDS:g} s) to measure the root's forward axis from; set data.forward_axis=[x,y,z] "
                           "(the root's forward direction in its own frame)")
    mean = total / used
    k = int(np.argmax(np.abs(mean)))
    axis = [0.0, 0.0, 0.0]
    axis[k] = 1.0 if mean[k] > 0 else -1.0
    return tuple(axis), {"clips_travelling": used, "agreement": round(float(abs(mean[k])), 3),
                         "measured_mean_direction": [round(float(x), 3) for x in mean]}


def derive_spec(paths: list[Path], options: FolderOptions) -> tuple[DatasetSpec, dict]:
    """Read the BVH files of ``paths`` and derive their dataset spec (module docstring): ``(spec, report)``; the
    spec's reader yields the clips read here, converted to the project's frame and rate."""
    o = options
    items = _read(paths, o.fold_root)
    if len(items) < 2:
        raise DatasetError(f"data.path: {len(items)} BVH file(s) in {[str(p) for p in paths]}: a split needs at least "
                           "two (one to train on, one to test)")
    skel_file = _check_skeletons(items, o.fold_root is None)
    folded = _folded_top(paths[0], skel_file)
    rates = Counter(round(r, 2) for *_, r in items)
    fps = float(o.fps) if o.fps is not None else max(rates, key=lambda r: (rates[r], r))
    if not fps > 0:
        raise DatasetError(f"data.fps must be positive, got {o.fps!r}")
    clips = [(f, c if abs(r - fps) <= 0.01 * fps else resample_clip(c, r, fps)) for f, c, _, r in items]
    resampled = sum(abs(r - fps) > 0.01 * fps for *_, r in items)

    # up axis and unit, measured in the file's frame
    raw_pos = _positions(skel_file, (c for _, c in clips))
    extent = {a: body_height(raw_pos, up=i) for a, i in (("y", 1), ("z", 2))}
    up = o.up_axis if o.up_axis is not None else max(extent, key=extent.get)
    height_file = extent.get(str(up), 0.0)
    if o.unit is not None:
        unit_name, unit_cm = parse_unit(o.unit)
    else:
        if not height_file > 0:
            raise DatasetError("data.unit: the joints have no vertical extent to measure the length unit from; set "
                               f"data.unit= (one of {list(UNITS)} or centimetres per unit)")
        unit_name = min(UNITS, key=lambda u: abs(math.log(height_file * UNITS[u] / REFERENCE_HEIGHT_CM)))
        unit_cm = UNITS[unit_name]
    try:
        conv = FileConvention(str(up), unit_cm)
    except ValueError as e:
        raise DatasetError(str(e)) from None

    # the clips in the project's frame (Y up, cm)
    converted = []
    for f, c in clips:
        root, q, offsets = conv.to_project(c.root_pos, c.local_q, skel_file.offsets)
        converted.append((f, Clip(c.name, q, root)))
    skel = Skeleton(skel_file.names, skel_file.parents, offsets)
    pos = _positions(skel, (c for _, c in converted))
    height_cm = body_height(pos)

    if o.forward_axis is not None:
        forward = tuple(float(a) for a in o.forward_axis)
        fwd_report = {"given": True}
    else:
        forward, fwd_report = _forward_axis([c for _, c in converted], fps, height_cm)

    median_h = np.median(np.concatenate([p[..., 1].reshape(-1, len(skel.names)) for p in pos]), axis=0)
    if o.feet is not None:
        feet, how_feet = tuple(str(f) for f in o.feet), "given"
    else:
        feet, how_feet = find_feet(skel.names, skel.parents, median_h)
    contact = scaled_contact(feet, height_cm)
    contact = FootContact(feet, o.contact_height if o.contact_height is not None else contact.height,
                          o.contact_speed if o.contact_speed is not None else contact.speed)
    contact.indices(skel.names, "data.feet")
    mirror = tuple(tuple(p) for p in o.mirror_map) if o.mirror_map is not None else derive_mirror(skel.names)
    mirror = validate_mirror(mirror, skel.names, "data.mirror_map")

    names = [f for f, _ in converted]
    if o.test_pattern is not None:
        rule, how_split = pattern_split(o.test_pattern), f"test = file names matching {o.test_pattern!r}"
    else:
        rule, how_split = hash_split(names), f"test = every {TEST_EVERY}th file by a stable hash of its name"
    n_test = sum(rule(f) == "test" for f in names)
    if n_test == 0:
        raise DatasetError(f"data.test_pattern: {o.test_pattern!r} matches none of the {len(names)} files")
    if n_test == len(names):
        raise DatasetError(f"data.test_pattern: {o.test_pattern!r} matches every file: nothing left to train on")

    out = [(f, c, skel, fps) for f, c in converted]
    spec = DatasetSpec(
        BVH_DATASET, rule, forward, fps=fps, mirror=mirror, reader=lambda spec, path: iter(out),
        feet=contact.feet, contact_height=contact.height, contact_speed=contact.speed,
    )
    report = {
        "sources": [str(p) for p in paths],
        "files": len(names), "train_files": len(names) - n_test, "test_files": n_test,
        "split": how_split,
        "skeleton": {"joints": len(skel.names), "root": skel.names[0], "folded_top_joint": folded or None},
        "fps": fps, "file_rates": {f"{r:g}": n for r, n in sorted(rates.items())}, "resampled_files": resampled,
        "up_axis": conv.up_axis, "extent_y": round(extent["y"], 4), "extent_z": round(extent["z"], 4),
        "unit": unit_name, "unit_cm": conv.unit_cm, "body_height_cm": round(height_cm, 2),
        "forward_axis": list(forward), "forward_measure": fwd_report,
        "feet": list(contact.feet), "feet_from": how_feet,
        "contact_height_cm": round(contact.height, 3), "contact_speed_cm_s": round(contact.speed, 3),
        "overrides": {k: v for k, v in o.settings().items() if v is not None},
    }
    return spec, report


def _folded_top(path: Path, skeleton: Skeleton) -> str | None:
    """The top joint the reader folded into ``skeleton``'s root (the first file's header says), or ``None``."""
    name, raw = next(read_bvh_sources(path, list_bvh_sources(path, "*.bvh")[:1]))
    names = parse_bvh(raw, source=name).names
    return names[0] if tuple(names[1:]) == skeleton.names else None
