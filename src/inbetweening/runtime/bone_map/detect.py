"""The map itself: :class:`BoneMap`, the override template, override files (:func:`read_override`) and
:func:`detect_bone_map`, which runs the name pass, the structural fallback and the override."""
from __future__ import annotations

import difflib
import json
import re
from dataclasses import dataclass, field

import numpy as np

from .name_pass import _names_pass
from .names import canonical
from .rig import _Rig, _violations
from .slots import _SIDED, REQUIRED, SLOT_PARENTS, SLOTS, BoneMapError
from .structure import _merge, _structure


# --------------------------------------------------------------------------------------------
# The map
# --------------------------------------------------------------------------------------------
def _q(name: str) -> str:
    """A bone name as a YAML double-quoted scalar (JSON's escapes are YAML's)."""
    return json.dumps(name, ensure_ascii=False)


_HEADER = (
    "# one line per bone: `\"rig bone\": slot` (the slot is a joint of the model's skeleton); `\"bone\": null` unmaps\n"
    f"# slots: {', '.join(SLOTS)}\n"
    f"# required: {', '.join(REQUIRED)}\n"
)


@dataclass(frozen=True)
class BoneMap:
    """``slots``: slot -> the rig's bone name (the mapped slots; every required one); ``how``: slot -> how it was
    found (``"name (<preset>)"``, ``"structure"`` or ``"override"``)."""

    slots: dict[str, str]
    how: dict[str, str] = field(default_factory=dict)

    def bone(self, slot: str) -> str | None:
        """The rig's bone in ``slot`` (``None`` when unmapped)."""
        if slot not in SLOT_PARENTS:
            raise KeyError(f"{slot!r} is not a slot; the slots: {', '.join(SLOTS)}")
        return self.slots.get(slot)

    def slot_of(self, bone: str) -> str | None:
        """The slot ``bone`` plays (``None``: no slot)."""
        return next((s for s, b in self.slots.items() if b == bone), None)

    def to_yaml(self) -> str:
        """The map as an override file (:func:`read_override` reads it back)."""
        lines = ["# bone map of the rig onto the model's skeleton (inbetweening); edit it and pass it back as the "
                 "override", _HEADER.rstrip("\n")]
        for s in SLOTS:
            if s in self.slots:
                lines.append(f"{_q(self.slots[s])}: {s}  # {self.how.get(s, '')}".rstrip(" #"))
        missing = [s for s in SLOTS if s not in self.slots]
        if missing:
            lines.append(f"# unmapped: {', '.join(missing)}")
        return "\n".join(lines) + "\n"

    def summary(self) -> str:
        """A few lines for a person: the groups of slots with their bones, and how they were found."""
        counts: dict[str, int] = {}
        for s in self.slots:
            counts[self.how.get(s, "?")] = counts.get(self.how.get(s, "?"), 0) + 1
        main = max(counts, key=counts.get) if counts else ""
        head = ", ".join(f"{n} by {h}" for h, n in sorted(counts.items(), key=lambda kv: -kv[1]))
        lines = [f"bone map: {len(self.slots)} of {len(SLOTS)} slots ({head})"]
        groups = (("body", SLOTS[:5]), ("arm L", SLOTS[5:9]), ("arm R", SLOTS[9:13]), ("leg L", SLOTS[13:17]),
                  ("leg R", SLOTS[17:]))
        for label, slots in groups:
            parts = []
            for s in slots:
                if s in self.slots:
                    note = "" if self.how.get(s) == main else f" ({self.how.get(s)})"
                    parts.append(f"{s[:-2] if label[-2:] in (' L', ' R') else s} <- {self.slots[s]}{note}")
            lines.append(f"  {label}: " + (", ".join(parts) if parts else "-"))
        missing = [s for s in SLOTS if s not in self.slots]
        if missing:
            lines.append(f"  unmapped: {', '.join(missing)}")
        return "\n".join(lines)


