"""The rig interface: what the DCC core needs of a host application (Blender, Maya, a game engine's editor).

A front end implements two objects for the rig the animator fills:

- :class:`Curves`: the rig's animation as the host stores it.  A *channel* is one animated value, named
  ``(path, index)`` the way the host names it (Blender: ``('pose.bones["Hips"].rotation_euler', 0)``; Maya:
  ``("Hips.rotateX", 0)``).  Per channel the host gives its keys (frame, value, whether the fill generated the key,
  whether it is selected), evaluates it between keys, marks keys as the animator's or the fill's, and writes the
  fill's keys; it also keeps the core's record of the last fill with the animation (saved with the scene, restored by
  undo: :mod:`.record`).
- :class:`Rig`: the rig's poses.  Which channels' keys are the animator's keys, the pose read at frames, the channels
  the fill writes and their values for a pose.  A rig of the model's own skeleton subclasses :class:`Rig` (its poses
  are the model's ``root (F, 3)``, ``local_q (F, J, 4)``); any other humanoid subclasses
  :class:`~.mapped.MappedRig` (the bone map and retargeting are the core's; its poses are the rig's own local
  rotations and translations in the BVH convention).

Everything else (which frames are keys, partial keys, hand edits, the re-fill plan, the fill itself) is the core's
(:func:`~.fill.fill_action`).  Errors that the animator can fix are :class:`RigError` (one line; raised before
anything is changed).
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from typing import NamedTuple

import numpy as np

__all__ = ["Channel", "Curves", "Keys", "Rig", "RigError", "WriteChannel"]

Channel = tuple[str, int]  # (path, index): one animated value, named as the host names it
WriteChannel = tuple[int, str, int]  # (joint, path, index): a channel the fill writes, of the joint whose pose sets it


class RigError(ValueError):
    """The rig cannot be filled as it is (no keys, no gap, a limb in IK, ...); the message says why, in one line."""


class Keys(NamedTuple):
    """One channel's keys, in the host's order: ``frames`` and ``values`` as stored (float32 in Blender; a frame may be
    a sub-frame), ``generated``: whether the fill wrote the key (the host's tag of it: Blender's key type *Generated*),
    ``selected``: whether the animator selected it (bool arrays)."""

    frames: np.ndarray
    values: np.ndarray
    generated: np.ndarray
    selected: np.ndarray


class Curves(ABC):
    """The animation of one rig as the host stores it (Blender: the action's F-curves)."""

    @abstractmethod
    def keys(self, channel: Channel) -> Keys | None:
        """The channel's keys, ``None`` when the channel has no curve."""

    @abstractmethod
    def evaluate(self, channel: Channel, frames: Sequence[int]) -> np.ndarray:
        """``(F,)`` float64: the channel's value at ``frames`` as the host plays it (its current value without a
        curve)."""

    @abstractmethod
    def bone(self, channel: Channel) -> str:
        """The bone the channel animates (the animator's keys are counted per bone: partial keys)."""

    @abstractmethod
    def set_generated(self, channel: Channel, indices: Sequence[int], generated: bool) -> None:
        """Tag the keys at ``indices`` (into :meth:`keys`) as the fill's (``True``) or the animator's (``False``)."""

    @abstractmethod
    def add(self, channel: Channel, frame: int) -> None:
        """Create the channel's curve with one key of the animator at ``frame`` holding its current value."""

    @abstractmethod
    def write(self, channel: Channel, frames: np.ndarray, values: np.ndarray, spans: Sequence[Sequence[int]]) -> None:
        """Key ``values`` at ``frames`` (tagged as the fill's); the fill's keys strictly inside ``spans``
        ``[[lo, hi], ...]`` are replaced, every other key is kept as it is, and the curve outside the spans keeps its
        shape (Blender: the handles at the span ends are frozen)."""

    @abstractmethod
    def load_record(self) -> Mapping | None:
        """The record the core stored last (:meth:`store_record`), ``None`` when there is none."""

    @abstractmethod
    def store_record(self, entry: dict) -> None:
        """Keep ``entry`` with the animation (a JSON string under ``"meta"`` and numpy arrays), replacing the last."""


class Rig(ABC):
    """A rig the core fills: its poses and the channels the fill writes.  This base class is a rig of the model's own
    skeleton (its joints the model's, by name: the fill runs on its poses directly, :meth:`fill`);
    :class:`~.mapped.MappedRig` is any other humanoid.

    Attributes a front end sets: ``curves`` (:class:`Curves`), ``where`` (how messages name the rig: ``"armature
    'Armature'"``), ``whole_keys_only`` (every key frame is a whole key: no partial keys; a rig whose pose is solved
    frame by frame)."""

    curves: Curves
    where: str = "the rig"
    whole_keys_only: bool = False
    retargeted: bool = False  # filled through the bone map (MappedRig)

    @property
    @abstractmethod
    def joint_names(self) -> list[str]:
        """The joints of the poses :meth:`read` returns, by the names :meth:`Curves.bone` gives their channels."""

    @abstractmethod
    def key_channels(self) -> list[Channel]:
        """The channels whose keys are the animator's keys (a frame is a key where one of them holds one)."""

    @abstractmethod
    def read(self, frames: Sequence[int]) -> tuple[np.ndarray, np.ndarray, list]:
        """The pose at ``frames``: the model's ``root (F, 3)`` and ``local_q (F, J, 4)`` (a :class:`MappedRig`: the
        rig's ``local_q (F, J, 4)`` and ``local_p (F, J, 3)``), and per frame the host's raw channel values (handed
        back to :meth:`basis_values` for the frame before each run of generated frames: Euler angles and quaternion
        signs continue from there)."""

    @abstractmethod
    def channels(self) -> list[WriteChannel]:
        """The channels the fill writes (after :meth:`plan`)."""

    @abstractmethod
    def basis_values(self, frames: Sequence[int], a: np.ndarray, b: np.ndarray, raw_prev: dict) -> dict:
        """``{(joint, path, index): values over frames}`` of :meth:`channels`: the channel values that pose the rig as
        ``a``, ``b`` (:meth:`read`'s arrays) at ``frames``; ``raw_prev``: ``{frame: raw values}`` of :meth:`read`."""

    def plan(self, reference: np.ndarray, poses: np.ndarray, translations: np.ndarray):
        """Prepare the fill from the pose at the keys (``reference``: :meth:`read`'s first array at the first key;
        ``poses``, ``translations``: both arrays at every key).  The model's own skeleton needs nothing."""
        return None

    def fill(self, runtime, a: np.ndarray, b: np.ndarray, keys: list[int], **kw):
        """Run the fill runtime on :meth:`read`'s arrays (``kw``: :meth:`FillRuntime.fill`'s): ``(the runtime's
        :class:`~inbetweening.runtime.fill.Filled`, the filled a, b, the generated key gaps)``."""
        filled = runtime.fill(a, b, keys, **kw)
        return filled, filled.root, filled.local_q, filled.generated

    def check(self, first: int, last: int) -> None:
        """Raise :class:`RigError` when the rig cannot be filled between frames ``first`` and ``last``."""
        return None

    def settings_parts(self) -> list:
        """More of what a change of re-fills every gap (bytes or arrays: the curves that place the model's root on
        every frame, say)."""
        return []

    def summary(self) -> dict:
        """What the rig adds to the fill's summary."""
        return {}
