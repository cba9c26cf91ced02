"""``inbetweening.data.clips``: clips of a BVH in a model's skeleton and back (a static top joint folded into the
root and unfolded again), and the skeleton check."""
from __future__ import annotations

import numpy as np
import pytest

from inbetweening.data.bvh import BVH
from inbetweening.data.clips import check_skeleton, clip_from_bvh, clip_in_skeleton, fold_static_root, motion_in_file
from inbetweening.data.errors import DatasetError
from inbetweening.data.synthetic import generate_clip, make_bvh
from inbetweening.geometry.quaternion import euler_to_quat_np


def _with_top(bvh: BVH, yaw_deg: float = 30.0, shift=(5.0, 0.0, -7.0)) -> BVH:
    """The clip under a motionless extra top joint ``joint_Root`` (6 channels, ZXY; a fixed yaw and offset), its
    old root's channels re-expressed in it so the world motion is unchanged."""
    from inbetweening.geometry.quaternion import qinv, qmul, qrot, quat_to_euler_np

    f = bvh.num_frames
    top_q = np.broadcast_to(euler_to_quat_np(np.array([[yaw_deg, 0.0, 0.0]]), "yxz"), (f, 4)).copy()
    top_p = np.broadcast_to(np.asarray(shift, float), (f, 3)).copy()
    q, root = bvh.local_rotations(), bvh.local_positions()[:, 0]
    hips_q = qmul(qinv(top_q), q[:, 0])
    hips_p = qrot(qinv(top_q), root - top_p)
    channels = [("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")] + list(bvh.channels)
    top_motion = np.concatenate([top_p, quat_to_euler_np(top_q, "zxy")], axis=1)
    hips = np.concatenate([hips_p, quat_to_euler_np(hips_q, "zyx")], axis=1)
    motion = np.concatenate([top_motion, hips, bvh.motion[:, 6:]], axis=1)
    offsets = np.concatenate([np.zeros((1, 3)), bvh.offsets], axis=0)
    return BVH(names=["joint_Root", *bvh.names], parents=np.concatenate([[-1], np.asarray(bvh.parents) + 1]),
               offsets=offsets, channels=channels, end_sites={k + 1: v for k, v in bvh.end_sites.items()},
               frame_time=bvh.frame_time, motion=motion, source="with_top")


@pytest.fixture(scope="module")
def clip_bvh() -> BVH:
    q, root = generate_clip(np.random.default_rng(4), 40)
    return make_bvh(q, root)


def test_same_skeleton_is_taken_as_is(clip_bvh):
    folded, root, q = clip_in_skeleton(clip_bvh, clip_bvh.skeleton())
    assert not folded
    assert np.array_equal(root, clip_bvh.local_positions()[:, 0]) and np.array_equal(q, clip_bvh.local_rotations())


def test_a_static_top_joint_folds_and_unfolds_without_changing_the_motion(clip_bvh):
    top = _with_top(clip_bvh)
    folded, root, q = clip_in_skeleton(top, clip_bvh.skeleton())
    assert folded
    sk = clip_bvh.skeleton()
    _, want = sk.pose(clip_bvh.local_positions()[:, 0], clip_bvh.local_rotations())
    _, got = sk.pose(root, q)
    assert np.abs(got - want).max() < 1e-5  # the world motion is the original's (cm; Euler channels in between)
    back = motion_in_file(top, True, root, q, np.arange(top.num_frames))
    assert np.array_equal(back.motion[:, :6], top.motion[:, :6])  # the top joint copied raw from its rows
    assert np.abs(back.motion - top.motion).max() < 1e-5  # everything else through quaternions and back (Euler degrees, cm)


def test_unfolding_takes_the_top_joint_from_the_given_rows(clip_bvh):
    top = _with_top(clip_bvh)
    _, root, q = clip_in_skeleton(top, clip_bvh.skeleton())
    rows = np.zeros(top.num_frames, dtype=np.int64)  # every output frame's top joint from frame 0
    out = motion_in_file(top, True, root, q, rows)
    assert np.array_equal(out.motion[:, :6], np.repeat(top.motion[:1, :6], top.num_frames, axis=0))


def test_another_skeleton_is_one_error_naming_the_first_difference(clip_bvh):
    other = BVH(names=["Root", *clip_bvh.names[1:]], parents=clip_bvh.parents, offsets=clip_bvh.offsets,
                channels=clip_bvh.channels, end_sites=clip_bvh.end_sites, frame_time=clip_bvh.frame_time,
                motion=clip_bvh.motion, source="other.bvh")
    with pytest.raises(DatasetError, match=r"other.bvh has 22 joints.*first difference at joint 0: file 'Root'"):
        clip_in_skeleton(other, clip_bvh.skeleton())
    with pytest.raises(DatasetError, match="expected top joint 'joint_Root'"):
        fold_static_root(other, "other")


def test_check_skeleton_names_the_file(clip_bvh):
    _, sk = clip_from_bvh(clip_bvh, "a")
    assert check_skeleton(None, sk, "a") is sk and check_skeleton(sk, sk, "b") is sk
    short = type(sk)(sk.names[:-1], sk.parents[:-1], sk.offsets[:-1])
    with pytest.raises(DatasetError, match="^b: skeleton differs"):
        check_skeleton(sk, short, "b")


def test_a_dataset_in_another_joint_order_is_the_same_motion(tmp_path):
    from inbetweening.data.datasets import load_dataset

    data = load_dataset("synthetic", cache_dir=str(tmp_path), synthetic={"num_clips": 6, "min_frames": 80,
                                                                         "max_frames": 90, "seed": 1})
    sk = data.skeleton
    legs_swapped = sk.names[:1] + sk.names[5:9] + sk.names[1:5] + sk.names[9:]  # right leg before left: still valid
    other = data.in_joint_order(legs_swapped)
    assert other.skeleton.names == legs_swapped and other.skeleton.names != sk.names
    perm = [sk.names.index(n) for n in legs_swapped]
    c0, c1 = data.train[0], other.train[0]
    gp0 = sk.pose(c0.root_pos, c0.local_q)[1]
    gp1 = other.skeleton.pose(c1.root_pos, c1.local_q)[1]
    assert np.abs(gp1 - gp0[:, perm]).max() < 1e-9  # the same motion, joint for joint by name
    assert np.array_equal(other.pos_mean.reshape(-1, 3), data.pos_mean.reshape(-1, 3)[perm])
    assert np.array_equal(other.test_Q, np.asarray(data.test_Q)[:, :, perm])
    back = other.in_joint_order(sk.names)
    assert back.skeleton.same_topology(sk) and np.array_equal(back.train[0].local_q, c0.local_q)
    assert data.in_joint_order(sk.names) is data
    with pytest.raises(DatasetError, match="puts a joint before its parent"):
        data.in_joint_order(sk.names[1:2] + sk.names[:1] + sk.names[2:])
    with pytest.raises(DatasetError, match="another skeleton"):
        data.in_joint_order(sk.names[:-1])
