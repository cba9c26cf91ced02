"""Left/right mirror maps: derived from joint-name conventions, validated against LAFAN and Bandai-Namco skeletons."""
from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pytest

from inbetweening.data.bvh import BVH, parse_bvh
from inbetweening.data.bvh_writer import format_bvh
from inbetweening.data.clips import fold_static_root
from inbetweening.data.datasets import load_dataset
from inbetweening.data.errors import DatasetError
from inbetweening.data.mirror import derive_mirror, mirror_permutation, side_of, side_pairs, swap_side, validate_mirror
from inbetweening.data.specs import bandai_namco_split
from inbetweening.data.synthetic import NAMES, PARENTS

SHARED_BN2 = Path(__file__).resolve().parents[2] / "shared" / "datasets" / "bandai-namco-2.zip"
# the Bandai-Namco-Research-Motiondataset hierarchy (read from the release's BVH headers)
BN_NAMES = (
    "joint_Root", "Hips", "Spine", "Chest", "Neck", "Head", "Shoulder_L", "UpperArm_L", "LowerArm_L", "Hand_L",
    "Shoulder_R", "UpperArm_R", "LowerArm_R", "Hand_R", "UpperLeg_L", "LowerLeg_L", "Foot_L", "Toes_L",
    "UpperLeg_R", "LowerLeg_R", "Foot_R", "Toes_R",
)  # fmt: skip
BN_PARENTS = (-1, 0, 1, 2, 3, 4, 3, 6, 7, 8, 3, 10, 11, 12, 1, 14, 15, 16, 1, 18, 19, 20)
LAFAN_MIRROR = (
    ("LeftUpLeg", "RightUpLeg"), ("LeftLeg", "RightLeg"), ("LeftFoot", "RightFoot"), ("LeftToe", "RightToe"),
    ("LeftShoulder", "RightShoulder"), ("LeftArm", "RightArm"), ("LeftForeArm", "RightForeArm"), ("LeftHand", "RightHand"),
)  # fmt: skip
BN_MIRROR = (
    ("Shoulder_L", "Shoulder_R"), ("UpperArm_L", "UpperArm_R"), ("LowerArm_L", "LowerArm_R"), ("Hand_L", "Hand_R"),
    ("UpperLeg_L", "UpperLeg_R"), ("LowerLeg_L", "LowerLeg_R"), ("Foot_L", "Foot_R"), ("Toes_L", "Toes_R"),
)  # fmt: skip


def bn_format_bvh(rng: np.random.Generator, frames: int) -> BVH:
    """A Bandai-Namco-format clip: the release's joint names, static joint_Root, 6 channels ZXY on every joint."""
    j = len(BN_NAMES)
    offsets = rng.normal(0, 10, (j, 3))
    offsets[0] = 0.0
    t = np.arange(frames)[:, None] / 30.0
    motion = np.zeros((frames, j, 6))
    motion[:, :, :3] = offsets
    motion[:, 0] = 0.0
    motion[:, 1, :3] = np.concatenate([100 * t, 90 + 2 * np.sin(6 * t), 20 * t], axis=1)
    motion[:, 1:, 3:] = 20 * np.sin(rng.uniform(1, 3, (1, j - 1, 3)) * t[..., None] + rng.uniform(0, 6, (1, j - 1, 3)))
    ch = ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")
    return BVH(list(BN_NAMES), np.array(BN_PARENTS), offsets, [ch] * j, {5: np.array([0, 10.0, 0])}, 1 / 30,
               motion.reshape(frames, -1))


def check_involution(pairs, names, parents):
    perm = mirror_permutation(pairs, names)
    np.testing.assert_array_equal(perm[perm], np.arange(len(names)))  # mirroring twice is the identity
    assert int((perm != np.arange(len(names))).sum()) == 2 * len(pairs)
    # the swap respects the hierarchy: a mirrored joint's parent is the mirror of its parent
    mapped_parents = [-1 if parents[perm[j]] < 0 else int(perm[parents[perm[j]]]) for j in range(len(names))]
    assert mapped_parents == list(parents)
    for left, right in pairs:  # each pair is a left joint and its right counterpart
        assert side_of(left) == "left" and side_of(right) == "right" and perm[names.index(left)] == names.index(right)


