"""The project's frame for motion data, and a file's way from its own frame into it and back.

Everything after loading works in one frame: **Y up, lengths in centimetres** (the frame of LAFAN1, Bandai-Namco
and the synthetic data, which need no conversion).  A BVH folder of another rig (``data=bvh``) may be Z-up and in
metres, millimetres or inches: :class:`FileConvention` records its up axis and length unit; :meth:`~FileConvention.
to_project` turns a clip read from such a file into the project's frame (a rotation of the whole motion about X and
a scale: the root's rotation and position, and the bone offsets), :meth:`~FileConvention.to_file` turns a clip
back (what ``predict`` writes into the user's file).  The convention is recorded in the checkpoint.

Joint-local rotations below the root are unchanged by both: the up-axis change is a rotation of the world, and a
uniform scale does not touch rotations.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from inbetweening.geometry.quaternion import qinv, qmul, qrot

__all__ = ["FileConvention", "PROJECT", "UNITS", "UP_AXES", "parse_unit"]

# centimetres per unit of the length units a file may use (data.unit=<name>, or a number of centimetres per unit)
UNITS = {"mm": 0.1, "cm": 1.0, "inch": 2.54, "m": 100.0}
UP_AXES = ("y", "z")
# file -> project rotation per up axis (wxyz): Z up is turned to Y up by -90 degrees about X: (x, y, z) -> (x, z, -y)
_TO_Y_UP = {"y": np.array([1.0, 0.0, 0.0, 0.0]),
            "z": np.array([math.cos(-math.pi / 4), math.sin(-math.pi / 4), 0.0, 0.0])}


def parse_unit(unit) -> tuple[str, float]:
    """``(name, centimetres per unit)`` of ``data.unit``: a name of :data:`UNITS` or a positive number of
    centimetres per unit; ``ValueError`` naming the choices otherwise."""
    if isinstance(unit, str) and unit.strip().lower() in UNITS:
        name = unit.strip().lower()
        return name, UNITS[name]
    try:
        value = float(unit)
    except (TypeError, ValueError):
        value = float("nan")
    if not value > 0 or not math.isfinite(value):
        raise ValueError(f"data.unit must be one of {list(UNITS)} or a positive number of centimetres per unit, "
                         f"got {unit!r}")
    name = next((n for n, v in UNITS.items() if v == value), f"{value:g} cm")
    return name, value


@dataclass(frozen=True)
class FileConvention:
    """A file's up axis (``"y"`` or ``"z"``) and length unit (``unit_cm`` centimetres per file unit)."""

    up_axis: str = "y"
    unit_cm: float = 1.0

    def __post_init__(self):
        if self.up_axis not in UP_AXES:
            raise ValueError(f"data.up_axis must be one of {list(UP_AXES)}, got {self.up_axis!r}")
        if not (float(self.unit_cm) > 0 and math.isfinite(float(self.unit_cm))):
            raise ValueError(f"unit_cm must be a positive number, got {self.unit_cm!r}")
        object.__setattr__(self, "unit_cm", float(self.unit_cm))

    @property
    def is_project(self) -> bool:
        """Whether files of this convention are already in the project's frame (nothing to convert)."""
        return self.up_axis == "y" and self.unit_cm == 1.0

    @property
    def rotation(self) -> np.ndarray:
        """The file -> project rotation (wxyz)."""
        return _TO_Y_UP[self.up_axis]

    def to_project(self, root: np.ndarray, local_q: np.ndarray, offsets: np.ndarray | None = None):
        """``root (F, 3), local_q (F, J, 4)`` (and bone ``offsets (J, 3)``) of a file -> the same motion in the
        project's frame: ``(root, local_q)`` or ``(root, local_q, offsets)``; new arrays."""
        r = self.rotation
        root = self.unit_cm * qrot(np.broadcast_to(r, root.shape[:-1] + (4,)), np.asarray(root, dtype=np.float64))
        q = np.array(local_q, dtype=np.float64)
        q[..., 0, :] = qmul(np.broadcast_to(r, q[..., 0, :].shape), q[..., 0, :])
        if offsets is None:
            return root, q
        return root, q, self.unit_cm * np.asarray(offsets, dtype=np.float64)

    def to_file(self, root: np.ndarray, local_q: np.ndarray):
        """The inverse of :meth:`to_project` for a motion: ``root (F, 3), local_q (F, J, 4)`` in the project's frame
        -> in the file's; new arrays."""
        inv = qinv(self.rotation)
        root = qrot(np.broadcast_to(inv, root.shape[:-1] + (4,)), np.asarray(root, dtype=np.float64)) / self.unit_cm
        q = np.array(local_q, dtype=np.float64)
        q[..., 0, :] = qmul(np.broadcast_to(inv, q[..., 0, :].shape), q[..., 0, :])
        return root, q

    def to_dict(self) -> dict:
        return {"up_axis": self.up_axis, "unit_cm": self.unit_cm}

    @classmethod
    def from_dict(cls, d: dict | None) -> FileConvention:
        return cls(**(d or {}))


PROJECT = FileConvention()  # the project's own frame: what every built-in dataset's files already are
