"""BVH motion files: a fast, strict reader and a standard writer.

``parse_bvh`` reads the (small) HIERARCHY with a plain line loop and the (large) MOTION block
vectorised: token boundaries, per-line value counts and the decimal-to-float conversion are all
numpy operations over the raw bytes, never a Python loop over frames.  Plain decimals (``-12.345678``,
up to 15 significant digits, the format every common exporter writes) are converted by an exact
SWAR digit parser; anything else (exponents, longer mantissas) goes through numpy's ``strtod`` path.
Both give the correctly rounded double, identical to ``float(token)``.

Malformed input raises one :class:`BVHError` whose message starts with ``"<file>:<line>: "``.  The
vectorised path only *detects* a problem; a slow line-by-line pass then finds the first offending line
(error path only).

Conventions: ``names``/``parents``/``offsets`` list joints in file order (End Sites are not joints);
``motion`` is ``(F, C)`` with the raw channel values in file order; rotations are returned as ``wxyz``
quaternions built from each joint's own Euler channel order (see :mod:`inbetweening.geometry.quaternion`).
"""

from __future__ import annotations

import fnmatch
import functools
import math
import os
import re
import zipfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inbetweening.geometry.quaternion import euler_to_quat_np, quat_to_euler_np, remove_discontinuities
from inbetweening.geometry.skeleton import Skeleton

__all__ = [
    "BVH",
    "BVHError",
    "format_bvh",
    "iter_bvh_sources",
    "parse_bvh",
    "read_bvh",
    "read_bvh_many",
    "write_bvh",
]

_CHANNELS = {
    "xposition": ("p", 0),
    "yposition": ("p", 1),
    "zposition": ("p", 2),
    "xrotation": ("r", 0),
    "yrotation": ("r", 1),
    "zrotation": ("r", 2),
}
_AXIS_NAMES = "xyz"


class BVHError(ValueError):
    """A malformed BVH file.

    ``str(err)`` is ``"<source>:<line>: <reason>"`` (``"<source>: <reason>"`` when no line applies).
    """

    def __init__(self, reason: str, source: str = "<memory>", line: int | None = None):
        self.reason, self.source, self.line = reason, source, line
        where = f"{source}:{line}" if line is not None else source
        super().__init__(f"{where}: {reason}")


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
            kind = _CHANNELS.get(name.lower())
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
# Reading: the hierarchy (a small line loop)
# --------------------------------------------------------------------------------------------
_MOTION_RE = re.compile(rb"^[ \t]*MOTION\b", re.MULTILINE | re.IGNORECASE)
_END_SITE = -2


def _header_lines(text: str, first_line: int = 1) -> Iterator[tuple[int, list[str]]]:
    """``(line number, tokens)`` for each non-blank line, comments (``#`` to end of line) removed."""
    for i, line in enumerate(text.split("\n"), first_line):
        if "#" in line:
            line = line[: line.index("#")]
        tokens = line.split()
        if tokens:
            yield i, tokens


def _parse_float3(tokens: list[str], source: str, line: int) -> np.ndarray:
    if len(tokens) != 3:
        raise BVHError(f"OFFSET needs 3 values, got {len(tokens)}", source, line)
    try:
        out = np.array([float(t) for t in tokens])
    except ValueError:
        raise BVHError(f"non-numeric OFFSET {' '.join(tokens)!r}", source, line) from None
    if not np.isfinite(out).all():
        raise BVHError(f"non-finite OFFSET {' '.join(tokens)!r}", source, line)
    return out


def _parse_channels(tokens: list[str], source: str, line: int) -> tuple[str, ...]:
    if not tokens or not (tokens[0].isascii() and tokens[0].isdigit()):
        raise BVHError(f"CHANNELS needs a count, got {' '.join(tokens)!r}", source, line)
    count, names = int(tokens[0]), tuple(tokens[1:])
    if count != len(names):
        raise BVHError(f"CHANNELS declares {count} channels but names {len(names)}", source, line)
    for name in names:
        if name.lower() not in _CHANNELS:
            raise BVHError(f"unknown channel name {name!r}", source, line)
    if len({n.lower() for n in names}) != len(names):
        raise BVHError(f"repeated channel in {' '.join(names)!r}", source, line)
    return names


