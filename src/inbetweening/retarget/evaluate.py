"""Scoring of ``task=retarget`` on held-out clips (:func:`score_sets`): the learned retargeter, the analytic one (its
training target) and copying local rotations by slot, with the figures of :mod:`.metrics` and the time
per frame; the table (:func:`format_table`) and the side-by-side figure
(:func:`clip_figure`)."""
from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from inbetweening.data.clips import Clip
from inbetweening.data.contacts import body_height

from .figure import retarget_figure
from .learned import LearnedRetarget
from .metrics import METRICS, RetargetScore, source_scores
from .rig import TargetRig

__all__ = ["METHODS", "clip_figure", "format_table", "score_sets"]

METHODS = ("learned", "analytic", "copy")


def _timed(fn, *args):
    t0 = time.perf_counter()
    out = fn(*args)
    return out, time.perf_counter() - t0


def score_clips(learned: LearnedRetarget, rig: TargetRig, clips: Sequence[Clip], contact, fps: float) -> dict:
    """``{method: {metric: value}, "n_clips", "n_frames"}`` over ``clips`` (module docstring)."""
    src = rig.source
    runs = {m: [] for m in METHODS}
    seconds = dict.fromkeys(METHODS, 0.0)
    heads, src_gp = [], []
    for c in clips:
        (a_q, a_p), dt = _timed(rig.analytic, c.root_pos, c.local_q)
        seconds["analytic"] += dt
        (c_q, c_p), dt = _timed(rig.copy_by_slot, c.root_pos, c.local_q)
        seconds["copy"] += dt
        (l_q, l_p, head), dt = _timed(learned, c.root_pos, c.local_q)
        seconds["learned"] += dt
        runs["analytic"].append(rig.positions(a_q, a_p))
        runs["copy"].append(rig.positions(c_q, c_p))
        runs["learned"].append(rig.positions(l_q, l_p))
        heads.append(head)
        src_gp.append(src.pose(c.root_pos, c.local_q)[1])
    heights = (body_height(runs["analytic"]), body_height(src_gp))
    frames = int(sum(c.num_frames for c in clips))
    out: dict = {"n_clips": len(clips), "n_frames": frames, "heights": list(heights),
                 "source": source_scores(src_gp, rig.source_feet, heights[1], contact, fps)}
    slots = [(b, src.names.index(s)) for s, b in rig.slots.items()]
    for m in METHODS:
        score = RetargetScore(rig.bones, rig.bone_parents, rig.bone_lengths, slots,
                              (rig.hips, src.names.index("Hips")), (rig.feet, rig.source_feet), heights, contact, fps)
        for gp, ref, s in zip(runs[m], runs["analytic"], src_gp):
            score.add(gp, ref, s)
        if m == "learned":
            for head in heads:
                score.add_bones(head, "bone_err_head")
        out[m] = {**score.result(), "ms_per_frame": 1000.0 * seconds[m] / max(frames, 1)}
    return out


def score_sets(learned: LearnedRetarget, sets: dict[str, Sequence[Clip]], contact, fps: float) -> dict:
    """:func:`score_clips` per named set of clips."""
    return {name: score_clips(learned, learned.rig, clips, contact, fps) for name, clips in sets.items()}


def format_table(results: dict) -> str:
    """A Markdown table: one row per set and method."""
    cols = [*METRICS, "bone_err_head", "ms_per_frame"]
    lines = ["| clips | method | " + " | ".join(cols) + " |", "|---|---|" + "---:|" * len(cols)]
    for name, res in results.items():
        for m in METHODS:
            row = res[m]
            cells = [f"{row[c]:.3f}" if c in row else "-" for c in cols]
            lines.append(f"| {name} ({res['n_clips']}) | {m} | " + " | ".join(cells) + " |")
        src = res.get("source", {})
        lines.append(f"| {name} ({res['n_clips']}) | (source) | " + " | ".join(
            f"{src[c]:.3f}" if c in src else "-" for c in cols) + " |")
    return "\n".join(lines)


def clip_figure(learned: LearnedRetarget, clip: Clip, n: int = 6):
    """Source, analytic and learned target of ``clip`` side by side (:func:`retarget_figure`)."""
    rig = learned.rig
    a_q, a_p = rig.analytic(clip.root_pos, clip.local_q)
    l_q, l_p, _ = learned(clip.root_pos, clip.local_q)
    src = rig.source.pose(clip.root_pos, clip.local_q)[1]
    frames = list(np.linspace(0, min(clip.num_frames, 90) - 1, n).astype(int))
    top, j = set(), rig.skeleton.parents[rig.hips]
    while j >= 0:  # bones above the hips (a static armature root at the origin) are not drawn
        top.add(j)
        j = rig.skeleton.parents[j]
    parents = [-1 if p in top else p for p in rig.skeleton.parents]
    rows = [("source", src, rig.source.parents), ("analytic", rig.positions(a_q, a_p), parents),
            ("learned", rig.positions(l_q, l_p), parents)]
    return retarget_figure(rows, frames, title=f"{clip.name}: source ({rig.source.num_joints} joints) and target "
                                               f"({rig.skeleton.num_joints} joints)")
