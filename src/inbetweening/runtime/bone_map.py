"""The humanoid bone map: which bone of a user's rig plays which joint (*slot*) of the model's skeleton.

The slots are the shipped model's 21 joints (Unity/VRM humanoid names with a side suffix); 15 of them are required
(:data:`REQUIRED`).  :func:`detect_bone_map` finds them in three steps:

1. **names**: every bone name is brought to a canonical form (namespaces such as ``mixamorig:``/``Armature|`` and
   prefixes such as ``DEF-``/``CC_Base_``/``Bip01 ``/``J_Bip_L_`` stripped, camelCase and ``_ . - space`` split, the
   side tokens ``L/R/Left/Right/左/右`` taken out as a side), then scored against naming presets (the model's own
   names, Mixamo/LAFAN1, CMU, UE4/UE5 mannequin, Rigify meta-rig and deform bones, SMPL, Poser, DAZ, MakeHuman,
   VRM/VRoid, 3ds Max Biped, Character Creator, MMD, and a generic vocabulary).  One preset is chosen for the whole
   rig, the one that maps the most required slots consistently with the hierarchy and explains the most bones, so
   an ambiguous name is read the way its rig means it ("LeftShoulder" is the clavicle next to "LeftArm", the upper
   arm next to "LeftCollar");
2. **structure**, for the slots the names leave empty: the hierarchy and the rest offsets (any up axis, any unit):
   legs and arms are the two mirrored pairs of big branches, the hips where the legs branch off, the spine the path
   up to the arms, the head the chain above it; elbows and knees by their place along the limb, feet where the
   limb turns forward, left and right from the rest pose (forward = where the toes point);
3. **override**: ``{rig_bone: slot}`` (a YAML file, :func:`read_override`) on top; ``null`` unmaps a bone.

A rig that cannot be mapped raises :class:`BoneMapError` (one line naming the missing slots) with an override
template in ``.template``.

Standard library and numpy only (PyYAML imported inside :func:`read_override`): the Blender extension bundles this
module without PyTorch.
"""
from __future__ import annotations

import difflib
import json
import re
from dataclasses import dataclass, field
from itertools import combinations

import numpy as np

__all__ = [
    "OPTIONAL",
    "PRESETS",
    "REQUIRED",
    "SLOTS",
    "SLOT_PARENTS",
    "BoneMap",
    "BoneMapError",
    "canonical",
    "detect_bone_map",
    "read_override",
]

SLOTS: tuple[str, ...] = (
    "Hips", "Spine", "Chest", "Neck", "Head",
    "Shoulder_L", "UpperArm_L", "LowerArm_L", "Hand_L",
    "Shoulder_R", "UpperArm_R", "LowerArm_R", "Hand_R",
    "UpperLeg_L", "LowerLeg_L", "Foot_L", "Toes_L",
    "UpperLeg_R", "LowerLeg_R", "Foot_R", "Toes_R",
)
SLOT_PARENTS: dict[str, str | None] = {
    "Hips": None, "Spine": "Hips", "Chest": "Spine", "Neck": "Chest", "Head": "Neck",
    **{f"{part}_{s}": parent for s in "LR" for part, parent in (
        ("Shoulder", "Chest"), ("UpperArm", f"Shoulder_{s}"), ("LowerArm", f"UpperArm_{s}"), ("Hand", f"LowerArm_{s}"),
        ("UpperLeg", "Hips"), ("LowerLeg", f"UpperLeg_{s}"), ("Foot", f"LowerLeg_{s}"), ("Toes", f"Foot_{s}"))},
}
REQUIRED: tuple[str, ...] = (
    "Hips", "Spine", "Head",
    *(f"{part}_{s}" for s in "LR" for part in ("UpperArm", "LowerArm", "Hand", "UpperLeg", "LowerLeg", "Foot")),
)
OPTIONAL: tuple[str, ...] = tuple(s for s in SLOTS if s not in REQUIRED)
_SIDED = ("Shoulder", "UpperArm", "LowerArm", "Hand", "UpperLeg", "LowerLeg", "Foot", "Toes")


class BoneMapError(ValueError):
    """A rig that cannot be mapped, or a bad override: one line.  ``template``: YAML text of an override file listing
    every bone of the rig (a guessed slot, or commented out), where one could be written."""

    def __init__(self, message: str, template: str | None = None):
        super().__init__(message)
        self.template = template


# --------------------------------------------------------------------------------------------
# Canonical names
# --------------------------------------------------------------------------------------------
_PREFIXES = (  # (lower-case prefix, side it implies, priority when two bones share a canonical name: lower wins)
    ("def-", None, 0), ("org-", None, 2), ("mch-", None, 3), ("cc_base_", None, 1), ("bip001 ", None, 1),
    ("bip01 ", None, 1), ("bip001_", None, 1), ("bip01_", None, 1), ("j_bip_c_", None, 1), ("j_bip_l_", "L", 1),
    ("j_bip_r_", "R", 1), ("mixamorig_", None, 1), ("bone_", None, 1), ("b_", None, 1),
)
_NAMESPACE = re.compile(r"^.*[:|/]")
_CHARACTER = re.compile(r"^character\d*_", re.IGNORECASE)  # HumanIK's Character1_LeftUpLeg
_TOKEN = re.compile(r"[A-Z]+(?=[A-Z][a-z])|[A-Z]?[a-z]+|[A-Z]+|[0-9]+|[^\x00-\x7f]+")
_SIDE_WORDS = {"l": "L", "left": "L", "r": "R", "right": "R"}
_END_WORDS = {"end", "nub", "tip", "top", "site"}