def _parse_hierarchy(text: str, source: str, end_line: int) -> dict:
    """Parse the text before MOTION into names/parents/offsets/channels/end_sites (lists).

    ``end_line`` is the line number reported for problems found at the end (the MOTION line).
    """
    names: list[str] = []
    parents: list[int] = []
    offsets: list[np.ndarray | None] = []
    channels: list[tuple[str, ...]] = []
    end_sites: dict[int, np.ndarray] = {}
    opened: list[tuple[int, int]] = []  # stack of (joint index or _END_SITE, line it was opened on)
    pending: tuple[int, int, str] | None = None  # node waiting for its "{": (index, line, label)
    end_offset: np.ndarray | None = None  # OFFSET of the End Site being read
    state = "start"  # start -> hierarchy (after HIERARCHY) -> root (inside ROOT) -> done (ROOT closed)
    for line, tokens in _header_lines(text):
        key = tokens[0].upper()
        is_node = key in ("ROOT", "JOINT") or (key == "END" and len(tokens) > 1 and tokens[1].upper() == "SITE")
        if state == "start":
            if key != "HIERARCHY" or len(tokens) != 1:
                raise BVHError(f"expected HIERARCHY, got {' '.join(tokens)!r}", source, line)
            state = "hierarchy"
            continue
        if state == "hierarchy" and key != "ROOT":
            raise BVHError(f"expected ROOT, got {' '.join(tokens)!r}", source, line)
        if state == "done" and all(t == "}" for t in tokens):
            raise BVHError("unbalanced braces: '}' without a matching '{'", source, line)
        if state == "done":
            raise BVHError(f"unexpected {' '.join(tokens)!r} after the hierarchy (missing MOTION?)", source, line)
        if pending is not None and key != "{":
            raise BVHError(f"expected '{{' after {pending[2]}, got {' '.join(tokens)!r}", source, line)
        if is_node:
            brace = tokens[-1] == "{"
            args = tokens[1:-1] if brace else tokens[1:]
            parent = opened[-1][0] if opened else -1
            if key == "ROOT" and state != "hierarchy":
                raise BVHError("a second ROOT is not supported", source, line)
            if key != "ROOT" and parent == _END_SITE:
                raise BVHError(f"{' '.join(tokens)!r} inside an End Site", source, line)
            state = "root"
            if key == "END":
                if len(args) != 1:
                    raise BVHError(f"unexpected {' '.join(tokens)!r}", source, line)
                if parent in end_sites:
                    raise BVHError(f"joint {names[parent]!r} has more than one End Site", source, line)
                pending = (_END_SITE, line, "End Site")
            else:
                if not args:
                    raise BVHError(f"{tokens[0]} without a name", source, line)
                names.append(" ".join(args))
                parents.append(parent)
                offsets.append(None)
                channels.append(())
                pending = (len(names) - 1, line, f"{tokens[0]} {names[-1]}")
            if brace:
                opened.append(pending[:2])
                pending = None
        elif all(t == "{" for t in tokens) or all(t == "}" for t in tokens):
            for t in tokens:
                if t == "{":
                    if pending is None:
                        raise BVHError("unbalanced braces: '{' without ROOT/JOINT/End Site", source, line)
                    opened.append(pending[:2])
                    pending = None
                    continue
                if not opened:
                    raise BVHError("unbalanced braces: '}' without a matching '{'", source, line)
                node, _ = opened.pop()
                if node == _END_SITE:
                    if end_offset is None:
                        raise BVHError("End Site without OFFSET", source, line)
                    end_sites[opened[-1][0]] = end_offset
                    end_offset = None
                elif offsets[node] is None:
                    raise BVHError(f"joint {names[node]!r} has no OFFSET", source, line)
                if not opened:
                    state = "done"
        elif key == "OFFSET":
            value = _parse_float3(tokens[1:], source, line)
            node = opened[-1][0]
            if (end_offset if node == _END_SITE else offsets[node]) is not None:
                raise BVHError("repeated OFFSET", source, line)
            if node == _END_SITE:
                end_offset = value
            else:
                offsets[node] = value
        elif key == "CHANNELS":
            node = opened[-1][0]
            if node == _END_SITE:
                raise BVHError("CHANNELS inside an End Site", source, line)
            if channels[node]:
                raise BVHError(f"repeated CHANNELS for joint {names[node]!r}", source, line)
            channels[node] = _parse_channels(tokens[1:], source, line)
        else:
            raise BVHError(f"unexpected {' '.join(tokens)!r} in the hierarchy", source, line)
    if state == "start":
        raise BVHError("missing HIERARCHY", source, end_line)
    if state == "hierarchy":
        raise BVHError("missing ROOT", source, end_line)
    if pending is not None:
        raise BVHError(f"expected '{{' after {pending[2]}", source, pending[1])
    if opened:
        node, opened_at = opened[-1]
        label = "End Site" if node == _END_SITE else repr(names[node])
        raise BVHError(f"unbalanced braces: {label} (declared at line {opened_at}) is never closed", source, end_line)
    return {"names": names, "parents": parents, "offsets": offsets, "channels": channels, "end_sites": end_sites}


