"""The text side of the BVH reader: the HIERARCHY block, the MOTION header lines, and the error path.

The hierarchy is small and read with a plain line loop (:func:`parse_header`, memoised: the clips of a
dataset share their header).  :func:`raise_motion_error` walks a MOTION block line by line to report the
first problem once the vectorised conversion (:mod:`inbetweening.data.bvh_motion`) has declined it.  Every
problem raises one :class:`~inbetweening.data.errors.BVHError` naming the line.
"""
from __future__ import annotations

import functools
import math
import re
from collections.abc import Iterator

import numpy as np

from inbetweening.data.errors import BVHError

CHANNELS = {
    "xposition": ("p", 0),
    "yposition": ("p", 1),
    "zposition": ("p", 2),
    "xrotation": ("r", 0),
    "yrotation": ("r", 1),
    "zrotation": ("r", 2),
}
MOTION_RE = re.compile(rb"^[ \t]*MOTION\b", re.MULTILINE | re.IGNORECASE)
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
        if name.lower() not in CHANNELS:
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
def parse_header(header: bytes, end_line: int) -> tuple:
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


def parse_motion_header(data: bytes, start: int, line: int, source: str) -> tuple[int, float, int, int]:
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


_NUMBER_RE = re.compile(rb"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")


def raise_motion_error(block: bytes, frames: int, width: int, first_line: int, source: str) -> None:
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
