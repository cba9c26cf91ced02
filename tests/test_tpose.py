"""The reference poses of a humanoid (runtime/tpose.py), checked with SciPy's rotations and the test's own forward
kinematics: the T-pose points every limb where a T-pose does from any starting pose, the hinges keep their bend's
axis, up is the axis the keys stand along, and the mean pose ignores quaternion signs."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation as R

from inbetweening.geometry.skeleton import Skeleton
from inbetweening.runtime.tpose import mean_pose, tpose, world_up

NAMES = ("Hips", "Spine", "Chest", "Neck", "Head", "Shoulder_L", "UpperArm_L", "LowerArm_L", "Hand_L", "Shoulder_R",
         "UpperArm_R", "LowerArm_R", "Hand_R", "UpperLeg_L", "LowerLeg_L", "Foot_L", "Toes_L", "UpperLeg_R",
         "LowerLeg_R", "Foot_R", "Toes_R")
PARENTS = (-1, 0, 1, 2, 3, 2, 5, 6, 7, 2, 9, 10, 11, 0, 13, 14, 15, 0, 17, 18, 19)
OFFSETS = np.array([[0, 0, 0], [0, 10, 0], [0, 15, 0], [0, 20, 0], [0, 8, 0],  # standing, Y up, a T-pose rest
                    [4, 15, 0], [12, 0, 0], [28, 0, 0], [25, 0, 0], [-4, 15, 0], [-12, 0, 0], [-28, 0, 0], [-25, 0, 0],
                    [9, -5, 0], [0, -42, 0], [0, -40, 0], [0, -6, 12], [-9, -5, 0], [0, -42, 0], [0, -40, 0],
                    [0, -6, 12]], dtype=float)
SLOTS = {n: i for i, n in enumerate(NAMES)}
WANT = {"UpperArm_L": (1, 0, 0), "LowerArm_L": (1, 0, 0), "UpperArm_R": (-1, 0, 0), "LowerArm_R": (-1, 0, 0),
        "UpperLeg_L": (0, -1, 0), "LowerLeg_L": (0, -1, 0), "UpperLeg_R": (0, -1, 0), "LowerLeg_R": (0, -1, 0),
        "Spine": (0, 1, 0), "Chest": (0, 1, 0), "Neck": (0, 1, 0), "Foot_L": (0, 0, 1), "Foot_R": (0, 0, 1)}
CHILD = {"UpperArm_L": "LowerArm_L", "LowerArm_L": "Hand_L", "UpperArm_R": "LowerArm_R", "LowerArm_R": "Hand_R",
         "UpperLeg_L": "LowerLeg_L", "LowerLeg_L": "Foot_L", "UpperLeg_R": "LowerLeg_R", "LowerLeg_R": "Foot_R",
         "Spine": "Chest", "Chest": "Neck", "Neck": "Head", "Foot_L": "Toes_L", "Foot_R": "Toes_R"}


def wxyz(r: R) -> np.ndarray:
    x, y, z, w = np.moveaxis(r.as_quat(), -1, 0)
    return np.stack([w, x, y, z], -1)


def from_wxyz(q) -> R:
    q = np.asarray(q)
    return R.from_quat(np.concatenate([q[..., 1:], q[..., :1]], -1))


def positions(global_q: np.ndarray, offsets: np.ndarray = OFFSETS) -> np.ndarray:
    """The test's own FK from global rotations: each joint at its parent's position plus the parent's rotation of its
    offset."""
    pos = np.zeros((len(PARENTS), 3))
    for j, p in enumerate(PARENTS):
        if p >= 0:
            pos[j] = pos[p] + from_wxyz(global_q[p]).apply(offsets[j])
    return pos


def bone_directions(global_q: np.ndarray, offsets: np.ndarray = OFFSETS) -> dict[str, np.ndarray]:
    pos = positions(global_q, offsets)
    d = {n: pos[SLOTS[c]] - pos[SLOTS[n]] for n, c in CHILD.items()}
    return {n: v / np.linalg.norm(v) for n, v in d.items()}


def local_of_global(g: R) -> np.ndarray:
    out = [wxyz(g[0])]
    for j, p in enumerate(PARENTS[1:], 1):
        out.append(wxyz(g[p].inv() * g[j]))
    return np.array(out)


@pytest.mark.parametrize("seed", range(4))
def test_any_starting_pose_gives_the_same_limb_directions(seed):
    """Start from a random pose (every joint turned up to 50 degrees): the T-pose points each bone where a T-pose
    does (arms out to the sides, legs down, the body up, the feet forward)."""
    rng = np.random.default_rng(seed)
    start = wxyz(R.from_rotvec(rng.uniform(-0.9, 0.9, (len(NAMES), 3))))
    start[0] = (1, 0, 0, 0)
    t = tpose(Skeleton(NAMES, PARENTS, OFFSETS), SLOTS, start=start)
    for name, d in bone_directions(t).items():
        np.testing.assert_allclose(d, WANT[name], atol=1e-6, err_msg=name)


def test_a_bent_knee_keeps_its_bend_axis_in_the_tpose():
    """The shin bent 40 degrees about the thigh's local X (a knee): in the T-pose the knee's hinge axis (thigh x shin)
    is the body's left-right axis, whatever the thigh's twist in the starting pose."""
    for twist in (0.0, 35.0, -70.0):
        g = R.from_quat(np.tile([0, 0, 0, 1.0], (len(NAMES), 1)))
        rots = [R.identity()] * len(NAMES)
        rots[SLOTS["UpperLeg_L"]] = R.from_euler("y", twist, degrees=True)
        rots[SLOTS["LowerLeg_L"]] = R.from_euler("x", 40, degrees=True)
        g = [None] * len(NAMES)
        for j, p in enumerate(PARENTS):
            g[j] = rots[j] if p < 0 else g[p] * rots[j]
        start = local_of_global(R.concatenate(g))
        t = tpose(Skeleton(NAMES, PARENTS, OFFSETS), SLOTS, start=start)
        pos = positions(t)
        thigh = pos[SLOTS["LowerLeg_L"]] - pos[SLOTS["UpperLeg_L"]]
        shin = pos[SLOTS["Foot_L"]] - pos[SLOTS["LowerLeg_L"]]
        axis = np.cross(thigh, shin)
        if np.linalg.norm(axis) > 1e-6:  # bent in the T-pose: about left-right
            assert abs(axis[0]) / np.linalg.norm(axis) > 0.999, twist
        knee_axis = from_wxyz(t[SLOTS["UpperLeg_L"]]).apply([1.0, 0, 0])  # the thigh's own hinge axis (local X)
        assert abs(knee_axis[0]) > 0.999, twist  # turned to the body's left-right: the knee bends forward/back


@pytest.mark.parametrize("turn, up", [(None, (0, 1, 0)), (("x", 90), (0, 0, 1)), (("z", -90), (1, 0, 0)),
                                      (("x", 180), (0, -1, 0))])
def test_up_is_the_axis_the_keys_stand_along(turn, up):
    """The skeleton's rest lies along X (as the model's own zero pose does); its keys stand along the axis the test
    turns them to: that axis is up."""
    lying = OFFSETS @ R.from_euler("z", -90, degrees=True).as_matrix().T  # rest: hips -> head along +X
    sk = Skeleton(NAMES, PARENTS, lying)
    stand = R.from_euler("z", 90, degrees=True) if turn is None else R.from_euler(turn[0], turn[1], degrees=True) * \
        R.from_euler("z", 90, degrees=True)
    keys = np.tile([1.0, 0, 0, 0], (3, len(NAMES), 1))
    keys[:, 0] = wxyz(stand)
    np.testing.assert_array_equal(world_up(sk, SLOTS, keys), up)
    np.testing.assert_array_equal(world_up(sk, SLOTS), (1, 0, 0))  # the rest alone: along X


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_the_mean_pose_ignores_quaternion_signs(seed):
    rng = np.random.default_rng(seed)
    q = wxyz(R.from_rotvec(rng.normal(0, 0.3, (12 * len(NAMES), 3)))).reshape(12, len(NAMES), 4)
    flipped = q * rng.choice([-1.0, 1.0], (12, len(NAMES), 1))
    a, b = mean_pose(q), mean_pose(flipped)
    same = np.abs(np.sum(a * b, -1))  # one rotation: q and -q
    np.testing.assert_allclose(same, 1.0, atol=1e-9)
    np.testing.assert_array_equal(a[0], (1, 0, 0, 0))  # the top joint: no heading