@functools.lru_cache(maxsize=64)
def _parse_header_cached(header: bytes, end_line: int) -> tuple:
    """:func:`_parse_hierarchy` of the bytes before MOTION, memoised: clips of one dataset share their header.

    Returns read-only ``(names, parents, offsets (J, 3), channels, ((joint, end site offset (3,)), ...))``;
    errors carry no file name (the caller adds it).
    """
    h = _parse_hierarchy(header.decode("utf-8", "replace"), "", end_line)
    offsets = np.array(h["offsets"], dtype=np.float64).reshape(-1, 3)
    offsets.flags.writeable = False
    for off in h["end_sites"].values():
        off.flags.writeable = False
    return tuple(h["names"]), tuple(h["parents"]), offsets, tuple(h["channels"]), tuple(h["end_sites"].items())


def _parse_motion_header(data: bytes, start: int, line: int, source: str) -> tuple[int, float, int, int]:
    """Parse ``MOTION`` / ``Frames:`` / ``Frame Time:`` from ``data[start:]`` (``start`` at the MOTION line).

    Returns ``(frames, frame_time, offset of the first motion data byte, its line number)``.
    """
    expected = ["MOTION", "Frames:", "Frame Time:"]
    found: list[str] = []
    pos = start
    while len(found) < 3:
        if pos >= len(data):
            raise BVHError(f"missing {expected[len(found)]!r} line", source, line - 1)
        end = data.find(b"\n", pos)
        end = len(data) if end < 0 else end
        text = data[pos:end].decode("utf-8", "replace")
        pos, line = end + 1, line + 1
        if "#" in text:
            text = text[: text.index("#")]
        text = text.strip()
        if not text:
            continue
        want = expected[len(found)]
        if want == "MOTION":
            if text.upper() != "MOTION":
                raise BVHError(f"expected MOTION, got {text!r}", source, line - 1)
            found.append(text)
            continue
        m = re.fullmatch(
            r"Frames\s*:\s*(\S*)" if want == "Frames:" else r"Frame\s+Time\s*:\s*(\S*)", text, re.IGNORECASE
        )
        if m is None:
            raise BVHError(f"expected '{want} <value>', got {text!r}", source, line - 1)
        found.append(m.group(1))
        if want == "Frames:" and not (m.group(1).isascii() and m.group(1).isdigit()):
            raise BVHError(f"invalid frame count {m.group(1)!r} (need an integer >= 0)", source, line - 1)
        if want == "Frame Time:":
            try:
                frame_time = float(m.group(1))
            except ValueError:
                frame_time = math.nan
            if not (math.isfinite(frame_time) and frame_time > 0):
                raise BVHError(f"invalid frame time {m.group(1)!r} (need a number > 0)", source, line - 1)
    return int(found[1]), frame_time, pos, line


