"""Feet and the foot-contact rule of a dataset: one owner for "where is a foot planted".

A :class:`FootContact` names a skeleton's foot joints and two thresholds in the project's frame (Y up, cm): a foot
joint is *in contact* over a frame pair when its mean height is below ``height`` and its speed below ``speed``
(cm/s).  The keyframes protocol scores foot skating on the ground truth's contacts (:mod:`inbetweening.evaluation.
keyframes`), and the training loss's foot term uses the same joints and speed limit.

The built-in datasets state theirs (:data:`~inbetweening.data.specs.CONTACT`, chosen on Bandai-Namco-2); a BVH
folder (``data=bvh``) gets its feet from the joint names (:func:`find_feet`) and thresholds scaled with the
skeleton's height (:func:`scaled_contact`), so a child-sized rig or a giant gets the same rule relative to its body.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from inbetweening.data.errors import DatasetError
from inbetweening.data.mirror import side_of

__all__ = ["CONTACT_HEIGHT_CM", "CONTACT_SPEED_CM_S", "CONTACT_THRESHOLD", "FOOT_WORDS", "FootContact", "REFERENCE_HEIGHT_CM",
           "body_height", "find_feet", "foot_contacts", "planted_frames", "scaled_contact"]

UP = 1  # Y up (the project's frame)

# The built-in rule, chosen on Bandai-Namco-2 (see inbetweening.data.specs.CONTACT), and the body height it was
# chosen on: BN-2's median vertical extent of the joints (body_height of its training clips, every 10th clip and
# 5th frame: 133.9 cm; toes to the head joint, so less than the actors' stature).
CONTACT_HEIGHT_CM, CONTACT_SPEED_CM_S = 15.0, 30.0
REFERENCE_HEIGHT_CM = 133.9
FOOT_WORDS = ("foot", "toe", "ankle", "ball", "heel")
CONTACT_THRESHOLD = 0.5
"""Predicted contact above which a foot counts as planted (a model's contact channel is in [0, 1]; the foot
lock of the tools and the training figures read it the same way)."""


@dataclass(frozen=True)
class FootContact:
    """Foot joint names and the contact thresholds (cm above the floor at y = 0, cm/s); no feet: no contacts."""

    feet: tuple[str, ...] = ()
    height: float = 0.0
    speed: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "feet", tuple(str(f) for f in self.feet))
        object.__setattr__(self, "height", float(self.height))
        object.__setattr__(self, "speed", float(self.speed))
        if self.feet and not (self.height > 0 and self.speed > 0):
            raise ValueError(f"foot contact: feet need a height and a speed > 0, got {self.height!r} and {self.speed!r}")

    def indices(self, names: Sequence[str], where: str = "dataset") -> tuple[int, ...]:
        """The foot joints' indices in ``names``; :class:`DatasetError` naming the missing ones."""
        missing = [f for f in self.feet if f not in names]
        if missing:
            raise DatasetError(f"{where}: foot joint(s) {missing} are not in the skeleton ({len(names)} joints)")
        return tuple(list(names).index(f) for f in self.feet)

    def to_dict(self) -> dict:
        return {"feet": list(self.feet), "height": self.height, "speed": self.speed}

    @classmethod
    def from_dict(cls, d: dict | None) -> FootContact:
        return cls(**(d or {}))


def foot_contacts(feet_gp: np.ndarray, fps: float, contact_height: float, contact_speed: float) -> np.ndarray:
    """Contact per frame pair and foot joint.  ``feet_gp (F, K, 3) -> (F-1, K)`` bool.

    Pair ``(t, t+1)`` is in contact when the joint's mean height over the two frames is below ``contact_height``
    and its speed ``|p[t+1] - p[t]| * fps`` is below ``contact_speed`` (length units per second).
    """
    step = np.diff(feet_gp, axis=0)
    height = 0.5 * (feet_gp[1:, :, UP] + feet_gp[:-1, :, UP])
    speed = np.linalg.norm(step, axis=-1) * fps
    return (height < contact_height) & (speed < contact_speed)


def planted_frames(feet_gp: np.ndarray, fps: float, contact_height: float, contact_speed: float) -> np.ndarray:
    """Contact per frame and foot joint, the rule of :func:`foot_contacts` on single frames (the contact channels of
    ``global_pos_local_quat_contact`` are these labels): ``feet_gp (..., F, K, 3) -> (..., F, K)`` bool, frame ``t``
    planted when its height is below ``contact_height`` and its speed to the next frame (where that is unknown: from
    the previous one) below ``contact_speed``; a frame with no known neighbour is judged on its height alone, an
    unknown (NaN) frame is not planted."""
    feet_gp = np.asarray(feet_gp, dtype=np.float64)
    step = np.linalg.norm(np.diff(feet_gp, axis=-3), axis=-1) * fps  # (..., F-1, K)
    pad = np.full_like(step[..., :1, :], np.nan)
    fwd, bwd = np.concatenate([step, pad], axis=-2), np.concatenate([pad, step], axis=-2)
    speed = np.where(np.isnan(fwd), bwd, fwd)
    with np.errstate(invalid="ignore"):
        return (feet_gp[..., UP] < contact_height) & ((speed < contact_speed) | np.isnan(speed))


def body_height(positions: Sequence[np.ndarray], up: int = UP) -> float:
    """Median over frames of the joints' extent along axis ``up``: global positions ``(F, J, 3)`` per clip."""
    ext = np.concatenate([np.ptp(np.asarray(p)[..., up], axis=-1).reshape(-1) for p in positions])
    return float(np.median(ext)) if ext.size else 0.0


def scaled_contact(feet: Sequence[str], height_cm: float) -> FootContact:
    """The built-in contact rule scaled from Bandai-Namco-2's body height to ``height_cm``."""
    k = float(height_cm) / REFERENCE_HEIGHT_CM
    return FootContact(tuple(feet), CONTACT_HEIGHT_CM * k, CONTACT_SPEED_CM_S * k)


def _branch(j: int, parents: Sequence[int], n_children: np.ndarray) -> int:
    """The first joint above ``j`` (or ``j``) whose parent branches: the top of ``j``'s limb."""
    while parents[j] >= 0 and n_children[parents[j]] == 1:
        j = parents[j]
    return j


def find_feet(names: Sequence[str], parents: Sequence[int], heights: np.ndarray) -> tuple[tuple[str, ...], str]:
    """``(foot joint names, how they were found)``.

    Joints whose name holds a foot word (:data:`FOOT_WORDS`) and a side marker (``Left``/``Right``, ``_L``/``_R``,
    ...) when both sides have one; otherwise, per leg, the lowest leaf joint (by median height ``heights (J,)``, Y up)
    of the two lowest limbs, with its parent when that is not where the limb starts.
    """
    named = [n for n in names if any(w in n.lower() for w in FOOT_WORDS) and side_of(n) is not None]
    if {side_of(n) for n in named} == {"left", "right"}:
        return tuple(named), "joint names"
    parents = list(parents)
    n_children = np.bincount([p for p in parents if p >= 0], minlength=len(names))
    leaves = [j for j in range(len(names)) if n_children[j] == 0 and parents[j] >= 0]
    feet: list[int] = []
    limbs: list[int] = []
    for j in sorted(leaves, key=lambda j: heights[j]):
        limb = _branch(j, parents, n_children)
        if limb in limbs:
            continue
        limbs.append(limb)
        feet += [parents[j], j] if parents[j] != limb and j != limb else [j]
        if len(limbs) == 2:
            break
    return tuple(names[j] for j in sorted(feet)), "the lowest leaf joint of each of the two lowest limbs"