@dataclass(frozen=True)
class _Canon:
    side: str | None  # "L", "R" or None
    key: str  # letters joined, lower case; each group of digits as ".<int>" ("spine_01" -> "spine.1")
    tokens: tuple[str, ...]
    priority: int  # DEF- 0, plain 1, ORG- 2, MCH- 3


def canonical(name: str) -> _Canon:
    """Side and canonical key of a bone name: ``"mixamorig:LeftForeArm"`` -> ``("L", "forearm")``,
    ``"DEF-upper_arm.L.001"`` -> ``("L", "upperarm.1")``, ``"spine_03"`` -> ``(None, "spine.3")``."""
    text = _NAMESPACE.sub("", str(name).strip()) or str(name)
    text = _CHARACTER.sub("", text)
    side, priority = None, 1
    stripped = True
    while stripped:
        stripped = False
        for prefix, implied, prio in _PREFIXES:
            if text.lower().startswith(prefix) and len(text) > len(prefix):
                text, stripped = text[len(prefix):], True
                side = side or implied
                priority = prio if priority == 1 else priority
                break
    tokens: list[str] = []
    for part in re.split(r"[_.\-\s]+", text):
        tokens += _TOKEN.findall(part)
    words: list[str] = []
    for i, tok in enumerate(tokens):
        low = tok.lower()
        if low in _SIDE_WORDS and side is None:
            side = _SIDE_WORDS[low]
            continue
        if low in _SIDE_WORDS:
            continue
        if low == "c" and (i == 0 or i == len(tokens) - 1) and len(tokens) > 1:
            continue  # a centre marker
        if low == "mixamorig" and i == 0:
            continue
        if low[0] in "左右" or low[-1] in "左右":
            mark = low[0] if low[0] in "左右" else low[-1]
            if side is None:
                side = "L" if mark == "左" else "R"
            low = low[1:] if low[0] == mark else low[:-1]
            if not low:
                continue
        words.append(low)
    key = "".join(f".{int(w)}" if w.isdigit() else w for w in words)
    return _Canon(side, key, tuple(words), priority)


