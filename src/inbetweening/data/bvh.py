"""BVH motion files: the :class:`BVH` data class and a fast, strict reader.

``parse_bvh`` reads the (small) HIERARCHY with a plain line loop (:mod:`inbetweening.data.bvh_header`) and
the (large) MOTION block vectorised (:mod:`inbetweening.data.bvh_motion`): token boundaries, per-line value
counts and the decimal-to-float conversion are numpy operations over the raw bytes, never a Python loop
over frames, and give the correctly rounded double, identical to ``float(token)``.

Malformed input raises one :class:`BVHError` whose message starts with ``"<file>:<line>: "``.  The
vectorised path only *detects* a problem; a slow line-by-line pass then finds the first offending line
(error path only).

Conventions: ``names``/``parents``/``offsets`` list joints in file order (End Sites are not joints);
``motion`` is ``(F, C)`` with the raw channel values in file order; rotations are returned as ``wxyz``
quaternions built from each joint's own Euler channel order (see :mod:`inbetweening.geometry.quaternion`).
Folder/zip discovery lives in :mod:`inbetweening.data.sources`, writing in :mod:`inbetweening.data.bvh_writer`.
"""

from __future__ import annotations

import functools
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inbetweening.data.bvh_header import CHANNELS, MOTION_RE, parse_header, parse_motion_header, raise_motion_error
from inbetweening.data.bvh_motion import motion_values
from inbetweening.data.errors import BVHError
from inbetweening.data.sources import iter_bvh_sources
from inbetweening.geometry.quaternion import euler_to_quat_np, quat_to_euler_np, remove_discontinuities
from inbetweening.geometry.skeleton import Skeleton

__all__ = [
    "BVH",
    "BVHError",
    "iter_bvh_sources",
    "parse_bvh",
    "read_bvh",
    "read_bvh_many",
]

_AXIS_NAMES = "xyz"