# --------------------------------------------------------------------------------------------
# Reading: the motion block (vectorised)
# --------------------------------------------------------------------------------------------
_PAD = 24  # whitespace around the block so 8-byte loads never leave the buffer
_U64 = np.uint64
_POW10 = 10.0 ** np.arange(16)
# digit nibbles of the k highest bytes of a little-endian uint64 (the last k characters of an 8-byte load)
_DIGITS_HIGH = np.array([0x0F0F0F0F0F0F0F0F & ~((1 << (8 * (8 - k))) - 1) for k in range(9)], dtype=_U64)
_POW10_U64 = np.array([10**k for k in range(16)], dtype=_U64)


def _eight_digits(chunk: np.ndarray, keep: np.ndarray | np.uint64) -> np.ndarray:
    """SWAR: 8 ASCII digits per uint64 (little-endian load, first byte most significant) -> their value.

    ``keep`` selects the digit nibbles to use (from ``_DIGITS_HIGH``); other bytes count as ``0``.
    ``(N,) uint64 -> (N,) uint64``, values < 1e8.
    """
    x = chunk & keep
    x = (x * _U64(2561)) >> _U64(8)  # pairs of digits: 10 * d0 + d1 in every other byte
    lo, hi = x & _U64(0x000000FF000000FF), (x >> _U64(16)) & _U64(0x000000FF000000FF)
    return (lo * _U64(0x000F424000000064) + hi * _U64(0x0000271000000001)) >> _U64(32)


def _fast_decimals(
    buf: bytes, a: np.ndarray, ts: np.ndarray, te: np.ndarray, nsigns: int, ndots: int
) -> np.ndarray | None:
    """Convert plain decimal tokens ``[+-]digits[.digits]`` exactly, vectorised.

    ``buf``/``a``: the padded block (bytes / uint8 view) holding only digits, ``+-.`` and whitespace;
    ``ts``/``te``: ``(M,)`` token start/end offsets; ``nsigns``/``ndots``: counts of ``+-`` and ``.`` in ``a``.
    Returns ``(M,)`` float64 equal to ``float(token)``, or ``None`` when a token is not of that form or has
    more than 15 significant digits (or 8 before the point): the caller then uses the general path.

    Each token's digits before and after the point are read as integers with SWAR arithmetic on 8-byte
    loads; the mantissa (< 1e15, exact in float64) divided by the exact power of ten is correctly rounded.
    """
    m = len(ts)
    if m == 0:
        return np.zeros(0)
    first = a[ts]
    negative = first == 45
    signed = negative | (first == 43)
    if np.count_nonzero(signed) != nsigns:
        return None  # a sign inside a token
    pivot = None  # position of each token's point (its end if it has none)
    tok0 = buf[ts[0] : te[0]]
    if ndots == m and b"." in tok0:  # common case: every token has the same number of decimals
        nfrac = len(tok0) - tok0.index(b".") - 1
        guess = te - (nfrac + 1)
        if (a[guess] == 46).all():
            nint = guess - ts - signed
            if nint.min() >= 0:  # each guessed point lies inside its own token
                pivot, ndig = guess, nint + nfrac
    if pivot is None:
        dots = np.flatnonzero(a == 46)
        owner = np.searchsorted(te, dots, side="right")
        if len(owner) > 1 and not (np.diff(owner) > 0).all():
            return None  # two points in one token
        pivot = te.copy()
        pivot[owner] = dots
        nfrac = np.zeros(m, dtype=np.int64)
        nfrac[owner] = te[owner] - dots - 1
        nint = pivot - ts - signed
        ndig = nint + nfrac
    if nint.max() > 8 or ndig.max() > 15 or ndig.min() < 1:
        return None
    max_frac = int(np.max(nfrac))
    if max_frac <= 7:  # one 16-byte load per token: 8 bytes before the point, the point and 7 after it
        v16 = np.ndarray(shape=(len(buf) - 15,), dtype="V16", buffer=buf, strides=(1,))
        words = v16[pivot - 8].view("<u8").reshape(m, 2)
        mantissa = _eight_digits(words[:, 0], _DIGITS_HIGH[nint])
        if max_frac:  # shift the decimals to the top bytes, dropping the point and what follows them
            frac = _eight_digits(words[:, 1] << (_U64(8) * _U64(7 - nfrac)), _DIGITS_HIGH[nfrac])
            mantissa = mantissa * _POW10_U64[nfrac] + frac
    else:  # up to 15 decimals: the first nfrac - 8 and the last 8 from two more 8-byte loads
        u = np.ndarray(shape=(len(buf) - 7,), dtype="<u8", buffer=buf, strides=(1,))
        lo, hi = np.maximum(nfrac - 8, 0), np.minimum(nfrac, 8)
        mantissa = _eight_digits(u[pivot - 8], _DIGITS_HIGH[nint])
        mantissa = mantissa * _POW10_U64[lo] + _eight_digits(u[te - 16], _DIGITS_HIGH[lo])
        mantissa = mantissa * _POW10_U64[hi] + _eight_digits(u[te - 8], _DIGITS_HIGH[hi])
    scale = _POW10[nfrac]
    return mantissa.astype(np.float64) / np.where(negative, -scale, scale)  # one correctly rounded division