# --------------------------------------------------------------------------------------------
# Presets: per slot kind, regular expressions over the canonical key (full match).  "spine" and "neck" are chains
# (every match, ordered by depth: Spine = the first, Chest = the last below the neck and arms, Neck = the first).
# "other": names of the preset's bones that are not slots (fingers, twist bones...), counted when scoring.
# --------------------------------------------------------------------------------------------
_D = r"(\.\d+)*"  # any digit groups
_FINGERS = r"(hand)?(thumb|index|middle|mid|ring|pinky|little|finger|fingers|fingerbase)[a-z]*" + _D
PRESETS: dict[str, dict[str, tuple[str, ...]]] = {
    "model": {  # the shipped model's joints (Bandai-Namco-2)
        "Hips": ("hips",), "spine": ("spine", "chest"), "neck": ("neck",), "Head": ("head",),
        "Shoulder": ("shoulder",), "UpperArm": ("upperarm",), "LowerArm": ("lowerarm",), "Hand": ("hand",),
        "UpperLeg": ("upperleg",), "LowerLeg": ("lowerleg",), "Foot": ("foot",), "Toes": ("toes",), "other": (),
    },
    "Mixamo/LAFAN1": {
        "Hips": ("hips",), "spine": (r"spine(\.\d+)?",), "neck": (r"neck(\.\d+)?",), "Head": ("head",),
        "Shoulder": ("shoulder",), "UpperArm": ("arm",), "LowerArm": ("forearm",), "Hand": ("hand",),
        "UpperLeg": ("upleg",), "LowerLeg": ("leg",), "Foot": ("foot",), "Toes": ("toebase", "toe"),
        "other": (r"(headtop|toe|hand[a-z]*\.\d+)end", r"hand(thumb|index|middle|ring|pinky)\.\d+", "eye"),
    },
    "CMU": {
        "Hips": ("hips",), "spine": ("lowerback", r"spine(\.\d+)?"), "neck": (r"neck(\.\d+)?",),
        "Head": ("head",), "Shoulder": ("shoulder",), "UpperArm": ("arm",), "LowerArm": ("forearm",),
        "Hand": ("hand",), "UpperLeg": ("upleg",), "LowerLeg": ("leg",), "Foot": ("foot",), "Toes": ("toebase",),
        "other": ("hipjoint", "fingerbase", "fingers", "thumb"),
    },
    "UE mannequin": {
        "Hips": ("pelvis",), "spine": (r"spine\.\d+",), "neck": (r"neck\.\d+",), "Head": ("head",),
        "Shoulder": ("clavicle",), "UpperArm": ("upperarm",), "LowerArm": ("lowerarm",), "Hand": ("hand",),
        "UpperLeg": ("thigh",), "LowerLeg": ("calf",), "Foot": ("foot",), "Toes": ("ball",),
        "other": ("root", r"ik[a-z]*" + _D, r"[a-z]*twist[a-z]*" + _D, r"(thumb|index|middle|ring|pinky)" + _D,
                  r"[a-z]+corrective[a-z]*" + _D, r"(clavicle|spine|thigh|calf|upperarm|lowerarm)[a-z.0-9]+",
                  r"(interaction|center[a-z]*|weapon|attach|prop)"),
    },
    "Rigify": {  # the meta-rig and the generated rig's deform bones (DEF-, preferred over ORG-/MCH-)
        "Hips": ("spine",), "spine": (r"spine\.[123]",), "neck": (r"spine\.[45]", "neck"),
        "Head": (r"spine\.6", "head"), "Shoulder": ("shoulder",), "UpperArm": ("upperarm",),
        "LowerArm": ("forearm",), "Hand": ("hand",), "UpperLeg": ("thigh",), "LowerLeg": ("shin",), "Foot": ("foot",),
        "Toes": ("toe",),
        "other": ("pelvis", "breast", r"heel\.\d+", r"palm\.\d+", r"(thumb|f(index|middle|ring|pinky))" + _D,
                  r"(upperarm|forearm|thigh|shin)\.\d+", "face", r"(eye|ear|lip|lid|brow|nose|cheek|chin|jaw|teeth|"
                  r"tongue|temple|forehead)[a-z]*" + _D),
    },
    "SMPL": {
        "Hips": ("pelvis",), "spine": (r"spine\.[123]",), "neck": ("neck",), "Head": ("head",),
        "Shoulder": ("collar",), "UpperArm": ("shoulder",), "LowerArm": ("elbow",), "Hand": ("wrist",),
        "UpperLeg": ("hip",), "LowerLeg": ("knee",), "Foot": ("ankle",), "Toes": ("foot",),
        "other": ("hand", "jaw", "eye", r"eyesmplhf", r"(thumb|index|middle|ring|pinky)" + _D),
    },
    "Poser": {
        "Hips": ("hips", "hip"), "spine": ("abdomen", "ab", "chest"), "neck": ("neck",), "Head": ("head",),
        "Shoulder": ("collar",), "UpperArm": ("shoulder", "shldr"), "LowerArm": ("elbow", "forearm"),
        "Hand": ("wrist", "hand"), "UpperLeg": ("hip", "thigh"), "LowerLeg": ("knee", "shin"),
        "Foot": ("ankle", "foot"), "Toes": ("toes", "toe"),
        "other": ("buttock", "pelvis", "eye", r"(thumb|index|mid|ring|pinky)" + _D),
    },
    "DAZ": {
        "Hips": ("hip",), "spine": ("abdomenlower", "abdomenupper", "chestlower", "chestupper", "abdomen",
                                    r"abdomen\.2", "chest"),
        "neck": ("necklower", "neckupper", "neck"), "Head": ("head",), "Shoulder": ("collar",),
        "UpperArm": ("shldrbend", "shldr"), "LowerArm": ("forearmbend", "forearm"), "Hand": ("hand",),
        "UpperLeg": ("thighbend", "thigh"), "LowerLeg": ("shin",), "Foot": ("foot",), "Toes": ("toe",),
        "other": ("pelvis", r"(thigh|shldr|forearm)twist", "metatarsals", r"(carpal|thumb|index|mid|ring|pinky)" + _D,
                  r"(big|small)toe" + _D, "eye", "jaw"),
    },
    "MakeHuman": {
        "Hips": ("root",), "spine": (r"spine\.[1-5]",), "neck": (r"neck\.[1-3]",), "Head": ("head",),
        "Shoulder": ("clavicle",), "UpperArm": (r"upperarm\.1",), "LowerArm": (r"lowerarm\.1",), "Hand": ("wrist",),
        "UpperLeg": (r"upperleg\.1",), "LowerLeg": (r"lowerleg\.1",), "Foot": ("foot",), "Toes": (r"toe\.1\.1",),
        "other": ("pelvis", r"shoulder\.1", r"(upperarm|lowerarm|upperleg|lowerleg)\.2", r"(finger|metacarpal|toe)" + _D,
                  r"(eye|jaw|tongue|orbicularis|levator|oris|risorius|temporalis|special)[a-z]*" + _D),
    },
    "VRM": {  # VRM humanoid bones and VRoid's J_Bip_ names
        "Hips": ("hips",), "spine": ("spine", "chest", "upperchest"), "neck": ("neck",), "Head": ("head",),
        "Shoulder": ("shoulder",), "UpperArm": ("upperarm",), "LowerArm": ("lowerarm",), "Hand": ("hand",),
        "UpperLeg": ("upperleg",), "LowerLeg": ("lowerleg",), "Foot": ("foot",), "Toes": ("toes", "toebase"),
        "other": ("root", "eye", "jaw", r"(thumb|index|middle|ring|little)(metacarpal|proximal|intermediate|distal)?" + _D,
                  r"j(sec|adj)[a-z0-9.]*", r"face[a-z]*"),
    },
    "3ds Max Biped": {
        "Hips": ("pelvis",), "spine": (r"spine(\.\d+)?",), "neck": (r"neck(\.\d+)?",), "Head": ("head",),
        "Shoulder": ("clavicle",), "UpperArm": ("upperarm",), "LowerArm": ("forearm",), "Hand": ("hand",),
        "UpperLeg": ("thigh",), "LowerLeg": ("calf",), "Foot": ("foot",), "Toes": (r"toe\.0", "toe"),
        "other": (r"bip\.\d+", r"(finger|toe)" + _D + "(nub)?", r"[a-z]*nub", "footsteps", r"ponytail" + _D,
                  r"[a-z]*twist" + _D),
    },
    "Character Creator": {
        "Hips": ("hip",), "spine": ("waist", r"spine\.\d+"), "neck": (r"necktwist\.\d+",), "Head": ("head",),
        "Shoulder": ("clavicle",), "UpperArm": ("upperarm",), "LowerArm": ("forearm",), "Hand": ("hand",),
        "UpperLeg": ("thigh",), "LowerLeg": ("calf",), "Foot": ("foot",), "Toes": ("toebase",),
        "other": ("pelvis", r"[a-z]*twist" + _D, r"[a-z]*sharebone", r"(thumb|index|mid|ring|pinky)" + _D,
                  r"(facialbone|jawroot|eye|teeth|tongue|breast|bigtoe|indextoe|midtoe|ringtoe|pinkytoe)[a-z]*" + _D),
    },
    "MMD": {
        "Hips": ("腰", "グルーブ", "センター"), "spine": ("上半身", r"上半身\.\d+"), "neck": ("首",), "Head": ("頭",),
        "Shoulder": ("肩",), "UpperArm": ("腕",), "LowerArm": ("ひじ",), "Hand": ("手首",),
        "UpperLeg": ("足",), "LowerLeg": ("ひざ",), "Foot": ("足首",), "Toes": ("つま先",),
        "other": ("全ての親", "下半身", "両目", "目", r"[^a-z]*ik", r"[^a-z]*d", r"(親指|人指|中指|薬指|小指)" + _D,
                  r"腰キャンセル", r"(腕|手)捩" + _D),
    },
    "generic": {  # any studio rig with plain English names; never wins a tie
        "Hips": ("hips", "hip", "pelvis"),
        "spine": (r"spine" + _D, "lowerback", "waist", r"abdomen" + _D, "ab", r"chest" + _D, "upperchest", "torso"),
        "neck": (r"neck" + _D,), "Head": ("head",), "Shoulder": (r"clavicle" + _D, "collar", "collarbone", "shoulder"),
        "UpperArm": (r"upperarm" + _D, "uparm", "arm"), "LowerArm": (r"forearm" + _D, r"lowerarm" + _D, "elbow"),
        "Hand": ("hand", "wrist"), "UpperLeg": (r"thigh" + _D, "upleg", r"upperleg" + _D),
        "LowerLeg": (r"shin" + _D, r"calf" + _D, r"lowerleg" + _D, "knee"), "Foot": ("foot", "ankle"),
        "Toes": ("toes", "toe", "toebase", "ball"), "other": (),
    },
}
_KINDS = ("Hips", "spine", "neck", "Head", *_SIDED)
_COMPILED = {p: {k: [re.compile(a) for a in spec.get(k, ())] for k in (*_KINDS, "other")} for p, spec in PRESETS.items()}