# --------------------------------------------------------------------------------------------
# The data class
# --------------------------------------------------------------------------------------------
@dataclass(eq=False)
class BVH:
    """One BVH file: hierarchy (J joints) and raw motion ``(F, C)``."""

    names: list[str]
    parents: np.ndarray
    offsets: np.ndarray
    channels: list[tuple[str, ...]]
    end_sites: dict[int, np.ndarray]
    frame_time: float
    motion: np.ndarray
    source: str = "<memory>"

    def __post_init__(self):
        self.names = [str(n) for n in self.names]
        self.parents = np.asarray(self.parents, dtype=np.int64).reshape(-1)
        self.offsets = np.asarray(self.offsets, dtype=np.float64).reshape(-1, 3)
        self.channels = [tuple(map(str, ch)) for ch in self.channels]
        self.end_sites = {int(j): np.asarray(o, dtype=np.float64).reshape(3) for j, o in self.end_sites.items()}
        self.frame_time = float(self.frame_time)
        self.motion = np.asarray(self.motion, dtype=np.float64)
        n = len(self.names)
        if not (len(self.parents) == len(self.offsets) == len(self.channels) == n) or n == 0:
            raise BVHError(
                f"inconsistent hierarchy: {n} names, {len(self.parents)} parents, "
                f"{len(self.offsets)} offsets, {len(self.channels)} channel lists",
                self.source,
            )
        if self.parents[0] != -1 or any(not 0 <= p < j for j, p in enumerate(self.parents[1:].tolist(), 1)):
            raise BVHError("parents must be -1 for joint 0 and point to earlier joints otherwise", self.source)
        try:
            _channel_layout(tuple(self.channels))
        except BVHError as err:
            raise BVHError(err.reason, self.source) from None
        c = sum(len(ch) for ch in self.channels)
        if self.motion.ndim != 2 or self.motion.shape[1] != c:
            raise BVHError(f"motion has shape {self.motion.shape}, expected (frames, {c})", self.source)

    @property
    def _layout(self) -> tuple:
        return _channel_layout(tuple(self.channels))

    @property
    def num_frames(self) -> int:
        return int(self.motion.shape[0])

    @property
    def num_joints(self) -> int:
        return len(self.names)

    def rotation_order(self, j: int) -> str:
        """Axes of joint ``j``'s rotation channels in file order, e.g. ``"zxy"``; ``""`` if it has none."""
        return "".join(_AXIS_NAMES[axis] for _, axis in self._layout[j][1])

    def local_rotations(self) -> np.ndarray:
        """Local joint rotations ``(F, J, 4)`` wxyz, sign-continuous along time.

        Each joint's Euler channels (degrees) are composed in the joint's own channel order
        (``q_A ⊗ q_B ⊗ q_C``); joints without rotation channels get the identity.
        """
        f, j = self.num_frames, self.num_joints
        q = np.zeros((f, j, 4))
        q[..., 0] = 1.0
        for order, joints, cols in _rotation_groups(self._layout):
            q[:, joints] = euler_to_quat_np(self.motion[:, cols], order)
        return remove_discontinuities(q, axis=0)

    def channel_positions(self) -> np.ndarray:
        """``(F, J, 3)``: each joint's X/Y/Zposition channels where present, its OFFSET component elsewhere."""
        out = np.repeat(self.offsets[None], self.num_frames, axis=0)
        joints, axes, cols = _position_index(self._layout)
        out[:, joints, axes] = self.motion[:, cols]
        return out

    def local_positions(self) -> np.ndarray:
        """``(F, J, 3)`` LAFAN1 convention: the root from its position channels (offset where it has none),
        every other joint its OFFSET.

        Bandai-Namco files have a static ``joint_Root`` above ``Hips`` and carry the body translation in the
        ``Hips`` position channels: use :meth:`channel_positions` (or drop ``joint_Root``) there.
        """
        out = np.repeat(self.offsets[None], self.num_frames, axis=0)
        joints, axes, cols = _position_index(self._layout[:1])
        out[:, joints, axes] = self.motion[:, cols]
        return out

    def skeleton(self) -> Skeleton:
        return Skeleton(tuple(self.names), tuple(self.parents.tolist()), self.offsets.copy())

    def with_motion(self, local_q: np.ndarray, positions: np.ndarray, frame_time: float | None = None) -> BVH:
        """A new BVH with this hierarchy/channels: motion from ``local_q (F, J, 4)`` wxyz and ``positions (F, J, 3)``.

        Rotations become Euler angles (degrees) in each joint's own channel order; positions go into the
        joints' position channels (components without a channel are dropped).  A joint with fewer than
        three rotation channels gets the leading angles of the decomposition in its order completed with
        the missing axes (exact when the rotation only uses those axes).
        """
        local_q = np.asarray(local_q, dtype=np.float64)
        positions = np.asarray(positions, dtype=np.float64)
        j = self.num_joints
        if local_q.ndim != 3 or local_q.shape[1:] != (j, 4):
            raise ValueError(f"with_motion: local_q must be (F, {j}, 4), got {local_q.shape}")
        if positions.shape != (*local_q.shape[:2], 3):
            raise ValueError(f"with_motion: positions must be {(*local_q.shape[:2], 3)}, got {positions.shape}")
        motion = np.zeros((local_q.shape[0], self.motion.shape[1]))
        for order, joints, cols in _rotation_groups(self._layout):
            full = order + "".join(a for a in _AXIS_NAMES if a not in order)
            motion[:, cols] = quat_to_euler_np(local_q[:, joints], full)[..., : len(order)]
        pj, pa, pc = _position_index(self._layout)
        motion[:, pc] = positions[:, pj, pa]
        return BVH(
            names=list(self.names),
            parents=self.parents.copy(),
            offsets=self.offsets.copy(),
            channels=list(self.channels),
            end_sites={k: v.copy() for k, v in self.end_sites.items()},
            frame_time=self.frame_time if frame_time is None else frame_time,
            motion=motion,
            source=self.source,
        )


