"""Writing BVH files: standard tab-indented text, fixed-point values, atomic file writes."""
from __future__ import annotations

import os
from typing import TYPE_CHECKING

import numpy as np

from inbetweening.data.errors import BVHError

if TYPE_CHECKING:
    from inbetweening.data.bvh import BVH

__all__ = ["format_bvh", "write_bvh"]


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