def _template(rig: _Rig, slots: dict[str, int], where: str) -> str:
    by_bone = {j: s for s, j in slots.items()}
    lines = [f"# bone map override for {where}: give each bone the model's joint it plays; lines starting with # "
             "are ignored", _HEADER.rstrip("\n")]
    missing = [s for s in SLOTS if s not in slots]
    if missing:
        lines.append(f"# not found: {', '.join(missing)}")
    for j, n in enumerate(rig.names):
        lines.append(f"{_q(n)}: {by_bone[j]}" if j in by_bone else f"# {_q(n)}: ")
    return "\n".join(lines) + "\n"


def _slot_name(value) -> str | None:
    """A slot name as written in an override (``Hips``, ``hips``, ``leftUpperArm``, ``UpperArm_L``); ``None``
    when it is none."""
    text = str(value).strip()
    if text in SLOT_PARENTS:
        return text
    lower = {s.lower(): s for s in SLOTS}
    if text.lower() in lower:
        return lower[text.lower()]
    c = canonical(text)
    for kind in ("Hips", "Head"):
        if c.side is None and c.key == kind.lower():
            return kind
    for kind, key in (("Spine", "spine"), ("Chest", "chest"), ("Neck", "neck")):
        if c.side is None and c.key == key:
            return kind
    if c.side:
        for kind in _SIDED:
            if c.key == kind.lower():
                return f"{kind}_{c.side}"
    return None


def _check_override(override: dict, rig: _Rig | None, where: str) -> dict[str, str | None]:
    """``{bone: slot or None}`` with slot names normalised; :class:`BoneMapError` for an unknown slot, a bone not in
    the rig (when ``rig`` is given) or two bones claiming one slot."""
    if not isinstance(override, dict):
        raise BoneMapError(f"{where}: the bone map override must be a mapping `rig_bone: slot`, "
                           f"not {type(override).__name__}")
    out: dict[str, str | None] = {}
    claimed: dict[str, str] = {}
    for bone, value in override.items():
        bone = str(bone)
        if value is None or (isinstance(value, str) and not value.strip()):
            slot = None
        else:
            slot = _slot_name(value)
            if slot is None:
                raise BoneMapError(f"{where}: bone '{bone}' is given the unknown slot '{value}'; the slots: "
                                   f"{', '.join(SLOTS)}")
        if rig is not None and bone not in rig.index:
            near = difflib.get_close_matches(bone, rig.names, n=1)
            hint = f" (did you mean '{near[0]}'?)" if near else ""
            raise BoneMapError(f"{where}: the override names bone '{bone}', which the rig does not have{hint}")
        if slot is not None and slot in claimed:
            raise BoneMapError(f"{where}: two bones claim slot {slot}: '{claimed[slot]}' and '{bone}'")
        if slot is not None:
            claimed[slot] = bone
        out[bone] = slot
    return out


_DETECTED: dict = {}  # the last rigs' maps: a front end maps its rig again on every fill
_DETECTED_MAX = 16


def _rig_key(names, parents, offsets, override) -> tuple | None:
    """What a bone map depends on, as a dictionary key (``None`` where the arguments are not plain arrays)."""
    try:
        return (tuple(str(n) for n in names), tuple(int(p) for p in parents),
                np.asarray(offsets, dtype=np.float64).tobytes(),
                tuple(sorted((str(b), s) for b, s in override.items())) if override else None)
    except (TypeError, ValueError):
        return None


def detect_bone_map(names, parents, offsets, override: dict[str, str] | None = None, where: str = "rig") -> BoneMap:
    """The bone map of a rig: ``names (J,)``, ``parents (J,)`` (-1 for a root, parents before children), ``offsets
    (J, 3)`` each joint's rest offset from its parent (any up axis, any unit); ``override`` ``{rig_bone: slot or
    None}`` on top.  ``where`` names the rig in messages (``"rig 'wolf.bvh'"``).  A rig mapped before (the same
    names, parents, offsets and override) gets its map again without the detection.

    :class:`BoneMapError` (one line) when a required slot stays empty (``.template``: an override file to fill in)
    or the override is wrong (a bone the rig lacks, an unknown slot, two bones for one slot, a bone not below its
    slot parent's bone)."""
    key = _rig_key(names, parents, offsets, override)
    if key is not None and key in _DETECTED:
        hit = _DETECTED[key]
        return BoneMap(dict(hit.slots), dict(hit.how))
    found = _detect(names, parents, offsets, override, where)
    if key is not None:
        if len(_DETECTED) >= _DETECTED_MAX:
            _DETECTED.pop(next(iter(_DETECTED)))
        _DETECTED[key] = BoneMap(dict(found.slots), dict(found.how))
    return found