# --------------------------------------------------------------------------------------------
# The rig
# --------------------------------------------------------------------------------------------
class _Rig:
    def __init__(self, names, parents, offsets):
        self.names = [str(n) for n in names]
        self.parents = [int(p) for p in np.asarray(parents).reshape(-1)]
        J = len(self.names)
        off = np.asarray(offsets, dtype=np.float64).reshape(-1, 3) if J else np.zeros((0, 3))
        if len(self.parents) != J or off.shape[0] != J:
            raise ValueError(f"bone map: {J} names, {len(self.parents)} parents, {off.shape[0]} offsets")
        if J and (self.parents[0] != -1 or any(not (-1 <= p < j) for j, p in enumerate(self.parents))):
            raise ValueError("bone map: parents must be -1 for a root and point to earlier joints otherwise")
        self.J = J
        self.children: list[list[int]] = [[] for _ in range(J)]
        self.depth = [0] * J
        self.pos = np.zeros((J, 3))
        for j, p in enumerate(self.parents):
            if p >= 0:
                self.children[p].append(j)
                self.depth[j] = self.depth[p] + 1
                self.pos[j] = self.pos[p] + off[j]
            else:
                self.pos[j] = off[j]
        self.canon = [canonical(n) for n in self.names]
        self.index = {}
        for j, n in enumerate(self.names):
            self.index.setdefault(n, j)

    def is_below(self, a: int, b: int) -> bool:
        """Whether joint ``a`` is a strict descendant of joint ``b``."""
        a = self.parents[a]
        while a >= 0:
            if a == b:
                return True
            a = self.parents[a]
        return False

    def subtree(self, j: int) -> list[int]:
        out, todo = [], [j]
        while todo:
            k = todo.pop()
            out.append(k)
            todo += self.children[k]
        return out

    def lca(self, a: int, b: int) -> int:
        up = set()
        while a >= 0:
            up.add(a)
            a = self.parents[a]
        while b >= 0 and b not in up:
            b = self.parents[b]
        return b