def _char_class(a: np.ndarray) -> tuple[str, int, int]:
    """Classify the bytes of a motion block (uint8 ``(N,)``): ``(kind, number of +/- signs, number of points)``.

    ``kind`` is ``"decimal"`` (only digits, ``+-.`` and whitespace), ``"float"`` (also ``eE``) or ``"bad"``.
    """
    nws = np.count_nonzero(a <= 32)
    if np.count_nonzero(a < 9) or np.count_nonzero((a > 13) & (a < 32)):
        return "bad", 0, 0  # control characters
    nsigns = np.count_nonzero(a == 43) + np.count_nonzero(a == 45)
    ndots = np.count_nonzero(a == 46)
    if np.count_nonzero(a < 48) != nws + nsigns + ndots:
        return "bad", 0, 0
    nhigh = np.count_nonzero(a > 57)
    if nhigh == 0:
        return "decimal", nsigns, ndots
    return ("float" if nhigh == np.count_nonzero(a == 101) + np.count_nonzero(a == 69) else "bad"), nsigns, ndots


def _motion_values(block: bytes, frames: int, width: int) -> np.ndarray | None:
    """Vectorised conversion of the MOTION data to ``(frames, width)`` float64.

    Returns ``None`` if anything is wrong (value counts, line counts, non-numeric or non-finite values);
    the caller then locates and reports the problem.
    """
    buf = b" " * _PAD + block + b" " * _PAD
    a = np.frombuffer(buf, dtype=np.uint8)
    kind, nsigns, ndots = _char_class(a)
    if kind == "bad":
        return None
    ws = a <= 32
    edges = np.flatnonzero(ws[1:] != ws[:-1]) + 1
    ts, te = edges[0::2], edges[1::2]
    if width == 0:
        return np.zeros((frames, 0)) if len(ts) == 0 else None
    # values per line, vectorised: tokens before each newline
    before = np.searchsorted(ts, np.flatnonzero(a == 10))
    per_line = np.diff(np.concatenate(([0], before, [len(ts)])))
    nonblank = per_line[per_line != 0]
    if len(nonblank) != frames or (nonblank != width).any():
        return None
    values = _fast_decimals(buf, a, ts, te, nsigns, ndots) if kind == "decimal" else None
    if values is None:
        try:
            values = np.array(block.split(), dtype=np.float64)
        except ValueError:
            return None
        if len(values) != len(ts) or not np.isfinite(values).all():
            return None
    return values.reshape(frames, width)


