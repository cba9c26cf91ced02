"""What the model did per gap, kept in the record (:mod:`.record`) and shown to the animator (Blender's *Last Fill*
panel): the network's share of each window (the do-no-harm blend weight, 100 % where the model has no blend) and the
frames where each foot is planted (the model's predicted contact above one half, or the contact rule on the fill for
a model without contact channels).  Gaps kept from an earlier fill show what was done then."""
from __future__ import annotations

import numpy as np

from inbetweening.data.contacts import CONTACT_THRESHOLD
from inbetweening.data.mirror import side_of
from inbetweening.runtime.foot_lock import legs

__all__ = ["gap_info", "summary_lines"]


def _runs(frames: np.ndarray, flags: np.ndarray) -> list[list[int]]:
    """``[[start, end], ...]`` (inclusive frames) of the runs of True in ``flags`` over consecutive ``frames``."""
    out: list[list[int]] = []
    for f, on in zip(frames.tolist(), flags.tolist()):
        if on and out and out[-1][1] == f - 1:
            out[-1][1] = f
        elif on:
            out.append([f, f])
    return out


def gap_info(frames: np.ndarray, gaps, filled, model_info) -> dict:
    """``{(a, b): {"windows": [[a, b, share]], "planted": {"L": [[s, e]], "R": ...} or None}}`` for the gaps filled
    now, from the runtime's :class:`~inbetweening.runtime.fill.Filled` over ``frames`` (its rows); the shares exact
    (the next re-fill compares them with its own)."""
    out = {}
    contact = filled.contact
    sides = []
    if contact is not None and filled.feet:  # the model's feet, or those found by name (a model without them)
        sk = model_info.skeleton
        for _, _, ankle in legs(sk, filled.feet):  # a foot is planted where its ankle or toe is
            side = side_of(sk.names[ankle])
            joints = [j for j in filled.feet if j == ankle or (side and side_of(sk.names[j]) == side)]
            sides.append(({"left": "L", "right": "R"}.get(side, sk.names[ankle]), joints))
    pos = {int(f): i for i, f in enumerate(frames)}
    for a, b in gaps:
        windows = [[int(frames[i]), int(frames[j]), float(w)] for i, j, w in filled.segments
                   if a <= frames[i] and frames[j] <= b]
        planted = None
        if sides:
            rows = np.array([pos[f] for f in range(a + 1, b)])
            gen = np.arange(a + 1, b)
            planted = {name: _runs(gen, (np.nan_to_num(contact[rows][:, js]) > CONTACT_THRESHOLD).any(-1))
                       for name, js in sides}
        out[(a, b)] = {"windows": windows, "planted": planted}
    return out


def _spans(runs) -> str:
    return ", ".join(f"{s}" if s == e else f"{s}–{e}" for s, e in runs) or "none"


def summary_lines(meta: dict | None) -> list[tuple[str, str]]:
    """The lines ``(text, icon)`` that tell the animator what the last fill did (``meta``: the record's,
    :func:`~.record.decode`; the icon: Blender's name for it)."""
    if meta is None:
        return [("Not filled yet", "INFO")]
    last = meta.get("last", {})
    lines = [(f"Last fill: {last.get('gaps', 0)} gap(s) filled, {last.get('kept', 0)} kept", "IPO_BEZIER")]
    if last.get("edits"):
        lines.append((f"{last['edits']} hand edit(s) kept as keys", "KEYFRAME_HLT"))
    if last.get("partial_keys"):
        lines.append((f"{last['partial_keys']} partial key(s): some bones keyed", "KEYFRAME"))
    refilled = {tuple(g) for g in last.get("refilled", [])}
    for (a, b), gi in zip(meta["gaps"], meta["info"]):
        shares = " / ".join(f"{100 * w:.0f} %" for _, _, w in gi.get("windows", [])) or "?"
        mark = "" if (a, b) in refilled else "  (kept)"
        lines.append((f"{a}–{b}: network {shares}{mark}", "IPO_EASE_IN_OUT"))
        planted = gi.get("planted")
        if planted is not None:
            feet = " · ".join(f"{side} {_spans(runs)}" for side, runs in planted.items())
            lines.append((f"feet planted: {feet}", "BLANK1"))
    return lines