def test_side_markers():
    assert swap_side("LeftForeArm") == "RightForeArm" and swap_side("RightToe") == "LeftToe"
    assert swap_side("Hand_L") == "Hand_R" and swap_side("Toes_R") == "Toes_L"
    assert swap_side("Hips") is None and swap_side("Left") is None and swap_side("_L") is None
    assert [side_of(n) for n in ("LeftArm", "Foot_R", "Spine1", "joint_Root")] == ["left", "right", None, None]
    for n in NAMES + BN_NAMES:  # swapping twice gives the name back
        assert swap_side(n) is None or swap_side(swap_side(n)) == n
    assert side_pairs("{}_L", "Hand Foot") == (("Hand_L", "Hand_R"), ("Foot_L", "Foot_R"))
    with pytest.raises(ValueError, match="no left side marker"):
        side_pairs("{}", "Hand")


def test_lafan_and_synthetic_map():
    assert derive_mirror(NAMES) == LAFAN_MIRROR
    assert validate_mirror(LAFAN_MIRROR, NAMES) == LAFAN_MIRROR
    check_involution(LAFAN_MIRROR, list(NAMES), PARENTS)


def test_bandai_namco_format_file_map(tmp_path):
    rng = np.random.default_rng(0)
    bvh = parse_bvh(format_bvh(bn_format_bvh(rng, 80)), "dataset-2_walk_normal_001.bvh")
    _, skel = fold_static_root(bvh, "x")
    assert derive_mirror(skel.names) == BN_MIRROR
    check_involution(BN_MIRROR, list(skel.names), skel.parents)
    # through the registry: the loaded dataset carries the validated map
    zpath = tmp_path / "bn.zip"
    with zipfile.ZipFile(zpath, "w") as z:
        for take in range(1, 12):
            z.writestr(f"data/dataset-2_walk_normal_{take:03d}.bvh", format_bvh(bn_format_bvh(rng, 80)))
    d = load_dataset("bandai_namco", path=zpath, use_cache=False)
    assert d.mirror == BN_MIRROR and d.skeleton.names == BN_NAMES[1:] and len(d.test) == 1


@pytest.mark.skipif(not SHARED_BN2.exists(), reason=f"Bandai-Namco-2 not found at {SHARED_BN2}")
def test_bandai_namco_release_header():
    with zipfile.ZipFile(SHARED_BN2) as z:
        name = next(n for n in sorted(z.namelist()) if bandai_namco_split(n.rsplit("/", 1)[-1]))
        bvh = parse_bvh(z.read(name), name)
    assert tuple(bvh.names) == BN_NAMES and tuple(bvh.parents.tolist()) == BN_PARENTS
    _, skel = fold_static_root(bvh, name)
    assert derive_mirror(skel.names) == BN_MIRROR


@pytest.mark.parametrize(
    "pairs, match",
    [
        ((("LeftArm", "RightArm", "LeftHand"),), "is not a \\(left, right\\) pair"),
        ((("LeftElbow", "RightElbow"),), "joint 'LeftElbow' of pair .* is not in the skeleton"),
        ((("LeftArm", "RightArm"), ("LeftArm", "RightArm")), "joint 'LeftArm' is in more than one pair"),
        ((("RightArm", "LeftArm"),), "\\('RightArm', 'LeftArm'\\) is not a left joint and its right counterpart"),
        ((("LeftArm", "RightHand"),), "is not a left joint and its right counterpart"),
        ((("Spine", "Spine1"),), "is not a left joint"),
        (LAFAN_MIRROR[:-1], "left/right joints \\['LeftHand'\\] have a counterpart in the skeleton but no pair"),
    ],
)
def test_invalid_maps_name_the_problem(pairs, match):
    with pytest.raises(DatasetError, match="^mirror map: .*" + match):
        validate_mirror(pairs, NAMES)


def test_unpaired_side_joint_without_counterpart_is_allowed():
    names = ("Hips", "LeftArm", "RightArm", "LeftProp")  # a prop on one side only: nothing to pair it with
    assert derive_mirror(names) == (("LeftArm", "RightArm"),)
    np.testing.assert_array_equal(mirror_permutation((("LeftArm", "RightArm"),), names), [0, 2, 1, 3])


def test_a_skeleton_missing_one_side_keeps_the_other_pairs():
    names = tuple(n for n in NAMES if n != "RightHand")  # e.g. a LAFAN-format file with a joint dropped
    assert derive_mirror(names) == LAFAN_MIRROR[:-1]
    assert validate_mirror(derive_mirror(names), names) == LAFAN_MIRROR[:-1]