_NUMBER_RE = re.compile(rb"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")


def _raise_motion_error(block: bytes, frames: int, width: int, first_line: int, source: str) -> None:
    """Error path only: walk the MOTION data line by line and raise a BVHError for the first problem."""
    found = 0
    last = first_line - 1  # last non-blank line
    for i, line in enumerate(block.split(b"\n"), first_line):
        tokens = line.split()
        if not tokens:
            continue
        last = i
        if found == frames:
            raise BVHError(f"more frame lines than 'Frames: {frames}' declares", source, i)
        found += 1
        if len(tokens) != width:
            raise BVHError(f"expected {width} values, got {len(tokens)}", source, i)
        for t in tokens:
            shown = t.decode("utf-8", "replace")
            if _NUMBER_RE.fullmatch(t) is None:
                if shown.lower().lstrip("+-") in ("nan", "inf", "infinity"):
                    raise BVHError(f"non-finite value {shown!r}", source, i)
                raise BVHError(f"non-numeric value {shown!r}", source, i)
            if not math.isfinite(float(t)):
                raise BVHError(f"non-finite value {shown!r}", source, i)
    if found < frames:
        raise BVHError(f"truncated motion: found {found} frame lines, 'Frames:' declares {frames}", source, last + 1)
    raise BVHError("could not parse the motion data", source, first_line)


# --------------------------------------------------------------------------------------------
# Public reading API
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
    m = _MOTION_RE.search(data)
    head_end = m.start() if m else len(data)
    motion_line = data.count(b"\n", 0, head_end) + 1 if m else data.count(b"\n", 0, len(data.rstrip())) + 1
    try:
        names, parents, offsets, channels, end_sites = _parse_header_cached(data[:head_end], motion_line)
    except BVHError as err:
        raise BVHError(err.reason, source, err.line) from None
    if m is None:
        raise BVHError("missing MOTION section", source, motion_line)
    frames, frame_time, start, first_line = _parse_motion_header(data, head_end, motion_line, source)
    block = data[start:]
    if b"#" in block:  # comments in the motion data: blank them, keeping the line numbers
        block = re.sub(rb"#[^\n]*", b"", block)
    width = sum(len(ch) for ch in channels)
    motion = _motion_values(block, frames, width)
    if motion is None:
        _raise_motion_error(block, frames, width, first_line, source)
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


