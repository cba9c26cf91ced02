"""The humanoid bone map (:mod:`inbetweening.runtime.bone_map`): real BVH rigs of other skeletons (Debian's
``assimp-testmodels``: CMU and Poser), the model's own skeleton, and rigs generated here in the naming of the common
tools (UE mannequin, Mixamo, Rigify, SMPL, VRM/VRoid, MakeHuman, ...), by structure alone (random names, Y-up cm and
Z-up metres), and the refusals (a quadruped, a snake, bad overrides)."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from conftest import BLOCK_TORCH
from inbetweening.runtime.bone_map import (
    OPTIONAL,
    REQUIRED,
    SLOT_PARENTS,
    SLOTS,
    BoneMap,
    BoneMapError,
    canonical,
    detect_bone_map,
    read_override,
)

ASSIMP_BVH = Path("/usr/share/assimp/models/BVH")
MODEL = Path(__file__).resolve().parents[1] / "models" / "bn2_reference" / "model.ckpt"
needs_assimp = pytest.mark.skipif(not ASSIMP_BVH.is_dir(), reason="apt-get install assimp-testmodels")


def both(**parts: str) -> dict[str, str]:
    """``{Part_L: name.format(s=l, S=L, side=Left), Part_R: ...}`` for each ``Part=name``."""
    out = {}
    for side, s, word in (("L", "l", "Left"), ("R", "r", "Right")):
        for part, name in parts.items():
            out[f"{part}_{side}"] = name.format(s=s, S=side, side=word, lower=word.lower())
    return out


# --------------------------------------------------------------------------------------------
# A generated humanoid: a T-pose in cm, Y up, facing +Z (the character's left is +X)
# --------------------------------------------------------------------------------------------
class Rig:
    def __init__(self):
        self.names: list[str] = []
        self.parents: list[int] = []
        self.offsets: list[list[float]] = []

    def add(self, name, parent, offset) -> str:
        assert name not in self.names, name
        self.names.append(name)
        self.parents.append(-1 if parent is None else self.names.index(parent))
        self.offsets.append([float(v) for v in offset])
        return name

    def arrays(self, z_up_metres: bool = False):
        off = np.array(self.offsets)
        if z_up_metres:  # +90 degrees about X: Y up -> Z up, facing +Z -> facing -Y (Blender's); cm -> m
            off = np.stack([off[:, 0], -off[:, 2], off[:, 1]], axis=1) / 100.0
        return list(self.names), np.array(self.parents), off

    def renamed(self, rename) -> Rig:
        out = Rig()
        out.names = [rename(n) for n in self.names]
        out.parents, out.offsets = list(self.parents), [list(o) for o in self.offsets]
        return out


def humanoid(n, *, spine=3, neck=1, root=None, clavicle=True, toes=True, twist=None, fingers=False, ends=False,
             hipjoint=False, top_spine_offset=(0.0, 15.0, 0.0)) -> Rig:
    """A humanoid with the bone names ``n(role, side)`` (side ``"l"``/``"r"``/``None``).  ``twist``: ``"child"``
    (UE: a twist bone beside each limb bone's child) or ``"chain"`` (Rigify: each limb bone split in two);
    ``fingers``: five fingers of three bones; ``ends``: Mixamo-style end bones; ``hipjoint``: CMU-style zero-length
    joints between the hips and the thighs."""
    r = Rig()
    top = r.add(n("root", None), None, (0, 0, 0)) if root else None
    hips = r.add(n("hips", None), top, (0, 95, 2))
    prev = hips
    for i in range(spine):
        prev = r.add(n("spine", i), prev, (0, 10, -1) if i < spine - 1 else top_spine_offset)
    chest = prev
    for i in range(neck):
        prev = r.add(n("neck", i), prev, (0, 8 / neck, 1))
    head = r.add(n("head", None), prev, (0, 10, 0))
    if ends:
        r.add(n("head_end", None), head, (0, 18, 0))
    for s, x in (("l", 1.0), ("r", -1.0)):
        parent = chest
        if clavicle:
            parent = r.add(n("clavicle", s), chest, (2 * x, 4, 1))
        ua = r.add(n("upperarm", s), parent, (15 * x, 0, -1))
        la = _limb_bone(r, n, s, "lowerarm", ua, (28 * x, 0, 0), twist)
        hand = _limb_bone(r, n, s, "hand", la, (25 * x, 0, 0), twist)
        if fingers:
            for name, z in (("thumb", 3), ("index", 2), ("middle", 0.5), ("ring", -1), ("pinky", -2.5)):
                prev = hand
                for k in range(3):
                    step = (3 * x, -1, 2) if name == "thumb" and k == 0 else (8 * x, 0, z) if k == 0 else (3 * x, 0, 0)
                    prev = r.add(n("finger", (s, name, k)), prev, step)
                if ends:
                    r.add(n("finger_end", (s, name)), prev, (2 * x, 0, 0))
        parent = hips
        if hipjoint:
            parent = r.add(n("hipjoint", s), hips, (0, 0, 0))
        thigh = r.add(n("thigh", s), parent, (9 * x, -5, 0))
        calf = _limb_bone(r, n, s, "calf", thigh, (0, -43, 0), twist)
        foot = _limb_bone(r, n, s, "foot", calf, (0, -42, -1), twist)
        if toes:
            ball = r.add(n("ball", s), foot, (0, -6, 12))
            if ends:
                r.add(n("toe_end", s), ball, (0, 0, 5))
    return r


_TWIST_OF = {"lowerarm": "upperarm", "hand": "lowerarm", "calf": "thigh", "foot": "calf"}


def _limb_bone(r, n, s, role, parent, offset, twist):
    """``role`` below ``parent`` at ``offset``, with the parent's twist bone (``"child"``) or half-bone (``"chain"``)."""
    off = np.array(offset, dtype=float)
    if twist == "child":
        r.add(n(_TWIST_OF[role] + "_twist", s), parent, off / 2)
    elif twist == "chain":
        parent = r.add(n(_TWIST_OF[role] + "_twist", s), parent, off / 2)
        off = off / 2
    return r.add(n(role, s), parent, off)


def detect(rig: Rig, z_up_metres=False, **kw) -> BoneMap:
    return detect_bone_map(*rig.arrays(z_up_metres), **kw)


def ue_name(role, side):
    s = side if isinstance(side, str) else side[0] if isinstance(side, tuple) else None
    return {
        "root": "root", "hips": "pelvis", "head": "head", "head_end": "head_end",
        "spine": f"spine_0{side + 1}" if isinstance(side, int) else "", "neck": f"neck_0{side + 1}" if isinstance(side, int)
        else "",
        "clavicle": f"clavicle_{s}", "upperarm": f"upperarm_{s}", "lowerarm": f"lowerarm_{s}", "hand": f"hand_{s}",
        "upperarm_twist": f"upperarm_twist_01_{s}", "lowerarm_twist": f"lowerarm_twist_01_{s}",
        "thigh": f"thigh_{s}", "calf": f"calf_{s}", "foot": f"foot_{s}", "ball": f"ball_{s}",
        "thigh_twist": f"thigh_twist_01_{s}", "calf_twist": f"calf_twist_01_{s}",
        "finger": f"{side[1]}_0{side[2] + 1}_{s}" if isinstance(side, tuple) else "",
    }[role]


def ue_rig(**kw) -> Rig:
    """UE4/UE5 mannequin naming: root, pelvis, spine_01..03, neck_01, head, clavicle/upperarm/lowerarm/hand + twist
    bones and fingers, thigh/calf/foot/ball + twist bones, and the IK helper bones under the root."""
    r = humanoid(ue_name, root=True, twist="child", fingers=True, **kw)
    r.add("ik_foot_root", "root", (0, 0, 0))
    r.add("ik_foot_l", "ik_foot_root", (11, 10, 0))
    r.add("ik_foot_r", "ik_foot_root", (-11, 10, 0))
    r.add("ik_hand_root", "root", (0, 0, 0))
    r.add("ik_hand_gun", "ik_hand_root", (-70, 144, 0))
    r.add("ik_hand_r", "ik_hand_gun", (0, 0, 0))
    r.add("ik_hand_l", "ik_hand_gun", (140, 0, 0))
    return r


UE_MAP = {
    "Hips": "pelvis", "Spine": "spine_01", "Chest": "spine_03", "Neck": "neck_01", "Head": "head",
    **both(Shoulder="clavicle_{s}", UpperArm="upperarm_{s}", LowerArm="lowerarm_{s}", Hand="hand_{s}",
           UpperLeg="thigh_{s}", LowerLeg="calf_{s}", Foot="foot_{s}", Toes="ball_{s}"),
}


def mixamo_name(role, side):
    word = {"l": "Left", "r": "Right"}.get(side[0] if isinstance(side, tuple) else side, "")
    if isinstance(side, tuple):
        return f"mixamorig:{word}Hand{side[1].capitalize()}{side[2] + 1}" if role == "finger" else \
            f"mixamorig:{word}Hand{side[1].capitalize()}4"
    return "mixamorig:" + {
        "hips": "Hips", "spine": f"Spine{side or ''}" if isinstance(side, int) else "Spine", "neck": "Neck",
        "head": "Head", "head_end": "HeadTop_End", "clavicle": f"{word}Shoulder", "upperarm": f"{word}Arm",
        "lowerarm": f"{word}ForeArm", "hand": f"{word}Hand", "thigh": f"{word}UpLeg", "calf": f"{word}Leg",
        "foot": f"{word}Foot", "ball": f"{word}ToeBase", "toe_end": f"{word}Toe_End",
    }[role]


MIXAMO_MAP = {
    "Hips": "mixamorig:Hips", "Spine": "mixamorig:Spine", "Chest": "mixamorig:Spine2", "Neck": "mixamorig:Neck",
    "Head": "mixamorig:Head",
    **both(Shoulder="mixamorig:{side}Shoulder", UpperArm="mixamorig:{side}Arm", LowerArm="mixamorig:{side}ForeArm",
           Hand="mixamorig:{side}Hand", UpperLeg="mixamorig:{side}UpLeg", LowerLeg="mixamorig:{side}Leg",
           Foot="mixamorig:{side}Foot", Toes="mixamorig:{side}ToeBase"),
}


def rigify_def_rig() -> Rig:
    """A generated Rigify rig: DEF- deform bones (limbs split in two, ``.L.001``), ORG- copies under the root, and
    controls (``torso``, ``hips``, ``upper_arm_fk.L``, ``hand_ik.L``...)."""
    def n(role, side):
        S = side.upper() if isinstance(side, str) else None
        base = {"hips": "spine", "head": "spine.006", "clavicle": f"shoulder.{S}", "upperarm": f"upper_arm.{S}",
                "upperarm_twist": f"upper_arm.{S}.001", "lowerarm": f"forearm.{S}", "lowerarm_twist": f"forearm.{S}.001",
                "hand": f"hand.{S}", "thigh": f"thigh.{S}", "thigh_twist": f"thigh.{S}.001", "calf": f"shin.{S}",
                "calf_twist": f"shin.{S}.001", "foot": f"foot.{S}", "ball": f"toe.{S}"}
        if role == "spine":
            return f"DEF-spine.00{side + 1}"
        if role == "neck":
            return f"DEF-spine.00{side + 4}"
        if role == "finger":
            s, f, k = side
            return f"DEF-{'thumb' if f == 'thumb' else 'f_' + f}.0{k + 1}.{s.upper()}"
        return "DEF-" + base[role]

    r = humanoid(n, spine=3, neck=2, twist="chain", fingers=True)
    r.add("root", None, (0, 0, 0))
    for s, x in (("L", 1), ("R", -1)):
        r.add(f"DEF-pelvis.{s}", "DEF-spine", (3 * x, 0, 2))
        r.add(f"DEF-breast.{s}", "DEF-spine.003", (10 * x, -5, 8))
    r.add("torso", "root", (0, 95, 0))
    r.add("hips", "torso", (0, 0, 0))
    r.add("chest", "torso", (0, 20, 0))
    r.add("ORG-spine", "root", (0, 95, 2))
    r.add("ORG-spine.001", "ORG-spine", (0, 10, 0))
    for s, x in (("L", 1), ("R", -1)):
        r.add(f"ORG-thigh.{s}", "ORG-spine", (9 * x, -5, 0))
        r.add(f"ORG-shin.{s}", f"ORG-thigh.{s}", (0, -43, 0))
        r.add(f"upper_arm_fk.{s}", "chest", (17 * x, 29, 0))
        r.add(f"forearm_fk.{s}", f"upper_arm_fk.{s}", (28 * x, 0, 0))
        r.add(f"hand_ik.{s}", "root", (70 * x, 144, 0))
        r.add(f"MCH-thigh_parent.{s}", "hips", (9 * x, -5, 0))
    return r


RIGIFY_MAP = {
    "Hips": "DEF-spine", "Spine": "DEF-spine.001", "Chest": "DEF-spine.003", "Neck": "DEF-spine.004",
    "Head": "DEF-spine.006",
    **both(Shoulder="DEF-shoulder.{S}", UpperArm="DEF-upper_arm.{S}", LowerArm="DEF-forearm.{S}",
           Hand="DEF-hand.{S}", UpperLeg="DEF-thigh.{S}", LowerLeg="DEF-shin.{S}", Foot="DEF-foot.{S}",
           Toes="DEF-toe.{S}"),
}


def smpl_rig() -> Rig:
    """SMPL's 24 joints in SMPL's own (interleaved) order; ``left_hip`` is the thigh, ``left_foot`` the toes,
    ``left_shoulder`` the upper arm."""
    r = Rig()
    for name, parent, off in (
        ("pelvis", None, (0, 93, 0)), ("left_hip", "pelvis", (7, -8, 0)), ("right_hip", "pelvis", (-7, -8, 0)),
        ("spine1", "pelvis", (0, 11, -2)), ("left_knee", "left_hip", (3, -38, 0)), ("right_knee", "right_hip", (-3, -38, 0)),
        ("spine2", "spine1", (0, 13, 0)), ("left_ankle", "left_knee", (-1, -40, -4)),
        ("right_ankle", "right_knee", (1, -40, -4)), ("spine3", "spine2", (0, 5, 1)),
        ("left_foot", "left_ankle", (2, -5, 12)), ("right_foot", "right_ankle", (-2, -5, 12)),
        ("neck", "spine3", (0, 21, -2)), ("left_collar", "spine3", (8, 11, -1)), ("right_collar", "spine3", (-8, 11, -1)),
        ("head", "neck", (0, 7, 5)), ("left_shoulder", "left_collar", (12, 3, -1)),
        ("right_shoulder", "right_collar", (-12, 3, -1)), ("left_elbow", "left_shoulder", (26, -1, -2)),
        ("right_elbow", "right_shoulder", (-26, -1, -2)), ("left_wrist", "left_elbow", (25, 1, 0)),
        ("right_wrist", "right_elbow", (-25, 1, 0)), ("left_hand", "left_wrist", (8, -1, -1)),
        ("right_hand", "right_wrist", (-8, -1, -1)),
    ):
        r.add(name, parent, off)
    return r


SMPL_MAP = {
    "Hips": "pelvis", "Spine": "spine1", "Chest": "spine3", "Neck": "neck", "Head": "head",
    **both(Shoulder="{lower}_collar", UpperArm="{lower}_shoulder", LowerArm="{lower}_elbow", Hand="{lower}_wrist",
           UpperLeg="{lower}_hip", LowerLeg="{lower}_knee", Foot="{lower}_ankle", Toes="{lower}_foot"),
}


def vroid_name(role, side):
    if isinstance(side, tuple):
        return f"J_Bip_{side[0].upper()}_{side[1].capitalize()}{side[2] + 1}"
    c = "C" if side is None or isinstance(side, int) else side.upper()
    return f"J_Bip_{c}_" + {
        "hips": "Hips", "spine": ("Spine", "Chest", "UpperChest")[side] if isinstance(side, int) else "", "neck": "Neck",
        "head": "Head", "clavicle": "Shoulder", "upperarm": "UpperArm", "lowerarm": "LowerArm", "hand": "Hand",
        "thigh": "UpperLeg", "calf": "LowerLeg", "foot": "Foot", "ball": "ToeBase",
    }[role]


def vrm_name(role, side):
    word = {"l": "left", "r": "right"}.get(side if isinstance(side, str) else "", "")
    part = {"hips": "hips", "spine": ("spine", "chest", "upperChest")[side] if isinstance(side, int) else "",
            "neck": "neck", "head": "head", "clavicle": "Shoulder", "upperarm": "UpperArm", "lowerarm": "LowerArm",
            "hand": "Hand", "thigh": "UpperLeg", "calf": "LowerLeg", "foot": "Foot", "ball": "Toes"}[role]
    return "Armature|" + (word + part if word else part)


def makehuman_rig() -> Rig:
    """MakeHuman's default skeleton: root (the hips), spine05 (bottom) .. spine01, neck01..03, clavicle.L ->
    shoulder01.L -> upperarm01/02.L -> lowerarm01/02.L -> wrist.L, pelvis.L -> upperleg01/02.L -> lowerleg01/02.L ->
    foot.L -> toe1-1.L."""
    r = Rig()
    r.add("root", None, (0, 95, 0))
    prev = "root"
    for i in (5, 4, 3, 2, 1):
        prev = r.add(f"spine0{i}", prev, (0, 9, 0))
    for i in (1, 2, 3):
        prev = r.add(f"neck0{i}", prev, (0, 3, 0))
    r.add("head", prev, (0, 9, 0))
    for s, x in (("L", 1), ("R", -1)):
        r.add(f"clavicle.{s}", "spine01", (2 * x, 3, 1))
        r.add(f"shoulder01.{s}", f"clavicle.{s}", (13 * x, 0, -1))
        r.add(f"upperarm01.{s}", f"shoulder01.{s}", (3 * x, 0, 0))
        r.add(f"upperarm02.{s}", f"upperarm01.{s}", (13 * x, 0, 0))
        r.add(f"lowerarm01.{s}", f"upperarm02.{s}", (13 * x, 0, 0))
        r.add(f"lowerarm02.{s}", f"lowerarm01.{s}", (12 * x, 0, 0))
        r.add(f"wrist.{s}", f"lowerarm02.{s}", (12 * x, 0, 0))
        for f in range(1, 6):
            r.add(f"finger{f}-1.{s}", f"wrist.{s}", (8 * x, 0, 3 - f))
        r.add(f"pelvis.{s}", "root", (0, 0, 0))
        r.add(f"upperleg01.{s}", f"pelvis.{s}", (9 * x, -5, 0))
        r.add(f"upperleg02.{s}", f"upperleg01.{s}", (0, -20, 0))
        r.add(f"lowerleg01.{s}", f"upperleg02.{s}", (0, -23, 0))
        r.add(f"lowerleg02.{s}", f"lowerleg01.{s}", (0, -20, 0))
        r.add(f"foot.{s}", f"lowerleg02.{s}", (0, -22, 0))
        for t in range(1, 6):
            r.add(f"toe{t}-1.{s}", f"foot.{s}", ((4 - t) * x, -6, 12))
    return r


MAKEHUMAN_MAP = {
    "Hips": "root", "Spine": "spine05", "Chest": "spine01", "Neck": "neck01", "Head": "head",
    **both(Shoulder="clavicle.{S}", UpperArm="upperarm01.{S}", LowerArm="lowerarm01.{S}", Hand="wrist.{S}",
           UpperLeg="upperleg01.{S}", LowerLeg="lowerleg01.{S}", Foot="foot.{S}", Toes="toe1-1.{S}"),
}


def read_header(path: Path):
    """``names, parents, offsets`` of a BVH file's hierarchy, read by the project's parser (``Boxing_Toes.bvh``
    has more frame lines than it declares, which the strict reader refuses: its header is read alone)."""
    from inbetweening.data.bvh import read_bvh
    from inbetweening.data.bvh_header import MOTION_RE, parse_header
    from inbetweening.data.errors import BVHError

    try:
        bvh = read_bvh(path)
        return bvh.names, bvh.parents, bvh.offsets
    except BVHError:
        data = path.read_bytes()
        m = MOTION_RE.search(data)
        names, parents, offsets, *_ = parse_header(data[:m.start()], data.count(b"\n", 0, m.start()) + 1)
        return list(names), np.array(parents), np.asarray(offsets)


CMU_MAP = {
    "Hips": "Hips", "Spine": "LowerBack", "Chest": "Spine1", "Neck": "Neck", "Head": "Head",
    **both(Shoulder="{side}Shoulder", UpperArm="{side}Arm", LowerArm="{side}ForeArm", Hand="{side}Hand",
           UpperLeg="{side}UpLeg", LowerLeg="{side}Leg", Foot="{side}Foot", Toes="{side}ToeBase"),
}
POSER_MAP = {
    "Hips": "Hips", "Spine": "Ab", "Chest": "Chest", "Neck": "Neck", "Head": "Head",
    **both(Shoulder="{side}Collar", UpperArm="{side}Shoulder", LowerArm="{side}Elbow", Hand="{side}Wrist",
           UpperLeg="{side}Hip", LowerLeg="{side}Knee", Foot="{side}Ankle", Toes="{side}Toes"),
}


def scrambled(names, seed=0):
    """Names that say nothing (``k3f9a2``...), and the way back."""
    rng = np.random.default_rng(seed)
    new = [f"k{rng.integers(16**5):05x}{i}" for i in range(len(names))]
    return new, dict(zip(new, names))


# --------------------------------------------------------------------------------------------
# The slots
# --------------------------------------------------------------------------------------------
def test_slots_are_the_models_joints():
    from inbetweening.predictor.checkpoint import load_predictor

    assert len(SLOTS) == 21 and len(REQUIRED) == 13 and set(REQUIRED) | set(OPTIONAL) == set(SLOTS)
    assert set(OPTIONAL) == {"Chest", "Neck", "Shoulder_L", "Shoulder_R", "Hand_L", "Hand_R", "Toes_L", "Toes_R"}
    sk = load_predictor(MODEL).skeleton
    assert tuple(sk.names) == SLOTS
    assert [SLOT_PARENTS[n] for n in sk.names] == [None if p < 0 else sk.names[p] for p in sk.parents]


def test_the_models_own_skeleton_maps_to_itself():
    """The checkpoint's skeleton (whose zero pose is degenerate: every bone along X) maps by its names alone."""
    from inbetweening.predictor.checkpoint import load_predictor

    sk = load_predictor(MODEL).skeleton
    bm = detect_bone_map(sk.names, sk.parents, sk.offsets)
    assert bm.slots == {s: s for s in SLOTS}
    assert set(bm.how.values()) == {"name (model)"}


@pytest.mark.parametrize("name, side, key", [
    ("mixamorig:LeftForeArm", "L", "forearm"), ("Armature|thigh_l", "L", "thigh"), ("ns:Spine1", None, "spine.1"),
    ("DEF-upper_arm.L.001", "L", "upperarm.1"), ("Bip01 L Thigh", "L", "thigh"), ("Bip001_R_Calf", "R", "calf"),
    ("J_Bip_R_UpperArm", "R", "upperarm"), ("J_Bip_C_UpperChest", None, "upperchest"), ("左腕", "L", "腕"),
    ("右足首", "R", "足首"), ("CC_Base_L_Upperarm", "L", "upperarm"), ("LHipJoint", "L", "hipjoint"),
    ("spine_03", None, "spine.3"), ("toe1-1.R", "R", "toe.1.1"), ("LowerLeg_L", "L", "lowerleg"),
    ("Lowerleg", None, "lowerleg"), ("RootMotion", None, "rootmotion"), ("Armature/Hips", None, "hips"),
    ("lShldrBend", "L", "shldrbend"), ("b_l_upperarm", "L", "upperarm"), ("Character1_RightUpLeg", "R", "upleg"),
    ("LeftHandIndex1", "L", "handindex.1"), ("upperarm_twist_01_l", "L", "upperarmtwist.1"),
])
def test_canonical_names(name, side, key):
    """Namespaces and tool prefixes stripped, camelCase and separators split, the side taken out; a bare L/R only
    as a whole token (never the L of "Lowerleg" or the R of "RootMotion")."""
    c = canonical(name)
    assert (c.side, c.key) == (side, key)


# --------------------------------------------------------------------------------------------
# Real rigs: Debian's assimp-testmodels
# --------------------------------------------------------------------------------------------
@needs_assimp
@pytest.mark.parametrize("file", ["01_01.bvh", "01_03.bvh"])
def test_cmu_bvh(file):
    """CMU (31 joints): LeftShoulder is the clavicle (beside LeftArm); LowerBack the first spine bone, Spine1 the
    chest; LHipJoint, the fingers and the thumbs have no slot."""
    names, parents, offsets = read_header(ASSIMP_BVH / file)
    assert len(names) == 31
    bm = detect_bone_map(names, parents, offsets, where=f"rig '{file}'")
    assert bm.slots == CMU_MAP
    assert set(bm.how.values()) == {"name (CMU)"}


@needs_assimp
def test_poser_bvh():
    """Poser names (Boxing_Toes.bvh): LeftShoulder is the *upper arm* (beside LeftCollar), LeftHip the thigh."""
    bm = detect_bone_map(*read_header(ASSIMP_BVH / "Boxing_Toes.bvh"))
    assert bm.slots == POSER_MAP
    assert set(bm.how.values()) == {"name (Poser)"}


@needs_assimp
@pytest.mark.parametrize("file, truth", [("01_01.bvh", CMU_MAP), ("Boxing_Toes.bvh", POSER_MAP)])
def test_real_rigs_by_structure_alone(file, truth):
    """The same rigs with names that say nothing: the hierarchy and the rest pose give the same map."""
    names, parents, offsets = read_header(ASSIMP_BVH / file)
    new, back = scrambled(names)
    bm = detect_bone_map(new, parents, offsets)
    assert {s: back[b] for s, b in bm.slots.items()} == truth
    assert set(bm.how.values()) == {"structure"}


# --------------------------------------------------------------------------------------------
# Generated rigs in the naming of the common tools
# --------------------------------------------------------------------------------------------
def test_ue_mannequin():
    """UE4/UE5 naming with a static root, IK helper bones, twist bones and fingers."""
    r = ue_rig()
    assert len(r.names) == 68
    bm = detect(r)
    assert bm.slots == UE_MAP
    assert set(bm.how.values()) == {"name (UE mannequin)"}


def test_a_rig_mapped_again_gets_its_map_without_the_detection(monkeypatch):
    """A front end maps its rig on every fill: the same names, parents, offsets and override give the same map from
    memory (the detection is not run); another override or other offsets are detected again, and a rig that cannot be
    mapped fails every time."""
    import inbetweening.runtime.bone_map.detect as detect_module

    names, parents, offsets = ue_rig().arrays(False)
    first = detect_bone_map(names, parents, offsets)
    runs = []
    real = detect_module._detect
    monkeypatch.setattr(detect_module, "_detect", lambda *a: runs.append(1) or real(*a))
    again = detect_bone_map(list(names), list(parents), np.array(offsets, dtype=np.float64))  # equal copies
    assert again == first and runs == []
    again.slots["Head"] = "pelvis"  # the caller's copy: the remembered map stays
    assert detect_bone_map(names, parents, offsets) == first and runs == []
    moved = np.array(offsets, dtype=np.float64)
    moved[1] *= 1.5
    assert detect_bone_map(names, parents, moved).slots == first.slots and runs == [1]
    swapped = detect_bone_map(names, parents, offsets, override={"spine_02": "Chest", "spine_03": None})
    assert swapped.slots["Chest"] == "spine_02" and runs == [1, 1]
    hidden = [n if n != "pelvis" else "thing" for n in names]
    bad = {"thing": None, "thigh_l": None, "thigh_r": None}
    for _ in range(2):
        with pytest.raises(BoneMapError):
            detect_bone_map(hidden, parents, offsets, override=bad)
    assert len(runs) == 4


def test_ue_mannequin_five_spine_bones_two_neck_bones():
    """UE5: spine_01..05, neck_01/02: Spine the first spine bone, Chest the last, Neck the first neck bone."""
    bm = detect(ue_rig(spine=5, neck=2))
    assert bm.slots == {**UE_MAP, "Chest": "spine_05"}


def test_mixamo_with_namespace():
    """Mixamo (``mixamorig:``): LeftShoulder the clavicle, LeftArm the upper arm, LeftUpLeg the thigh, LeftLeg the
    shin; end bones (HeadTop_End, LeftToe_End, finger tips) and fingers have no slot."""
    r = humanoid(mixamo_name, spine=3, fingers=True, ends=True)
    bm = detect(r)
    assert bm.slots == MIXAMO_MAP
    assert set(bm.how.values()) == {"name (Mixamo/LAFAN1)"}


def test_lafan1_names():
    """LAFAN1 (Mixamo names without the namespace, LeftToe): the same map."""
    r = humanoid(mixamo_name, spine=3).renamed(
        lambda n: n.removeprefix("mixamorig:").replace("ToeBase", "Toe"))
    bm = detect(r)
    assert bm.slots == {s: b.removeprefix("mixamorig:").replace("ToeBase", "Toe") for s, b in MIXAMO_MAP.items()}


def test_rigify_deform_bones():
    """A generated Rigify rig: the DEF- bones (not the ORG- copies, the MCH- helpers or the FK/IK controls);
    DEF-spine is the hips, DEF-spine.004 the neck, DEF-spine.006 the head; ``.L.001`` twist segments have no slot."""
    bm = detect(rigify_def_rig())
    assert bm.slots == RIGIFY_MAP
    assert set(bm.how.values()) == {"name (Rigify)"}


def test_rigify_meta_rig():
    """The meta-rig's names (no prefix): spine (hips), spine.001..003, spine.004/005 (neck), spine.006 (head)."""
    r = rigify_def_rig()
    keep = [i for i, n in enumerate(r.names) if n.startswith("DEF-")]
    meta = Rig()
    for i in keep:
        p = r.parents[i]
        meta.add(r.names[i].removeprefix("DEF-"), r.names[p].removeprefix("DEF-") if p >= 0 else None, r.offsets[i])
    bm = detect(meta)
    assert bm.slots == {s: b.removeprefix("DEF-") for s, b in RIGIFY_MAP.items()}


def test_blender_style_names_without_rigify_spine():
    """Blender-style limb names (thigh.L, upper_arm.L) with a bone called hips and spine, spine.001: the hips is
    "hips" (Rigify's reading of "spine" as the hips does not fit this hierarchy)."""
    def n(role, side):
        S = side.upper() if isinstance(side, str) else ""
        return {"hips": "hips", "spine": "spine" if side == 0 else f"spine.00{side}", "neck": "neck", "head": "head",
                "clavicle": f"shoulder.{S}", "upperarm": f"upper_arm.{S}", "lowerarm": f"forearm.{S}",
                "hand": f"hand.{S}", "thigh": f"thigh.{S}", "calf": f"shin.{S}", "foot": f"foot.{S}"}[role]

    bm = detect(humanoid(n, toes=False))
    assert bm.slots == {"Hips": "hips", "Spine": "spine", "Chest": "spine.002", "Neck": "neck", "Head": "head",
                        **both(Shoulder="shoulder.{S}", UpperArm="upper_arm.{S}", LowerArm="forearm.{S}",
                               Hand="hand.{S}", UpperLeg="thigh.{S}", LowerLeg="shin.{S}", Foot="foot.{S}")}


def test_smpl():
    """SMPL: left_hip is the thigh, left_shoulder the upper arm, left_collar the clavicle, left_foot the toes;
    left_hand (past the wrist) has no slot."""
    bm = detect(smpl_rig())
    assert bm.slots == SMPL_MAP
    assert set(bm.how.values()) == {"name (SMPL)"}


@pytest.mark.parametrize("naming", ["vroid", "vrm"])
def test_vrm_and_vroid(naming):
    """VRM humanoid bone names (leftUpperArm, upperChest; here under an ``Armature|`` namespace) and VRoid's
    J_Bip_C_/J_Bip_L_ names: Chest is the upper chest (the spine bone below the neck and the shoulders)."""
    r = humanoid(vroid_name if naming == "vroid" else vrm_name, spine=3, fingers=naming == "vroid")
    bm = detect(r)
    if naming == "vroid":
        truth = {"Hips": "J_Bip_C_Hips", "Spine": "J_Bip_C_Spine", "Chest": "J_Bip_C_UpperChest", "Neck": "J_Bip_C_Neck",
                 "Head": "J_Bip_C_Head",
                 **both(Shoulder="J_Bip_{S}_Shoulder", UpperArm="J_Bip_{S}_UpperArm", LowerArm="J_Bip_{S}_LowerArm",
                        Hand="J_Bip_{S}_Hand", UpperLeg="J_Bip_{S}_UpperLeg", LowerLeg="J_Bip_{S}_LowerLeg",
                        Foot="J_Bip_{S}_Foot", Toes="J_Bip_{S}_ToeBase")}
    else:
        truth = {"Hips": "Armature|hips", "Spine": "Armature|spine", "Chest": "Armature|upperChest",
                 "Neck": "Armature|neck", "Head": "Armature|head",
                 **both(Shoulder="Armature|{lower}Shoulder", UpperArm="Armature|{lower}UpperArm",
                        LowerArm="Armature|{lower}LowerArm", Hand="Armature|{lower}Hand",
                        UpperLeg="Armature|{lower}UpperLeg", LowerLeg="Armature|{lower}LowerLeg",
                        Foot="Armature|{lower}Foot", Toes="Armature|{lower}Toes")}
    assert bm.slots == truth
    assert set(bm.how.values()) == {"name (VRM)"}


def test_makehuman():
    """MakeHuman: root is the hips, spine05 the lowest spine bone, wrist the hand, upperleg01 the thigh; the second
    segments (upperarm02...) and shoulder01 have no slot."""
    bm = detect(makehuman_rig())
    assert bm.slots == MAKEHUMAN_MAP
    assert set(bm.how.values()) == {"name (MakeHuman)"}


def biped_name(role, side):
    S = side.upper() if isinstance(side, str) else ""
    if role == "spine":
        return "Bip01 Spine" + (str(side) if side else "")
    return {"root": "Bip01", "hips": "Bip01 Pelvis", "neck": "Bip01 Neck", "head": "Bip01 Head",
            "clavicle": f"Bip01 {S} Clavicle", "upperarm": f"Bip01 {S} UpperArm", "lowerarm": f"Bip01 {S} Forearm",
            "hand": f"Bip01 {S} Hand", "thigh": f"Bip01 {S} Thigh", "calf": f"Bip01 {S} Calf", "foot": f"Bip01 {S} Foot",
            "ball": f"Bip01 {S} Toe0"}[role]


def cc_name(role, side):
    S = side.upper() if isinstance(side, str) else ""
    if role == "spine":
        return "CC_Base_" + ("Waist", "Spine01", "Spine02")[side]
    return "CC_Base_" + {
        "hips": "Hip", "neck": "NeckTwist01", "head": "Head", "clavicle": f"{S}_Clavicle", "upperarm": f"{S}_Upperarm",
        "lowerarm": f"{S}_Forearm", "hand": f"{S}_Hand", "thigh": f"{S}_Thigh", "calf": f"{S}_Calf", "foot": f"{S}_Foot",
        "ball": f"{S}_ToeBase", "upperarm_twist": f"{S}_UpperarmTwist01", "lowerarm_twist": f"{S}_ForearmTwist01",
        "thigh_twist": f"{S}_ThighTwist01", "calf_twist": f"{S}_CalfTwist01"}[role]


def daz_name(role, side):
    if role == "spine":
        return ("abdomenLower", "abdomenUpper", "chestLower", "chestUpper")[side]
    if role == "neck":
        return ("neckLower", "neckUpper")[side]
    return {"hips": "hip", "head": "head", "clavicle": "{}Collar", "upperarm": "{}ShldrBend", "lowerarm": "{}ForearmBend",
            "hand": "{}Hand", "thigh": "{}ThighBend", "calf": "{}Shin", "foot": "{}Foot", "ball": "{}Toe",
            "upperarm_twist": "{}ShldrTwist", "lowerarm_twist": "{}ForearmTwist", "thigh_twist": "{}ThighTwist",
            "calf_twist": "{}ShinTwist"}[role].format(side)


@pytest.mark.parametrize("preset, rig, truth", [
    ("3ds Max Biped", lambda: humanoid(biped_name, root=True),
     {"Hips": "Bip01 Pelvis", "Spine": "Bip01 Spine", "Chest": "Bip01 Spine2", "Neck": "Bip01 Neck", "Head": "Bip01 Head",
      **both(Shoulder="Bip01 {S} Clavicle", UpperArm="Bip01 {S} UpperArm", LowerArm="Bip01 {S} Forearm",
             Hand="Bip01 {S} Hand", UpperLeg="Bip01 {S} Thigh", LowerLeg="Bip01 {S} Calf", Foot="Bip01 {S} Foot",
             Toes="Bip01 {S} Toe0")}),
    ("Character Creator", lambda: humanoid(cc_name, twist="child"),
     {"Hips": "CC_Base_Hip", "Spine": "CC_Base_Waist", "Chest": "CC_Base_Spine02", "Neck": "CC_Base_NeckTwist01",
      "Head": "CC_Base_Head",
      **both(Shoulder="CC_Base_{S}_Clavicle", UpperArm="CC_Base_{S}_Upperarm", LowerArm="CC_Base_{S}_Forearm",
             Hand="CC_Base_{S}_Hand", UpperLeg="CC_Base_{S}_Thigh", LowerLeg="CC_Base_{S}_Calf", Foot="CC_Base_{S}_Foot",
             Toes="CC_Base_{S}_ToeBase")}),
    ("DAZ", lambda: humanoid(daz_name, spine=4, neck=2, twist="chain"),
     {"Hips": "hip", "Spine": "abdomenLower", "Chest": "chestUpper", "Neck": "neckLower", "Head": "head",
      **both(Shoulder="{s}Collar", UpperArm="{s}ShldrBend", LowerArm="{s}ForearmBend", Hand="{s}Hand",
             UpperLeg="{s}ThighBend", LowerLeg="{s}Shin", Foot="{s}Foot", Toes="{s}Toe")}),
])
def test_biped_character_creator_daz(preset, rig, truth):
    """3ds Max Biped ("Bip01 L Thigh"), Character Creator (CC_Base_, twist bones), DAZ Genesis (lShldrBend with
    lShldrTwist in the chain, abdomenLower..chestUpper, neckLower/Upper)."""
    bm = detect(rig())
    assert bm.slots == truth
    assert set(bm.how.values()) == {f"name ({preset})"}


def test_mmd_japanese_names():
    """MMD (PMX) names: the side as 左/右, the hips the deepest of 腰/グルーブ/センター that holds the upper body and the
    legs (上半身 and 下半身 are siblings), IK bones without a slot."""
    r = Rig()
    for name, parent, off in (("全ての親", None, (0, 0, 0)), ("センター", "全ての親", (0, 80, 0)),
                              ("グルーブ", "センター", (0, 0, 0)), ("腰", "グルーブ", (0, 12, 0)),
                              ("上半身", "腰", (0, 2, 0)), ("上半身2", "上半身", (0, 12, 0)), ("首", "上半身2", (0, 20, 0)),
                              ("頭", "首", (0, 8, 0)), ("下半身", "腰", (0, 0, 0))):
        r.add(name, parent, off)
    for side, x in (("左", 1), ("右", -1)):
        r.add(f"{side}肩", "上半身2", (2 * x, 17, 0))
        r.add(f"{side}腕", f"{side}肩", (14 * x, -3, 0))
        r.add(f"{side}ひじ", f"{side}腕", (24 * x, -10, 0))
        r.add(f"{side}手首", f"{side}ひじ", (22 * x, -9, 0))
        r.add(f"{side}足", "下半身", (8 * x, -5, 0))
        r.add(f"{side}ひざ", f"{side}足", (0, -40, 0))
        r.add(f"{side}足首", f"{side}ひざ", (0, -42, 0))
        r.add(f"{side}つま先", f"{side}足首", (0, -6, 12))
        r.add(f"{side}足ＩＫ", "全ての親", (8 * x, 10, 0))
        r.add(f"{side}つま先ＩＫ", f"{side}足ＩＫ", (0, -6, 12))
    bm = detect(r)
    assert bm.slots == {"Hips": "腰", "Spine": "上半身", "Chest": "上半身2", "Neck": "首", "Head": "頭",
                        **{f"{part}_{s}": f"{side}{bone}" for s, side in (("L", "左"), ("R", "右")) for part, bone in (
                            ("Shoulder", "肩"), ("UpperArm", "腕"), ("LowerArm", "ひじ"), ("Hand", "手首"),
                            ("UpperLeg", "足"), ("LowerLeg", "ひざ"), ("Foot", "足首"), ("Toes", "つま先"))}}
    assert set(bm.how.values()) == {"name (MMD)"}


def a_pose(rig: Rig, seed: int) -> Rig:
    """``rig`` with the arms 45 degrees down (an A-pose rest) and every bone 15 % longer or shorter at random."""
    out = rig.renamed(lambda n: n)
    rng = np.random.default_rng(seed)
    c = np.sqrt(0.5)
    for j, name in enumerate(rig.names):
        up = j
        while up >= 0 and rig.names[up] not in ("upperarm_l", "upperarm_r"):
            up = rig.parents[up]
        x, y, z = rig.offsets[j]
        if up >= 0 and up != j:
            sign = 1.0 if name.endswith("_l") else -1.0
            x, y = c * x + sign * c * y, -sign * c * x + c * y
        out.offsets[j] = [v * rng.uniform(0.85, 1.15) for v in (x, y, z)] if rig.parents[j] >= 0 else [x, y, z]
    return out


@pytest.mark.parametrize("variant", ["Y-up cm", "Z-up m", "facing -Z", "A-pose, proportions +-15 %"])
def test_structure_alone_on_a_ue_like_rig(variant):
    """Random names on the UE-like rig (static root, IK helpers, twist bones, fingers), Y-up cm, Z-up metres, turned
    to face -Z, in an A-pose with other proportions: the structure finds every slot; left is the character's left
    (forward is where the toes point)."""
    r = ue_rig()
    if variant == "facing -Z":
        r.offsets = [[-x, y, -z] for x, y, z in r.offsets]
    if variant.startswith("A-pose"):
        r = a_pose(r, seed=4)
    new, back = scrambled(r.names, seed=1)
    bm = detect(r.renamed(dict(zip(r.names, new)).get), z_up_metres=variant == "Z-up m")
    assert {s: back[b] for s, b in bm.slots.items()} == UE_MAP
    assert set(bm.how.values()) == {"structure"}


def test_structure_alone_on_rigify_split_limbs():
    """Random names on the Rigify deform chain (each limb bone split in two, in the chain itself): the elbow and the
    knee by their place along the limb, not the twist segments."""
    r = rigify_def_rig()
    new, back = scrambled(r.names, seed=2)
    bm = detect(r.renamed(dict(zip(r.names, new)).get))
    got = {s: back[b] for s, b in bm.slots.items()}
    assert got == RIGIFY_MAP


def test_names_and_structure_together():
    """Mixamo names except the toes (renamed "LeftToeStuff"): names give 19 slots, the structure the toes."""
    r = humanoid(mixamo_name, spine=3).renamed(lambda n: n.replace("ToeBase", "ToeStuff"))
    bm = detect(r)
    assert bm.slots == {**MIXAMO_MAP, **both(Toes="mixamorig:{side}ToeStuff")}
    assert bm.how["Toes_L"] == bm.how["Toes_R"] == "structure"
    assert bm.how["Hips"] == "name (Mixamo/LAFAN1)"
    assert "(structure)" in bm.summary()


def test_optional_slots_may_be_absent():
    """One spine bone, no neck, no clavicles, no toes: the 13 required slots and the hands, nothing forced into the
    others."""
    def n(role, side):
        return {"hips": "Hips", "spine": "Spine", "neck": "Neck", "head": "Head", "upperarm": "UpperArm_{}",
                "lowerarm": "LowerArm_{}", "hand": "Hand_{}", "thigh": "UpperLeg_{}", "calf": "LowerLeg_{}",
                "foot": "Foot_{}"}[role].format(str(side).upper())

    bm = detect(humanoid(n, spine=1, neck=0, clavicle=False, toes=False))
    assert set(bm.slots) == set(REQUIRED) | {"Hand_L", "Hand_R"}
    assert bm.slots["Spine"] == "Spine" and bm.slots["Hand_L"] == "Hand_L" and bm.bone("Chest") is None


# --------------------------------------------------------------------------------------------
# Refusals
# --------------------------------------------------------------------------------------------
def quadruped(names: bool = True) -> Rig:
    """A Rigify-animal-like quadruped (Y up, facing +Z): a horizontal spine, four legs down to the ground, a tail."""
    r = Rig()
    r.add("spine", None, (0, 60, -30))
    prev = "spine"
    for i in range(1, 5):
        prev = r.add(f"spine.00{i}", prev, (0, 2, 14))
    r.add("neck", prev, (0, 12, 10))
    r.add("head", "neck", (0, 5, 15))
    prev = "spine"
    for i in range(4):
        prev = r.add(f"tail.00{i}", prev, (0, -2, -8))
    for s, x in (("L", 1), ("R", -1)):
        r.add(f"thigh.{s}", "spine", (8 * x, -5, 0))
        r.add(f"shin.{s}", f"thigh.{s}", (0, -25, -5))
        r.add(f"foot.{s}", f"shin.{s}", (0, -25, 2))
        r.add(f"toe.{s}", f"foot.{s}", (0, -5, 6))
        r.add(f"front_thigh.{s}", "spine.004", (8 * x, -8, 0))
        r.add(f"front_shin.{s}", f"front_thigh.{s}", (0, -25, 0))
        r.add(f"front_foot.{s}", f"front_shin.{s}", (0, -27, 0))
        r.add(f"front_toe.{s}", f"front_foot.{s}", (0, -2, 6))
    if not names:
        new, _ = scrambled(r.names, seed=3)
        return r.renamed(dict(zip(r.names, new)).get)
    return r


@pytest.mark.parametrize("names", [True, False])
def test_a_quadruped_is_refused(names):
    """Four legs and a tail (with Rigify animal names, or none): the front legs are not arms (they reach the ground
    and the spine is level); one line naming the missing slots, and an override template listing every bone."""
    r = quadruped(names)
    with pytest.raises(BoneMapError) as err:
        detect(r, where="rig 'wolf.bvh'")
    msg = str(err.value)
    assert "\n" not in msg
    assert msg.startswith("rig 'wolf.bvh' is not a humanoid the model can fill: no bone found for ")
    assert "UpperArm_L" in msg and "override" in msg
    template = err.value.template
    data = yaml.safe_load(template)
    listed = [line for line in template.splitlines() if line.startswith(('"', '# "'))]
    assert len(listed) == len(r.names)
    if names:
        assert data["thigh.L"] == "UpperLeg_L" and data["head"] == "Head"
        assert "front_thigh.L" not in data


def test_a_snake_is_refused():
    r = Rig()
    prev = r.add("root", None, (0, 0, 0))
    for i in range(30):
        prev = r.add(f"body_{i:02d}", prev, (0, 0, 5))
    r.add("head", prev, (0, 1, 6))
    with pytest.raises(BoneMapError, match=r"^snake is not a humanoid .*no bone found for Spine, UpperArm_L, "
                                           r"LowerArm_L, UpperLeg_L \(\+7 more\); ") as err:
        detect(r, where="snake")
    assert err.value.template.count("\n") > 31


# --------------------------------------------------------------------------------------------
# Overrides
# --------------------------------------------------------------------------------------------
def cmu_like() -> Rig:
    """Mixamo names without the namespace, and CMU's zero-length LHipJoint/RHipJoint."""
    def n(role, side):
        return f"{side.upper()}HipJoint" if role == "hipjoint" else mixamo_name(role, side).removeprefix("mixamorig:")

    return humanoid(n, spine=3, hipjoint=True)


def test_override_moves_a_slot_and_unmaps():
    """``{bone: slot}`` on top of the detection (how = "override"); the bone that had the slot loses it; ``None`` or
    "" unmaps a bone (an optional slot then stays empty)."""
    r = cmu_like()
    base = detect(r).slots
    bm = detect(r, override={"Spine1": "Spine", "LeftToeBase": None, "RightToeBase": ""})
    assert bm.slots["Spine"] == "Spine1" and bm.how["Spine"] == "override"
    assert "Toes_L" not in bm.slots and "Toes_R" not in bm.slots
    assert {s: b for s, b in bm.slots.items() if s != "Spine"} == {s: b for s, b in base.items()
                                                                    if s not in ("Spine", "Toes_L", "Toes_R")}
    # slot names as people write them
    bm = detect(r, override={"Neck": "neck", "Spine1": "spine", "LeftArm": "leftUpperArm"})
    assert bm.slots["Spine"] == "Spine1" and bm.how["UpperArm_L"] == "override"


@pytest.mark.parametrize("override, match", [
    ({"LeftHandd": "Hand_L"}, r"^rig 'x.bvh': the override names bone 'LeftHandd', which the rig does not have "
                              r"\(did you mean 'LeftHand'\?\)$"),
    ({"LeftHand": "Hand_L", "RightHand": "Hand_L"}, r"two bones claim slot Hand_L: 'LeftHand' and 'RightHand'"),
    ({"LeftHand": "Paw_L"}, r"bone 'LeftHand' is given the unknown slot 'Paw_L'"),
    ({"LeftHand": "UpperArm_L"}, r"does not fit the hierarchy: LowerArm_L 'LeftForeArm' is not below UpperArm_L "
                                 r"'LeftHand'"),
    ({"LeftFoot": None}, r"no bone found for Foot_L"),
])
def test_bad_overrides_are_refused(override, match):
    with pytest.raises(BoneMapError, match=match) as err:
        detect(cmu_like(), override=override, where="rig 'x.bvh'")
    assert "\n" not in str(err.value)


def test_saved_map_round_trips(tmp_path):
    """``to_yaml`` writes the override format: read back and applied, it gives the same map (every slot "override")."""
    bm = detect(rigify_def_rig())
    path = tmp_path / "bone_map.yaml"
    path.write_text(bm.to_yaml(), encoding="utf-8")
    override = read_override(path)
    assert override == {b: s for s, b in bm.slots.items()}
    again = detect(rigify_def_rig(), override=override)
    assert again.slots == bm.slots and set(again.how.values()) == {"override"}
    # names YAML would misread unquoted survive: namespaces, a colon, "yes", digits
    odd = BoneMap({"Hips": "mixamorig:Hips", "Spine": "yes", "Head": "01", "Chest": 'a "quoted": name'},
                  {"Hips": "override"})
    path.write_text(odd.to_yaml(), encoding="utf-8")
    assert read_override(path) == {"mixamorig:Hips": "Hips", "yes": "Spine", "01": "Head", 'a "quoted": name': "Chest"}


def test_the_refusal_template_is_an_override_file(tmp_path):
    """The template of a refused rig, filled in (a leg bone for each missing arm slot here, to keep it short), is
    read and applied like any override."""
    r = quadruped()
    with pytest.raises(BoneMapError) as err:
        detect(r)
    path = tmp_path / "t.yaml"
    text = err.value.template
    for bone, slot in (("front_thigh", "UpperArm"), ("front_shin", "LowerArm"), ("front_foot", "Hand")):
        for s in "LR":
            text = text.replace(f'# "{bone}.{s}": ', f'"{bone}.{s}": {slot}_{s}')
    path.write_text(text, encoding="utf-8")
    bm = detect(r, override=read_override(path))
    assert bm.slots["UpperArm_L"] == "front_thigh.L" and bm.how["Hand_R"] == "override"
    assert bm.slots["UpperLeg_L"] == "thigh.L" and bm.how["UpperLeg_L"] == "override"  # a line of the file


@pytest.mark.parametrize("text, match", [
    ("Hips: [1, 2\n", r"^bone map override .*t.yaml: not valid YAML at line 2"),
    ("- Hips\n- Spine\n", r"t.yaml: expected lines `rig_bone: slot`, found a list"),
    ("Hips: Hips\nHips: Spine\n", r"t.yaml: bone 'Hips' is listed twice"),
    ("Hips: Pelvis_L\n", r"t.yaml: bone 'Hips' is given the unknown slot 'Pelvis_L'"),
    ("Hips: 3\n", r"t.yaml: bone 'Hips': the slot must be a name, not 3"),
])
def test_bad_override_files(tmp_path, text, match):
    path = tmp_path / "t.yaml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(BoneMapError, match=match) as err:
        read_override(path)
    assert "\n" not in str(err.value)


def test_missing_override_file(tmp_path):
    with pytest.raises(BoneMapError, match=r"bone map override .*nope.yaml: cannot read it"):
        read_override(tmp_path / "nope.yaml")
    (tmp_path / "empty.yaml").write_text("# nothing\n")
    assert read_override(tmp_path / "empty.yaml") == {}


def test_summary_and_bone():
    bm = detect(ue_rig())
    text = bm.summary()
    assert text.splitlines()[0] == "bone map: 21 of 21 slots (21 by name (UE mannequin))"
    assert "arm L: Shoulder <- clavicle_l, UpperArm <- upperarm_l, LowerArm <- lowerarm_l, Hand <- hand_l" in text
    assert len(text.splitlines()) == 6
    assert bm.bone("Toes_R") == "ball_r" and bm.slot_of("calf_l") == "LowerLeg_L" and bm.slot_of("root") is None
    with pytest.raises(KeyError):
        bm.bone("Tail")


# --------------------------------------------------------------------------------------------
# Bundled without PyTorch
# --------------------------------------------------------------------------------------------
NO_TORCH = BLOCK_TORCH + """
from inbetweening.runtime.bone_map import detect_bone_map
names = ["Hips", "Spine", "Head", "LeftUpLeg", "LeftLeg", "LeftFoot", "RightUpLeg", "RightLeg", "RightFoot",
         "LeftArm", "LeftForeArm", "LeftHand", "RightArm", "RightForeArm", "RightHand"]
parents = [-1, 0, 1, 0, 3, 4, 0, 6, 7, 1, 9, 10, 1, 12, 13]
offsets = [[0, 0, 0]] * 15
print(len(detect_bone_map(names, parents, offsets).slots), sorted(m for m in sys.modules if m.startswith("torch")))
"""


def test_imports_without_torch(tmp_path):
    (tmp_path / "run.py").write_text(NO_TORCH)
    src = str(Path(__file__).resolve().parents[1] / "src")
    proc = subprocess.run([sys.executable, str(tmp_path / "run.py")], capture_output=True, text=True, cwd=tmp_path,
                          env={**os.environ, "PYTHONPATH": src})
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.split("\n")[0] == "15 []"


def test_the_extension_build_bundles_it():
    """The Blender build's import check accepts the module (standard library and numpy at import time)."""
    from inbetweening.blender.build import runtime_modules

    assert "inbetweening.runtime.bone_map" in runtime_modules()
