"""Where the DCC core's record of the last fill lives in Blender (:mod:`inbetweening.dcc.record`: what it holds and
what it is for): an ID property of the action, :data:`RECORD`, one entry per action slot, so it is saved with the
.blend and restored by undo."""
from __future__ import annotations

from inbetweening.dcc.record import decode

RECORD = "inbetween_fill"


def holder(obj):
    """``(action, key)``: where the record of the armature's animation lives (its action, one entry per slot)."""
    ad = obj.animation_data
    if ad is None or ad.action is None:
        return None, None
    slot = getattr(ad, "action_slot", None)
    return ad.action, (f"slot{slot.handle}" if slot is not None else "action")


def entry(obj):
    """The stored entry of the armature's animation (``{"meta": JSON, arrays...}``), ``None`` when there is none."""
    action, key = holder(obj)
    group = action.get(RECORD) if action is not None else None
    if group is None or key not in group:
        return None
    return group[key]


def load(obj) -> tuple[dict | None, dict]:
    """The stored record of the armature's animation: ``(meta, arrays)``, ``(None, {})`` when there is none."""
    return decode(entry(obj))


def store(obj, value: dict) -> None:
    """Store ``value`` (:func:`inbetweening.dcc.record.encode`) as the armature's record."""
    action, key = holder(obj)
    if action.get(RECORD) is None:
        action[RECORD] = {}
    group = action[RECORD]
    if key in group:
        del group[key]  # a fresh group: assigning into an existing ID property array keeps its old length
    group[key] = value