# --------------------------------------------------------------------------------------------
# Step 1: names
# --------------------------------------------------------------------------------------------
def _matches(rig: _Rig, pats, sided: str | None) -> list[tuple[int, int]]:
    """``(alias index, joint)`` of the bones whose canonical key matches one of ``pats`` on side ``sided``."""
    out = []
    for j, c in enumerate(rig.canon):
        if c.side != sided:
            continue
        for a, pat in enumerate(pats):
            if pat.fullmatch(c.key):
                out.append((a, j))
                break
    return out


def _ordered(rig: _Rig, found: list[tuple[int, int]]) -> list[int]:
    """Candidates best first: deform bones before plain before ORG-/MCH-, then the preset's alias order, depth."""
    return [j for a, j in sorted(found, key=lambda aj: (rig.canon[aj[1]].priority, aj[0], rig.depth[aj[1]], aj[1]))]


def _by_preset(rig: _Rig, preset: str) -> tuple[dict[str, int], int]:
    """The slots ``preset``'s names give on this rig (consistent with the hierarchy), and how many bones it names."""
    pats = _COMPILED[preset]
    cand = {k: _ordered(rig, _matches(rig, pats[k], None)) for k in ("Hips", "spine", "neck", "Head")}
    for s in "LR":
        for kind in _SIDED:
            cand[f"{kind}_{s}"] = _ordered(rig, _matches(rig, pats[kind], s))
    used: set[int] = set()

    def pick(key, under=None, above=None):
        for j in cand[key]:
            if j in used or (under is not None and not rig.is_below(j, under)):
                continue
            if above is not None and not rig.is_below(above, j):
                continue
            return j
        return None

    # the hips: the deepest candidate that holds a spine bone and both legs, else the first one
    hips = None
    for h in sorted(cand["Hips"], key=lambda j: (rig.canon[j].priority, -rig.depth[j])):
        if all(any(rig.is_below(j, h) for j in cand[k]) for k in ("spine", "UpperLeg_L", "UpperLeg_R")):
            hips = h
            break
    if hips is None and cand["Hips"]:
        hips = cand["Hips"][0]
    out: dict[str, int] = {}
    if hips is not None:
        out["Hips"] = hips
        used.add(hips)
    head = pick("Head", under=hips)
    if head is not None:
        out["Head"] = head
        used.add(head)
    necks = [j for j in cand["neck"] if j not in used and (hips is None or rig.is_below(j, hips))
             and (head is None or rig.is_below(head, j))]
    if necks:
        out["Neck"] = min(necks, key=lambda j: (rig.canon[j].priority, rig.depth[j]))
        used.add(out["Neck"])
    for s in "LR":
        top = hips
        for kind in ("UpperLeg", "LowerLeg", "Foot", "Toes"):
            j = pick(f"{kind}_{s}", under=top)
            if j is not None:
                out[f"{kind}_{s}"], top = j, j
                used.add(j)
        top = hips
        for kind in ("UpperArm", "LowerArm", "Hand"):
            j = pick(f"{kind}_{s}", under=top)
            if j is not None:
                out[f"{kind}_{s}"], top = j, j
                used.add(j)
        j = pick(f"Shoulder_{s}", under=hips, above=out.get(f"UpperArm_{s}"))
        if j is not None:
            out[f"Shoulder_{s}"] = j
            used.add(j)
    # the spine chain: below the hips, above the neck/head; Spine the first, Chest the last above neck and arms
    tops = [out[k] for k in ("Neck", "Head") if k in out][:1]
    tops += [out.get(f"Shoulder_{s}", out.get(f"UpperArm_{s}")) for s in "LR"]
    tops = [t for t in tops if t is not None]
    chain = [j for j in cand["spine"] if j not in used and (hips is None or rig.is_below(j, hips))
             and all(rig.is_below(t, j) for t in tops[:1])]
    # one bone per depth (two bones of one chain can share a canonical name only with other prefixes: keep the best)
    best: dict[int, int] = {}
    for j in chain:
        best.setdefault(rig.depth[j], j)
    chain = [best[d] for d in sorted(best)]
    if chain:
        out["Spine"] = chain[0]
        upper = [j for j in chain[1:] if all(rig.is_below(t, j) for t in tops)]
        if upper:
            out["Chest"] = upper[-1]
    out = _consistent(rig, out)
    vocab = list(pats["other"]) + [p for k in _KINDS for p in pats[k]]
    named = sum(1 for c in rig.canon if any(p.fullmatch(c.key) for p in vocab))
    return out, named


