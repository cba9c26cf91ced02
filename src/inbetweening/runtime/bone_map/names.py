"""Canonical bone names (:func:`canonical`: namespaces and prefixes stripped, words split, the side taken out) and
the naming presets (:data:`PRESETS`) scored against them."""
from __future__ import annotations

import re
from dataclasses import dataclass

from .slots import _SIDED

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
