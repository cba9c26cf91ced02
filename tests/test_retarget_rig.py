"""The learned retargeter's rig and features (src/inbetweening/retarget/rig.py)."""
from __future__ import annotations

import numpy as np
import pytest

from inbetweening.data.bvh import read_bvh
from inbetweening.geometry.quaternion import qangle, quat_to_rot6d
from inbetweening.retarget.rig import TargetRig, heading, rot6d_to_quat
from inbetweening.runtime.model import InbetweenError
from retarget_fixtures import CMU, rig_of, source_clips, source_skeleton


@pytest.fixture(scope="module")
def sk():
    return source_skeleton()


@pytest.mark.parametrize("kind", ["cmu", "extras"])
def test_features_decode_back_to_the_analytic_motion(sk, kind):
    """encode_target then decode: the analytic retarget again (positions to 1e-4 of the body), and the position head
    holds the same joints."""
    rig = TargetRig(rig_of(sk, kind), sk)
    c = source_clips(sk, 1)[0]
    lq, lp = rig.analytic(c.root_pos, c.local_q)
    y = rig.encode_target(lq, lp, c.root_pos, c.local_q)
    assert y.shape == (c.num_frames, rig.target_dim()) and rig.encode_source(c.root_pos, c.local_q).shape == (
        c.num_frames, rig.source_dim())
    lq2, lp2, head = rig.decode(y, c.root_pos, c.local_q)
    p = rig.positions(lq, lp)
    assert np.abs(rig.positions(lq2, lp2) - p).max() < 1e-2 and np.abs(head - p).max() < 1e-2


def test_the_extra_bones_are_driven_or_kept(sk):
    """The second spine bone is driven (it is inside the body chain), the twist and finger bones keep the rig's
    reference frame, the static root above the hips is not driven."""
    rig = TargetRig(rig_of(sk, "extras"), sk)
    names = rig.skeleton.names
    driven = {names[j] for j in rig.driven}
    assert "spine_02" in driven and "pelvis" in driven
    assert not driven & {"root", "upperarm_l_twist", "hand_l_finger0_01"}
    c = source_clips(sk, 1)[0]
    lq, _ = rig.analytic(c.root_pos, c.local_q)
    twist = names.index("upperarm_l_twist")
    assert np.allclose(lq[:, twist], rig.ref_q[twist])


def test_copy_by_slot_copies_local_rotations(sk):
    rig = TargetRig(rig_of(sk, "cmu"), sk)
    c = source_clips(sk, 1)[0]
    lq, lp = rig.copy_by_slot(c.root_pos, c.local_q)
    knee = rig.skeleton.names.index("LeftLeg")
    assert np.allclose(lq[:, knee], c.local_q[:, sk.names.index("LowerLeg_L")])
    a_q, a_p = rig.analytic(c.root_pos, c.local_q)  # the hips stand where the analytic retarget puts them
    assert np.allclose(rig.positions(lq, lp)[:, rig.hips], rig.positions(a_q, a_p)[:, rig.hips], atol=1e-6)


def test_rot6d_and_heading():
    rng = np.random.default_rng(0)
    q = rng.normal(size=(50, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    assert np.degrees(qangle(rot6d_to_quat(quat_to_rot6d(q)), q)).max() < 1e-4
    yaw = heading(q, (0.0, 0.0, 1.0))
    assert np.allclose(yaw[:, [1, 3]], 0.0) and np.allclose(np.linalg.norm(yaw, axis=-1), 1.0)


def test_a_rig_without_legs_is_one_line(sk):
    bvh = rig_of(sk, "cmu")
    keep = [j for j, n in enumerate(bvh.names) if "Leg" not in n and "Foot" not in n and "Toe" not in n]
    from inbetweening.data.bvh import BVH

    parents = [keep.index(p) if p >= 0 else -1 for p in bvh.parents[keep]]
    bad = BVH([bvh.names[j] for j in keep], parents, bvh.offsets[keep], [bvh.channels[j] for j in keep], {},
              bvh.frame_time, bvh.motion[:, np.concatenate([np.arange(6) + 6 * j for j in keep])], "legless.bvh")
    with pytest.raises(InbetweenError) as e:
        TargetRig(bad, sk, where="target_rig legless.bvh")
    assert "\n" not in str(e.value) and "legless" in str(e.value)


@pytest.mark.skipif(not CMU.exists(), reason="assimp-testmodels' CMU 01_01.bvh is not installed")
def test_the_real_cmu_skeleton(sk):
    rig = TargetRig(read_bvh(CMU), sk)
    assert rig.skeleton.num_joints == 31 and len(rig.feet) == 4
    c = source_clips(sk, 1)[0]
    lq, lp = rig.analytic(c.root_pos, c.local_q)
    lq2, lp2, _ = rig.decode(rig.encode_target(lq, lp, c.root_pos, c.local_q), c.root_pos, c.local_q)
    assert np.abs(rig.positions(lq2, lp2) - rig.positions(lq, lp)).max() < 1e-2