def _detect(names, parents, offsets, override, where) -> BoneMap:
    """:func:`detect_bone_map` without the memory of the last rigs."""
    rig = _Rig(names, parents, offsets)
    checked = _check_override(override, rig, where) if override else {}
    named, preset = _names_pass(rig)
    how = {s: f"name ({preset})" for s in named}
    slots = dict(named)
    if len(slots) < len(SLOTS):
        try:
            shaped = _structure(rig)
        except (ValueError, FloatingPointError, IndexError):  # a degenerate rest pose: names only
            shaped = {}
        slots = _merge(rig, slots, shaped)
        how.update({s: "structure" for s in slots if s not in how})
    if checked:
        for bone, slot in checked.items():
            j = rig.index[bone]
            for s in [s for s, k in slots.items() if k == j]:
                del slots[s], how[s]
            if slot is not None:
                slots[slot] = j
                how[slot] = "override"
        bad = _violations(rig, slots)
        if bad:
            raise BoneMapError(f"{where}: the bone map override does not fit the hierarchy: {bad[0]}",
                               _template(rig, slots, where))
    missing = [s for s in REQUIRED if s not in slots]
    if missing:
        shown = ", ".join(missing[:4]) + (f" (+{len(missing) - 4} more)" if len(missing) > 4 else "")
        raise BoneMapError(f"{where} is not a humanoid the model can fill: no bone found for {shown}; "
                           "map them in an override file (`rig_bone: slot`, a template is written for you)",
                           _template(rig, slots, where))
    dup = [s for s, j in slots.items() if rig.names.count(rig.names[j]) > 1]
    if dup:
        raise BoneMapError(f"{where}: two bones are named '{rig.names[slots[dup[0]]]}' ({dup[0]}); rename one")
    ordered = {s: rig.names[slots[s]] for s in SLOTS if s in slots}
    return BoneMap(ordered, {s: how[s] for s in ordered})


def read_override(path) -> dict[str, str | None]:
    """The override file at ``path`` (YAML, ``rig_bone: slot`` per line, ``null`` unmaps): ``{bone: slot or None}``
    with slot names normalised; :class:`BoneMapError` naming the file and the problem."""
    import yaml  # lazily: the Blender extension bundles this module without PyYAML

    where = str(path)
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except OSError as err:
        raise BoneMapError(f"bone map override {where}: cannot read it ({err.strerror or err})") from None
    dupes = _duplicate_keys(text)
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        at = f" at line {mark.line + 1}" if mark is not None else ""
        problem = getattr(err, "problem", None) or str(err).splitlines()[0]
        raise BoneMapError(f"bone map override {where}: not valid YAML{at}: {problem}") from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise BoneMapError(f"bone map override {where}: expected lines `rig_bone: slot`, found a {type(data).__name__}")
    if dupes:
        raise BoneMapError(f"bone map override {where}: bone '{dupes[0]}' is listed twice")
    for bone, value in data.items():
        if value is not None and not isinstance(value, str):
            raise BoneMapError(f"bone map override {where}: bone '{bone}': the slot must be a name, not {value!r}")
    return _check_override({str(k): v for k, v in data.items()}, None, f"bone map override {where}")


def _duplicate_keys(text: str) -> list[str]:
    """Top-level keys written twice in a flat YAML mapping (PyYAML keeps the last one silently)."""
    seen, dupes = set(), []
    for line in text.splitlines():
        if not line.strip() or line.lstrip().startswith("#") or line[:1].isspace():
            continue
        m = re.match(r'^\s*("(?:[^"\\]|\\.)*"|\'(?:[^\']|\'\')*\'|[^:#]+?)\s*:(\s|$)', line)
        if not m:
            continue
        key = m.group(1)
        if key.startswith('"'):
            try:
                key = json.loads(key)
            except ValueError:
                continue
        elif key.startswith("'"):
            key = key[1:-1].replace("''", "'")
        if key in seen:
            dupes.append(key)
        seen.add(key)
    return dupes
