"""``inbetweening.data.clips``: clips of a BVH in a model's skeleton and back (a static top joint folded into the
root and unfolded again), and the skeleton check."""
from __future__ import annotations

import numpy as np
import pytest

from inbetweening.data.bvh import BVH
from inbetweening.data.clips import (
    check_skeleton,
    clip_from_bvh,
    clip_in_skeleton,
    fold_static_root,
    motion_in_file,
    top_folds,
    top_is_static,
)
from inbetweening.data.errors import DatasetError
from inbetweening.data.synthetic import generate_clip, make_bvh
from inbetweening.geometry.quaternion import euler_to_quat_np
from inbetweening.geometry.skeleton import fk


def _with_top(bvh: BVH, yaw_deg=30.0, shift=(5.0, 0.0, -7.0), hips_positions: bool = True) -> BVH:
    """The clip under an extra top joint ``joint_Root`` (6 channels, ZXY; a yaw and an offset, fixed or ``(F,)`` and
    ``(F, 3)`` per frame: a moving top joint), its old root's channels re-expressed in it so the world motion is
    unchanged.  ``hips_positions=False``: the old root keeps only its rotation channels (at its offset) and the top
    joint carries the translation (then ``shift`` is ignored)."""
    from inbetweening.geometry.quaternion import qinv, qmul, qrot, quat_to_euler_np

    f = bvh.num_frames
    yaw = np.broadcast_to(np.asarray(yaw_deg, float), (f,))
    top_q = euler_to_quat_np(np.stack([yaw, np.zeros(f), np.zeros(f)], axis=1), "yxz")
    q, root = bvh.local_rotations(), bvh.local_positions()[:, 0]
    hips_q = qmul(qinv(top_q), q[:, 0])
    hips_off = np.array([1.5, 2.0, -0.5])
    if hips_positions:
        top_p = np.broadcast_to(np.asarray(shift, float), (f, 3)).copy()
        hips = np.concatenate([qrot(qinv(top_q), root - top_p), quat_to_euler_np(hips_q, "zyx")], axis=1)
        hips_ch = bvh.channels[0]
    else:
        top_p = root - qrot(top_q, np.broadcast_to(hips_off, (f, 3)))
        hips = quat_to_euler_np(hips_q, "zyx")
        hips_ch = ("Zrotation", "Yrotation", "Xrotation")
    channels = [("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"), hips_ch,
                *bvh.channels[1:]]
    top_motion = np.concatenate([top_p, quat_to_euler_np(top_q, "zxy")], axis=1)
    motion = np.concatenate([top_motion, hips, bvh.motion[:, 6:]], axis=1)
    offsets = np.concatenate([np.zeros((1, 3)), hips_off[None], bvh.offsets[1:]], axis=0)
    return BVH(names=["joint_Root", *bvh.names], parents=np.concatenate([[-1], np.asarray(bvh.parents) + 1]),
               offsets=offsets, channels=channels, end_sites={k + 1: v for k, v in bvh.end_sites.items()},
               frame_time=bvh.frame_time, motion=motion, source="with_top")


def _moving(f: int) -> tuple[np.ndarray, np.ndarray]:
    """A top joint that carries locomotion: yaw (degrees) turning through 100 and a 3 m walk with a sway, per frame."""
    t = np.linspace(0.0, 1.0, f)
    return 100.0 * t - 20.0, np.stack([300.0 * t, 2.0 * np.sin(9 * t), -40.0 * t**2], axis=1)


def _file_fk(bvh: BVH) -> np.ndarray:
    """World positions ``(F, J, 3)`` of every joint of a file, straight from its channels (no folding)."""
    return fk(bvh.local_rotations(), bvh.channel_positions(), list(bvh.parents))[1]


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


@pytest.mark.parametrize("hips_positions", [True, False])
def test_a_moving_top_joint_folds_and_unfolds_by_composition(clip_bvh, hips_positions):
    """A top joint that carries the locomotion (translation and yaw per frame) folds into the root without changing
    the world motion, in the same skeleton as a still one; written back, its channels move between the two given
    rows (raw at them) and the root's channels put the given world motion under it."""
    f = clip_bvh.num_frames
    top = _with_top(clip_bvh, *_moving(f), hips_positions=hips_positions)
    assert np.ptp(top.motion[:, [0, 2, 5]], axis=0).min() > 30 and not top_is_static(top)  # X, Z and yaw move
    folded, root, q = clip_in_skeleton(top, clip_bvh.skeleton())
    clip, sk = fold_static_root(top, "moving")
    assert folded and sk.names == clip_bvh.skeleton().names and np.array_equal(clip.root_pos, root)
    world = _file_fk(top)[:, 1:]  # the file's joints below joint_Root, its own FK
    assert np.abs(sk.pose(root, q)[1] - world).max() <= 1e-6  # lossless (cm)
    assert np.abs(root - world[:, 0]).max() <= 1e-6  # the root's world trajectory is the file's Hips'

    keys = np.array([0, 15, f - 1])
    t = np.arange(f)
    before = np.clip(np.searchsorted(keys, t, side="right") - 1, 0, len(keys) - 2)
    after = before + 1
    w = (t - keys[before]) / (keys[after] - keys[before])
    back = motion_in_file(top, True, root, q, keys[before], top_from=(keys[before], keys[after], w))
    top_cols = slice(0, 6) if hips_positions else slice(3, 6)
    assert np.array_equal(back.motion[keys][:, top_cols], top.motion[keys][:, top_cols])  # raw at the rows
    mid = (keys[0] + keys[1]) // 2
    lerp = top.motion[keys[0], :3] + w[mid] * (top.motion[keys[1], :3] - top.motion[keys[0], :3])
    if hips_positions:  # between the rows the top joint moves between them, not stepping at the nearest
        assert np.abs(back.motion[mid, :3] - lerp).max() < 1e-9
    refolded, _ = fold_static_root(back, "back")
    assert np.abs(refolded.root_pos - root).max() < 1e-4  # the world motion given (Euler degrees in between)
    assert np.abs(sk.pose(refolded.root_pos, refolded.local_q)[1] - world).max() < 1e-3


def test_which_top_joints_fold(clip_bvh):
    """data=bvh folds a top joint with one child where it holds still or sits above a hips-like child (one where the
    body branches), moving or not; never a root that branches itself, nor a moving joint above a plain chain."""
    f = clip_bvh.num_frames
    moving = _with_top(clip_bvh, *_moving(f))
    assert top_folds(_with_top(clip_bvh)) and top_folds(moving) and not top_folds(clip_bvh)
    assert top_is_static(_with_top(clip_bvh)) and not top_is_static(moving)

    def above(bvh: BVH, yaw) -> BVH:  # one more top joint, "Armature", above bvh's
        out = _with_top(bvh, yaw)
        out.names = ["Armature", *out.names[1:]]
        return out
    assert not top_folds(above(moving, _moving(f)[0]))  # moving, above joint_Root: a chain, not where the body branches
    assert top_folds(above(moving, 10.0))  # still: a wrapper wherever it sits


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
