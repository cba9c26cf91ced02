"""Scores of a retargeted motion (``task=retarget``), per clip, accumulated over a test set (:class:`RetargetScore`).

All lengths are divided by the body height of the character they belong to (:func:`~inbetweening.data.contacts.
body_height`: the median vertical extent of its joints), so figures of characters of different size and unit compare:

- ``pos_err``: the mean joint position error against the reference motion (the analytic retarget, the training
  target), in % of the target's body height (the normalised error of the deep-retargeting literature);
- ``pose_err``: the mean error of the mapped joints' positions relative to the hips against the source's, each in its
  own body heights, in % (how closely the target's pose follows the source's, with no reference needed);
- ``bone_err``: the mean absolute error of the bone lengths against the target rig's, in % of body height;
- ``jerk``: the mean magnitude of the third time derivative of the joint positions, body heights per s^3;
- ``skate``: the mean horizontal speed of the target's foot joints at the frames the source's foot is planted
  (the project's contact rule, :func:`~inbetweening.data.contacts.planted_frames`), in % of body height per second.
"""
from __future__ import annotations

from collections import defaultdict

import numpy as np

from inbetweening.data.contacts import FootContact, planted_frames
from inbetweening.evaluation.keyframes import foot_skate

__all__ = ["METRICS", "RetargetScore", "jerk", "source_scores"]

METRICS = ("pos_err", "pose_err", "bone_err", "jerk", "skate")


def jerk(gp: np.ndarray, fps: float) -> tuple[float, int]:
    """Sum and count of ``|d^3 p / dt^3|`` over frames and joints of positions ``(F, J, 3)``."""
    if len(gp) < 4:
        return 0.0, 0
    j = np.linalg.norm(np.diff(gp, n=3, axis=0), axis=-1) * fps**3
    return float(j.sum()), int(j.size)


class RetargetScore:
    """Accumulates the scores of one method over clips.  ``bones``/``bone_parents``/``bone_lengths``: the target's
    rigid bones (child, parent, length in the source's units); ``slots``: ``(target joint, source joint)`` pairs;
    ``hips``: ``(target, source)`` hips; ``feet``: ``(target feet, source feet)``; ``heights``: ``(target, source)``
    body heights; ``contact``: the source's foot-contact rule."""

    def __init__(self, bones, bone_parents, bone_lengths, slots, hips, feet, heights, contact: FootContact, fps: float):
        self.bones, self.bone_parents, self.bone_lengths = np.asarray(bones), np.asarray(bone_parents), bone_lengths
        self.slots = np.asarray(slots, dtype=np.int64).reshape(-1, 2)
        self.hips, self.feet, self.contact, self.fps = hips, feet, contact, float(fps)
        self.h_t, self.h_s = heights
        self.sums: dict[str, float] = defaultdict(float)
        self.counts: dict[str, int] = defaultdict(int)

    def _add(self, key: str, total: float, n: int) -> None:
        self.sums[key] += total
        self.counts[key] += n

    def add(self, gp: np.ndarray, ref_gp: np.ndarray | None, src_gp: np.ndarray) -> None:
        """One clip: the method's target positions ``gp (F, J, 3)``, the reference's (None: no ``pos_err``) and the
        source's ``(F, Js, 3)``, all in the source's world and units (Y up)."""
        h = self.h_t
        if ref_gp is not None:
            e = np.linalg.norm(gp - ref_gp, axis=-1) / h
            self._add("pos_err", 100 * float(e.sum()), e.size)
        t, s = self.slots[:, 0], self.slots[:, 1]
        rel_t = (gp[:, t] - gp[:, self.hips[0], None]) / h
        rel_s = (src_gp[:, s] - src_gp[:, self.hips[1], None]) / self.h_s
        e = np.linalg.norm(rel_t - rel_s, axis=-1)
        self._add("pose_err", 100 * float(e.sum()), e.size)
        self.add_bones(gp, "bone_err")
        self._add("jerk", *(v / h if i == 0 else v for i, v in enumerate(jerk(gp, self.fps))))
        c = self.contact
        planted = planted_frames(src_gp[:, self.feet[1]], self.fps, c.height, c.speed)[:-1]
        total, n = foot_skate(gp[:, self.feet[0]], planted, self.fps)
        self._add("skate", 100 * total / h, n)

    def add_bones(self, gp: np.ndarray, key: str) -> None:
        """The bone-length error of positions ``gp (F, J, 3)`` under ``key``."""
        length = np.linalg.norm(gp[:, self.bones] - gp[:, self.bone_parents], axis=-1)
        e = np.abs(length - self.bone_lengths[None]) / self.h_t
        self._add(key, 100 * float(e.sum()), e.size)

    def result(self) -> dict[str, float]:
        return {k: self.sums[k] / self.counts[k] for k in self.sums if self.counts[k]}


def source_scores(positions, feet, height: float, contact: FootContact, fps: float) -> dict[str, float]:
    """``jerk`` and ``skate`` of the source motions themselves (global positions ``(F, Js, 3)`` per clip, the feet at
    their own planted frames), in the source's body heights: what a retargeter inherits."""
    sums, counts = [0.0, 0.0], [0, 0]
    for gp in positions:
        total, n = jerk(gp, fps)
        sums[0], counts[0] = sums[0] + total / height, counts[0] + n
        planted = planted_frames(gp[:, feet], fps, contact.height, contact.speed)[:-1]
        total, n = foot_skate(gp[:, feet], planted, fps)
        sums[1], counts[1] = sums[1] + 100 * total / height, counts[1] + n
    return {k: s / n for k, s, n in zip(("jerk", "skate"), sums, counts) if n}