def _consistent(rig: _Rig, slots: dict[str, int]) -> dict[str, int]:
    """``slots`` less every slot whose bone is not below the bone of its nearest mapped slot ancestor, or repeats."""
    out: dict[str, int] = {}
    for s in SLOTS:
        if s not in slots or slots[s] in out.values():
            continue
        up = SLOT_PARENTS[s]
        while up is not None and up not in out:
            up = SLOT_PARENTS[up]
        if up is None or rig.is_below(slots[s], out[up]):
            out[s] = slots[s]
    return out


def _violations(rig: _Rig, slots: dict[str, int]) -> list[str]:
    out, seen = [], {}
    for s in SLOTS:
        if s not in slots:
            continue
        j = slots[s]
        if j in seen:
            out.append(f"bone '{rig.names[j]}' is in two slots, {seen[j]} and {s}")
            continue
        seen[j] = s
        up = SLOT_PARENTS[s]
        while up is not None and up not in slots:
            up = SLOT_PARENTS[up]
        if up is not None and not rig.is_below(j, slots[up]):
            out.append(f"{s} '{rig.names[j]}' is not below {up} '{rig.names[slots[up]]}'")
    return out


def _names_pass(rig: _Rig) -> tuple[dict[str, int], str | None]:
    best, best_score, best_preset = {}, None, None
    for preset in PRESETS:
        slots, named = _by_preset(rig, preset)
        required = sum(s in slots for s in REQUIRED)
        score = (required, 0 if preset == "generic" else named, len(slots))
        if best_score is None or score > best_score:
            best, best_score, best_preset = slots, score, preset
    return best, (best_preset if best else None)


# --------------------------------------------------------------------------------------------
# Step 2: structure
# --------------------------------------------------------------------------------------------
def _unit(v: np.ndarray) -> np.ndarray | None:
    n = float(np.linalg.norm(v))
    return v / n if n > 1e-12 else None


class _Shape:
    """Geometry helpers over the rest pose, with end markers (leaves named ``*_end``, ``*Nub``...) left out."""

    def __init__(self, rig: _Rig):
        self.rig = rig
        ends = {j for j in range(rig.J) if not rig.children[j] and _END_WORDS & set(rig.canon[j].tokens)}
        self.children = [[c for c in ch if c not in ends] for ch in rig.children]
        self.sub = [self._subtree(j) for j in range(rig.J)]
        ext = rig.pos.max(0) - rig.pos.min(0) if rig.J else np.zeros(3)
        self.size = float(np.linalg.norm(ext))

    def _subtree(self, j):
        out, todo = [], [j]
        while todo:
            k = todo.pop()
            out.append(k)
            todo += self.children[k]
        return out

    def reach(self, c: int, p: int) -> float:
        """How far the subtree of ``c`` gets from joint ``p``."""
        return float(np.linalg.norm(self.rig.pos[self.sub[c]] - self.rig.pos[p], axis=1).max())

    def twist_like(self, j: int, c: int, main: int) -> bool:
        """Whether child ``c`` of ``j`` lies along the segment from ``j`` to its main child (a twist/helper bone)."""
        P = self.rig.pos
        seg = P[main] - P[j]
        length = float(np.linalg.norm(seg))
        if length < 1e-9:
            return False
        rel = P[self.sub[c]] - P[j]
        t = rel @ seg / length**2
        perp = np.linalg.norm(rel - t[:, None] * seg, axis=1)
        return bool(np.all((t > 0.02) & (t < 0.9) & (perp < 0.15 * length)))

    def main_child(self, j: int) -> int | None:
        ch = self.children[j]
        return max(ch, key=lambda c: (self.reach(c, j), -c)) if ch else None

    def real_children(self, j: int) -> list[int]:
        main = self.main_child(j)
        return [c for c in self.children[j] if c == main or not self.twist_like(j, c, main)]

    def chain(self, j: int) -> list[int]:
        """``j`` and its main children down to a leaf or a joint with two or more real children (a hand, a head)."""
        out = [j]
        while True:
            real = self.real_children(out[-1])
            if len(real) != 1:
                return out
            out.append(real[0])


def _arc(P: np.ndarray, chain: list[int]) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P[chain], axis=0), axis=1))])


def _nearest_fraction(P, chain: list[int], a: int, b: int, target: float) -> int | None:
    """The joint strictly between positions ``a`` and ``b`` of ``chain`` whose arc fraction is nearest ``target``."""
    arc = _arc(P, chain[a:b + 1])
    if arc[-1] <= 0:
        return None
    best, err = None, None
    for i in range(1, len(arc) - 1):
        f = arc[i] / arc[-1]
        if f < 0.05 or f > 0.95:
            continue
        if err is None or abs(f - target) < err:
            best, err = chain[a + i], abs(f - target)
    return best