def iter_bvh_sources(path: str | os.PathLike, pattern: str = "*.bvh") -> Iterator[tuple[str, bytes]]:
    """Yield ``(file name without folders, raw bytes)`` for every file matching ``pattern``, sorted by name.

    ``path`` is a folder (searched recursively), a ``.zip`` archive (members are read directly, no
    extraction; ``__MACOSX/`` entries are skipped) or a single file.  ``pattern`` is matched against the
    file name, case-insensitively.  Raises ``FileNotFoundError`` if ``path`` does not exist and
    :class:`BVHError` if it holds no matching file.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"BVH source {str(path)!r} does not exist")
    pat = pattern.lower()
    if path.is_dir():
        files = sorted(
            (p.name, str(p)) for p in path.rglob("*") if fnmatch.fnmatch(p.name.lower(), pat) and p.is_file()
        )
        if not files:
            raise BVHError(f"no files matching {pattern!r} under this folder", str(path))
        for name, full in files:
            yield name, Path(full).read_bytes()
        return
    if zipfile.is_zipfile(path):
        with zipfile.ZipFile(path) as zf:
            members = sorted(
                (info.filename.rsplit("/", 1)[-1], info.filename, info)
                for info in zf.infolist()
                if not info.is_dir()
                and not info.filename.startswith("__MACOSX/")
                and fnmatch.fnmatch(info.filename.rsplit("/", 1)[-1].lower(), pat)
            )
            if not members:
                raise BVHError(f"no members matching {pattern!r} in this zip file", str(path))
            for name, _, info in members:
                yield name, zf.read(info)
        return
    if fnmatch.fnmatch(path.name.lower(), pat):
        yield path.name, path.read_bytes()
        return
    raise BVHError(f"not a folder, a zip file or a file matching {pattern!r}", str(path))


def read_bvh_many(path: str | os.PathLike, pattern: str = "*.bvh") -> list[BVH]:
    """Parse every BVH of a folder or zip file (see :func:`iter_bvh_sources`), sorted by file name."""
    return [parse_bvh(data, source=name) for name, data in iter_bvh_sources(path, pattern)]


# --------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------
def _fmt(x: float, precision: int) -> str:
    return f"{x:.{precision}f}"


def format_bvh(bvh: BVH, precision: int = 6) -> str:
    """Standard BVH text: tab-indented hierarchy, ``"\\n"`` line endings, values with ``precision`` decimals.

    Numbers are written in fixed-point notation (like Blender's exporter), so a read-back value differs
    by at most ``0.5 * 10**-precision``.  Joints are written depth-first; if ``bvh`` lists them in another
    order the motion columns are permuted to match.
    """
    if precision < 0:
        raise ValueError(f"format_bvh: precision must be >= 0, got {precision}")
    if not np.isfinite(bvh.motion).all():
        raise BVHError("cannot write non-finite motion values", bvh.source)
    children: dict[int, list[int]] = {}
    for j, p in enumerate(bvh.parents.tolist()):
        children.setdefault(p, []).append(j)
    out = ["HIERARCHY"]
    order: list[int] = []

    def offset_line(off: np.ndarray, depth: int) -> str:
        return "\t" * depth + "OFFSET " + " ".join(_fmt(v, precision) for v in off.tolist())

    def write_joint(j: int, depth: int) -> None:
        order.append(j)
        tab = "\t" * depth
        out.append(f"{tab}{'ROOT' if depth == 0 else 'JOINT'} {bvh.names[j]}")
        out.append(tab + "{")
        out.append(offset_line(bvh.offsets[j], depth + 1))
        ch = bvh.channels[j]
        out.append(f"{tab}\tCHANNELS {len(ch)} {' '.join(ch)}".rstrip())
        for c in children.get(j, []):
            write_joint(c, depth + 1)
        if j in bvh.end_sites:
            out.extend([f"{tab}\tEnd Site", f"{tab}\t{{", offset_line(bvh.end_sites[j], depth + 2), f"{tab}\t}}"])
        out.append(tab + "}")

    write_joint(0, 0)
    starts = np.cumsum([0] + [len(ch) for ch in bvh.channels])
    cols = np.concatenate([np.arange(starts[j], starts[j + 1]) for j in order]).astype(np.int64)
    motion = bvh.motion[:, cols]
    out += ["MOTION", f"Frames: {motion.shape[0]}", f"Frame Time: {float(bvh.frame_time)!r}"]
    row = " ".join([f"%.{precision}f"] * motion.shape[1])
    out += [row % tuple(r) for r in motion.tolist()]
    return "\n".join(out) + "\n"


def write_bvh(bvh: BVH, path_or_file, precision: int = 6) -> None:
    """Write :func:`format_bvh` text to a path or to an open text/binary file object."""
    text = format_bvh(bvh, precision)
    if isinstance(path_or_file, (str, os.PathLike)):
        from inbetweening.atomic import write_text

        write_text(path_or_file, text)  # atomic: an interrupted write never leaves half a file
        return
    try:
        path_or_file.write(text)
    except TypeError:  # a binary file object
        path_or_file.write(text.encode("utf-8"))