@functools.lru_cache(maxsize=256)
def _channel_layout(channels: tuple[tuple[str, ...], ...]) -> tuple:
    """Per joint ``(positions, rotations)``, each a tuple of ``(column, axis)`` in file order (cached)."""
    layout, col = [], 0
    for ch in channels:
        pos, rot = [], []
        for name in ch:
            kind = CHANNELS.get(name.lower())
            if kind is None:
                raise BVHError(f"unknown channel name {name!r}")
            (pos if kind[0] == "p" else rot).append((col, kind[1]))
            col += 1
        layout.append((tuple(pos), tuple(rot)))
    return tuple(layout)


def _rotation_groups(layout: tuple) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """Joints grouped by rotation order: ``[(order, joints (G,), columns (G, len(order)))]``."""
    groups: dict[str, tuple[list, list]] = {}
    for j, (_, rot) in enumerate(layout):
        if rot:
            order = "".join(_AXIS_NAMES[a] for _, a in rot)
            g = groups.setdefault(order, ([], []))
            g[0].append(j)
            g[1].append([c for c, _ in rot])
    return [(o, np.array(js), np.array(cs, dtype=np.int64)) for o, (js, cs) in groups.items()]


def _position_index(layout: tuple) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(joints, axes, columns)`` of every position channel, each ``(P,)`` int64."""
    rows = [(j, a, c) for j, (pos, _) in enumerate(layout) for c, a in pos]
    table = np.array(rows, dtype=np.int64).reshape(-1, 3)
    return table[:, 0], table[:, 1], table[:, 2]


# --------------------------------------------------------------------------------------------
# Reading
# --------------------------------------------------------------------------------------------
def parse_bvh(data: bytes | str, source: str = "<memory>") -> BVH:
    """Parse BVH text (bytes or str).  ``source`` names the file in error messages."""
    if isinstance(data, str):
        data = data.encode("utf-8")
    data = bytes(data)
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    if not data or data.isspace():
        raise BVHError("empty file", source, 1)
    if b"\n" not in data and b"\r" in data:  # old Mac line endings
        data = data.replace(b"\r", b"\n")
    m = MOTION_RE.search(data)
    head_end = m.start() if m else len(data)
    motion_line = data.count(b"\n", 0, head_end) + 1 if m else data.count(b"\n", 0, len(data.rstrip())) + 1
    try:
        names, parents, offsets, channels, end_sites = parse_header(data[:head_end], motion_line)
    except BVHError as err:
        raise BVHError(err.reason, source, err.line) from None
    if m is None:
        raise BVHError("missing MOTION section", source, motion_line)
    frames, frame_time, start, first_line = parse_motion_header(data, head_end, motion_line, source)
    block = data[start:]
    if b"#" in block:  # comments in the motion data: blank them, keeping the line numbers
        block = re.sub(rb"#[^\n]*", b"", block)
    width = sum(len(ch) for ch in channels)
    motion = motion_values(block, frames, width)
    if motion is None:
        raise_motion_error(block, frames, width, first_line, source)
    return BVH(
        names=list(names),
        parents=np.array(parents, dtype=np.int64),
        offsets=offsets.copy(),
        channels=list(channels),
        end_sites={j: off.copy() for j, off in end_sites},
        frame_time=frame_time,
        motion=motion,
        source=source,
    )


def read_bvh(path: str | os.PathLike) -> BVH:
    """Read a ``.bvh`` file from disk (errors name the file)."""
    path = Path(path)
    return parse_bvh(path.read_bytes(), source=path.name)


def read_bvh_many(path: str | os.PathLike, pattern: str = "*.bvh") -> list[BVH]:
    """Parse every BVH of a folder or zip file (see :func:`iter_bvh_sources`), sorted by file name."""
    return [parse_bvh(data, source=name) for name, data in iter_bvh_sources(path, pattern)]