def _structure(rig: _Rig) -> dict[str, int]:
    """Slots from the hierarchy and the rest pose alone; ``{}`` when the rig does not look like a humanoid."""
    if rig.J < 10:
        return {}
    sh = _Shape(rig)
    if sh.size <= 0:
        return {}
    # mirrored pairs of big branches: sibling subtrees of one size that reach as far
    pairs = []
    for p in range(rig.J):
        for a, b in combinations(sh.children[p], 2):
            if len(sh.sub[a]) != len(sh.sub[b]):
                continue
            ra, rb = sh.reach(a, p), sh.reach(b, p)
            if min(ra, rb) > 0.15 * sh.size and abs(ra - rb) <= 0.25 * max(ra, rb):
                pairs.append((ra + rb, p, a, b))
    combos = []
    for (r1, p1, a1, b1), (r2, p2, a2, b2) in combinations(sorted(pairs, reverse=True), 2):
        inside = set(sh.sub[a1]) | set(sh.sub[b1]) | set(sh.sub[a2]) | set(sh.sub[b2])
        if p1 in inside or p2 in inside:
            continue
        hips = rig.lca(p1, p2)
        if hips < 0:
            continue
        legs, arms = ((p1, a1, b1), (p2, a2, b2))
        if rig.depth[p2] - rig.depth[hips] < rig.depth[p1] - rig.depth[hips]:
            legs, arms = arms, legs
        combos.append((r1 + r2, hips, legs, arms))
    for _, hips, legs, arms in sorted(combos, key=lambda c: -c[0])[:12]:  # the biggest pairs that make a humanoid
        out = _humanoid(rig, sh, hips, legs, arms)
        if out:
            return out
    return {}


def _humanoid(rig: _Rig, sh: _Shape, hips: int, legs: tuple, arms: tuple) -> dict[str, int]:
    """The slots when ``legs`` and ``arms`` (each ``(branch joint, child a, child b)``) are the legs and the arms of a
    humanoid whose hips is ``hips``; ``{}`` when they are not (a level spine, hands down at the feet...)."""
    P = rig.pos
    (_, la, lb), (ap, aa, ab) = legs, arms

    def leg(a):
        ch = sh.chain(a)
        i = 0
        total = _arc(P, ch)[-1]
        while i < len(ch) - 3 and np.linalg.norm(P[ch[i]] - P[hips]) < 0.03 * total:
            i += 1  # a zero-length hip joint (CMU's LHipJoint)
        return ch, i

    (lch_a, ta), (lch_b, tb) = leg(la), leg(lb)

    def foot_of(ch, t, up):
        """The ankle: the first joint (two or more below the thigh) where the leg turns forward, or its end."""
        for i in range(t + 2, len(ch)):
            nxt = ch[i + 1] if i + 1 < len(ch) else None
            if nxt is None or len(sh.real_children(ch[i])) > 1:
                return i
            d = _unit(P[nxt] - P[ch[i]])
            if d is not None and abs(float(d @ up)) < 0.7:
                return i
        return None

    # up: from the leg ends to the hips, then again from the ankles (the toes lie forward of the hips)
    up = _unit(P[hips] - (P[lch_a[-1]] + P[lch_b[-1]]) / 2)
    feet: dict[str, int | None] = {}
    for _ in range(2):
        if up is None:
            return {}
        feet = {"a": foot_of(lch_a, ta, up), "b": foot_of(lch_b, tb, up)}
        if None in feet.values():
            return {}
        up = _unit(P[hips] - (P[lch_a[feet["a"]]] + P[lch_b[feet["b"]]]) / 2)
    if up is None:
        return {}
    spine_path = []
    j = ap
    while j != hips and j >= 0:
        spine_path.append(j)
        j = rig.parents[j]
    spine_path.reverse()
    if not spine_path:
        return {}
    out: dict[str, int] = {"Hips": hips, "Spine": spine_path[0]}
    if len(spine_path) >= 2:
        out["Chest"] = spine_path[-1]
    # head: the remaining branch of the chest that reaches highest
    others = [c for c in sh.children[ap] if c not in (aa, ab)]
    if not others:
        return {}
    top = max(others, key=lambda c: float((P[sh.sub[c]] @ up).max()))
    nch = sh.chain(top)
    out["Head"] = nch[-1]
    if len(nch) >= 2:
        out["Neck"] = nch[0]

    limbs = {}
    for name, (ch, t) in (("a", (lch_a, ta)), ("b", (lch_b, tb))):
        f = feet[name]
        knee = _nearest_fraction(P, ch, t, f, 0.5)
        toes = ch[f + 1] if f + 1 < len(ch) else None
        if toes is None and sh.real_children(ch[f]):  # several toes: the middle one
            kids = sh.real_children(ch[f])
            mid = P[kids].mean(0)
            toes = min(kids, key=lambda c: (float(np.linalg.norm(P[c] - mid)), c))
        limbs["leg_" + name] = {"UpperLeg": ch[t], "LowerLeg": knee, "Foot": ch[f], "Toes": toes}
    for name, a in (("a", aa), ("b", ab)):
        ch = sh.chain(a)
        if len(ch) < 3:
            return {}
        hand_i = len(ch) - 1
        for i in range(2, len(ch)):
            if len(sh.real_children(ch[i])) > 1:
                hand_i = i
                break
        lateral_start = np.linalg.norm((P[ch[0]] - P[ap]) - ((P[ch[0]] - P[ap]) @ up) * up)
        lateral_hand = np.linalg.norm((P[ch[hand_i]] - P[ap]) - ((P[ch[hand_i]] - P[ap]) @ up) * up)
        seg = np.linalg.norm(np.diff(P[ch], axis=0), axis=1)  # seg[i]: from ch[i] to ch[i + 1]
        if not sh.children[ch[hand_i]] and hand_i >= 3 and seg[hand_i - 1] < 0.5 * seg[hand_i - 2]:
            hand_i -= 1  # a short leaf past the wrist (SMPL's left_hand, a hand end bone)
        u = 0
        if hand_i >= 3 and lateral_start < 0.15 * lateral_hand:
            u = 1  # a clavicle: it starts near the middle of the body
            while u < hand_i - 2 and (seg[u - 1] < 1e-9 or seg[u] < 0.3 * seg[u + 1]):
                u += 1  # a zero-length clavicle start, or a short shoulder bone before the upper arm
        elbow = _nearest_fraction(P, ch, u, hand_i, 0.53)
        limbs["arm_" + name] = {"Shoulder": ch[0] if u else None, "UpperArm": ch[u], "LowerArm": elbow,
                                "Hand": ch[hand_i]}
    # a humanoid: the spine goes up, the hands hang well above the feet
    feet = [limbs[f"leg_{n}"]["Foot"] for n in "ab"]
    hands = [limbs[f"arm_{n}"]["Hand"] for n in "ab"]
    floor = min(float(P[f] @ up) for f in feet)
    height = float(P[out["Head"]] @ up) - floor
    spine_dir = _unit(P[out["Head"]] - P[hips])
    if height <= 0 or spine_dir is None or float(spine_dir @ up) < 0.7:
        return {}
    if min(float(P[h] @ up) for h in hands) - floor < 0.25 * height:
        return {}
    # left and right: forward from the toes (else the usual facing of a Y-up or Z-up file), left = up x forward
    fwd = np.zeros(3)
    for n in "ab":
        leg_ = limbs[f"leg_{n}"]
        if leg_["Toes"] is not None:
            v = P[leg_["Toes"]] - P[leg_["Foot"]]
            fwd += v - (v @ up) * up
    fwd = _unit(fwd)
    if fwd is None:
        fwd = np.array([0.0, 0.0, 1.0]) if abs(up[1]) >= abs(up[2]) else np.array([0.0, -1.0, 0.0])
        fwd = _unit(fwd - (fwd @ up) * up)
        if fwd is None:
            return {}
    left = np.cross(up, fwd)
    side_leg = {n: "L" if float((P[limbs[f"leg_{n}"]["UpperLeg"]] - P[hips]) @ left) > 0 else "R" for n in "ab"}
    side_arm = {n: "L" if float((P[limbs[f"arm_{n}"]["Hand"]] - P[ap]) @ left) > 0 else "R" for n in "ab"}
    if side_leg["a"] == side_leg["b"] or side_arm["a"] == side_arm["b"]:
        return {}
    for n in "ab":
        for kind, j in limbs[f"leg_{n}"].items():
            if j is not None:
                out[f"{kind}_{side_leg[n]}"] = j
        for kind, j in limbs[f"arm_{n}"].items():
            if j is not None:
                out[f"{kind}_{side_arm[n]}"] = j
    return _consistent(rig, out)


