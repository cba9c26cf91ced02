"""Training takes of other rigs (``data.extra``): every clip of a folder or zip of BVH files of any humanoid skeleton,
moved onto the dataset's skeleton by the fill's own retargeter (:class:`~inbetweening.runtime.retarget.Retarget`, the
road a user's rig takes at fill time) and resampled to the dataset's frame rate, added to the training clips.

Each file gets its own bone map (:func:`~inbetweening.runtime.bone_map.detect_bone_map`) and its own natural pose,
hinges, up and floor from its own frames (as a user's keys give them).  A first frame that is a T-pose (a jump of more
than :data:`TPOSE_JUMP` degrees on some bone into frame 1, as Character Creator's and many mocap exports start) is
left out.  The result is cached next to the dataset's cache (``cache_dir/other_rigs``), keyed by the files' bytes, the
skeleton and the frame rate.  A file whose rig cannot be mapped is one :class:`DatasetError` line naming it.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from inbetweening.data.bvh import parse_bvh
from inbetweening.data.bvh_folder import resample_clip
from inbetweening.data.cache import default_cache_dir, hash_source, settings_key
from inbetweening.data.clips import Clip
from inbetweening.data.errors import BVHError, DatasetError
from inbetweening.data.sources import list_bvh_sources, read_bvh_sources
from inbetweening.geometry.quaternion import qangle
from inbetweening.geometry.skeleton import Skeleton

__all__ = ["TPOSE_JUMP", "other_rig_clips", "retarget_take"]

TPOSE_JUMP = 30.0  # degrees: a first frame this far from the second on some bone is a rest pose, not motion
POSES = 200  # frames (evenly spaced) a take's natural pose and hinges are found from
VERSION = 1  # of the cached clips: bump when the retargeting of training takes changes


def retarget_take(bvh, skeleton: Skeleton, fps: float, name: str) -> Clip:
    """One take (a parsed :class:`~inbetweening.data.bvh.BVH` of any humanoid rig) as a :class:`Clip` of ``skeleton``
    at ``fps`` frames per second, in the project's frame (Y up, the model's lengths, its floor)."""
    from inbetweening.runtime.bone_map import detect_bone_map
    from inbetweening.runtime.retarget import Retarget

    lq, lp = bvh.local_rotations(), bvh.channel_positions()
    if len(lq) > 2 and np.degrees(qangle(lq[0], lq[1])).max() > TPOSE_JUMP:
        lq, lp = lq[1:], lp[1:]
    where = f"data.extra: {name}"
    bm = detect_bone_map(bvh.names, bvh.parents, bvh.offsets, where=where)
    pick = np.unique(np.linspace(0, len(lq) - 1, min(POSES, len(lq))).round().astype(int))
    rt = Retarget(bvh.skeleton(), skeleton, bm, reference=lq[0], where=where, poses=lq[pick], ends=bvh.end_sites,
                  translations=lp[pick])
    root, q = rt.to_model(lq, lp)
    clip = Clip(name, q, root)
    rate = 1.0 / bvh.frame_time if bvh.frame_time > 0 else fps
    return clip if abs(rate - fps) <= 0.01 * fps else resample_clip(clip, rate, fps)


def other_rig_clips(paths, skeleton: Skeleton, fps: float, cache_dir: str | Path | None = None) -> list[Clip]:
    """The clips of every BVH file under ``paths`` (folders, zips or files; a string or a list) moved onto
    ``skeleton`` at ``fps`` (:func:`retarget_take`), cached; names are ``<source stem>/<file stem>``."""
    from inbetweening.runtime.bone_map import SLOTS

    paths = [paths] if isinstance(paths, (str, Path)) else list(paths or [])
    if paths and not set(skeleton.names) <= set(SLOTS):
        raise DatasetError(f"data.extra: other rigs are moved onto a skeleton of the humanoid slots (Bandai-Namco-2's, "
                           f"data=bandai_namco); this dataset's joints are {list(skeleton.names)[:4]}...")
    root = (Path(cache_dir) if cache_dir else default_cache_dir()) / "other_rigs"
    out: list[Clip] = []
    for p in paths:
        p = Path(p)
        if not p.exists():
            raise DatasetError(f"data.extra: {str(p)!r} does not exist (a folder, a zip or a BVH file of another rig)")
        key = settings_key({"v": VERSION, "src": hash_source(p, root, "*.bvh"), "fps": round(float(fps), 6),
                            "names": list(skeleton.names), "offsets": np.round(skeleton.offsets, 6).tolist()})
        entry = root / f"{p.stem}-{key}.npz"
        if entry.exists():
            with np.load(entry) as z:
                meta = json.loads(str(z["meta"]))
                out += [Clip(n, z[f"q{i}"], z[f"r{i}"]) for i, n in enumerate(meta)]
            continue
        clips = []
        for fname, raw in read_bvh_sources(p, list_bvh_sources(p)):
            try:
                bvh = parse_bvh(raw, source=fname)
            except BVHError as e:
                raise DatasetError(f"data.extra: {p / fname}: {e}") from None
            try:
                clips.append(retarget_take(bvh, skeleton, fps, f"{p.stem}/{Path(fname).stem}"))
            except ValueError as e:  # the bone map's or the retargeter's one line, which names the file
                raise DatasetError(str(e)) from None
        entry.parent.mkdir(parents=True, exist_ok=True)
        tmp = entry.with_suffix(f".{os.getpid()}.tmp.npz")  # parallel jobs of a sweep may build it at once
        np.savez(tmp, meta=json.dumps([c.name for c in clips]),
                 **{f"q{i}": c.local_q for i, c in enumerate(clips)}, **{f"r{i}": c.root_pos for i, c in enumerate(clips)})
        tmp.replace(entry)
        out += clips
    return out