def _merge(rig: _Rig, named: dict[str, int], shaped: dict[str, int]) -> dict[str, int]:
    """``named`` with the slots it lacks taken from ``shaped`` where they fit (left/right turned to agree)."""
    agree = disagree = 0
    for s, j in shaped.items():
        if s[-2:] in ("_L", "_R"):
            for t, k in named.items():
                if k == j and t[-2:] in ("_L", "_R"):
                    agree += t[-1] == s[-1]
                    disagree += t[-1] != s[-1]
    if disagree > agree:
        flip = {"L": "R", "R": "L"}
        shaped = {(s[:-1] + flip[s[-1]] if s[-2:] in ("_L", "_R") else s): j for s, j in shaped.items()}
    out = dict(named)
    for s in SLOTS:
        if s in out or s not in shaped or shaped[s] in out.values():
            continue
        trial = {**out, s: shaped[s]}
        if not _violations(rig, trial):
            out = trial
    return out


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


def detect_bone_map(names, parents, offsets, override: dict[str, str] | None = None, where: str = "rig") -> BoneMap:
    """The bone map of a rig: ``names (J,)``, ``parents (J,)`` (-1 for a root, parents before children), ``offsets
    (J, 3)`` each joint's rest offset from its parent (any up axis, any unit); ``override`` ``{rig_bone: slot or
    None}`` on top.  ``where`` names the rig in messages (``"rig 'wolf.bvh'"``).

    :class:`BoneMapError` (one line) when a required slot stays empty (``.template``: an override file to fill in)
    or the override is wrong (a bone the rig lacks, an unknown slot, two bones for one slot, a bone not below its
    slot parent's bone)."""
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
