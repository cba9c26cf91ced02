"""Quaternions, Euler conversion, slerp, continuity, skeleton FK/IK — numpy and torch against each other."""
import numpy as np
import pytest
import roma
import torch

from inbetweening.geometry import quaternion as Q
from inbetweening.geometry.skeleton import Skeleton, fk, ik

ORDERS = ["xyz", "xzy", "yxz", "yzx", "zxy", "zyx"]


def rand_quat(rng, shape):
    q = rng.normal(size=shape + (4,))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def axis_angle(axis, deg):
    a = np.radians(deg) / 2
    v = np.zeros(3)
    v["xyz".index(axis)] = 1
    return np.concatenate([[np.cos(a)], np.sin(a) * v])


def test_qmul_identity_and_inverse():
    rng = np.random.default_rng(0)
    q = rand_quat(rng, (5, 3))
    ident = np.array([1.0, 0, 0, 0])
    np.testing.assert_allclose(Q.qmul(q, ident), q)
    np.testing.assert_allclose(Q.qmul(ident, q), q)
    np.testing.assert_allclose(Q.qmul(q, Q.qinv(q)), np.broadcast_to(ident, q.shape), atol=1e-12)


def test_hamilton_convention():
    # i * j = k in the Hamilton convention
    i, j, k = np.eye(4)[1], np.eye(4)[2], np.eye(4)[3]
    np.testing.assert_allclose(Q.qmul(i, j), k)
    np.testing.assert_allclose(Q.qmul(j, i), -k)


def test_qrot_matches_matrix_and_composition():
    rng = np.random.default_rng(1)
    q, r = rand_quat(rng, (10,)), rand_quat(rng, (10,))
    v = rng.normal(size=(10, 3))
    m = Q.quat_to_matrix_np(q)
    np.testing.assert_allclose(Q.qrot(q, v), np.einsum("nij,nj->ni", m, v), atol=1e-12)
    # rotating by q⊗r = rotate by r then by q
    np.testing.assert_allclose(Q.qrot(Q.qmul(q, r), v), Q.qrot(q, Q.qrot(r, v)), atol=1e-12)
    # 90 degrees about Z takes X to Y
    np.testing.assert_allclose(Q.qrot(axis_angle("z", 90), np.array([1.0, 0, 0])), [0, 1, 0], atol=1e-12)


def test_numpy_and_torch_paths_agree():
    rng = np.random.default_rng(2)
    a, b = rand_quat(rng, (4, 6)), rand_quat(rng, (4, 6))
    v = rng.normal(size=(4, 6, 3))
    ta, tb, tv = (torch.from_numpy(x) for x in (a, b, v))
    np.testing.assert_allclose(Q.qmul(ta, tb).numpy(), Q.qmul(a, b), atol=1e-12)
    np.testing.assert_allclose(Q.qrot(ta, tv).numpy(), Q.qrot(a, v), atol=1e-12)
    np.testing.assert_allclose(Q.qinv(ta).numpy(), Q.qinv(a))
    np.testing.assert_allclose(Q.qbetween(tv, tv.flip(0)).numpy(), Q.qbetween(v, v[::-1]), atol=1e-12)
    np.testing.assert_allclose(Q.qangle(ta, tb).numpy(), Q.qangle(a, b), atol=1e-7)


@pytest.mark.parametrize("order", ORDERS)
def test_euler_to_quat_is_intrinsic_product(order):
    rng = np.random.default_rng(3)
    ang = rng.uniform(-180, 180, size=(7, 3))
    q = Q.euler_to_quat_np(ang, order)
    for n in range(7):
        ref = Q.qmul(Q.qmul(axis_angle(order[0], ang[n, 0]), axis_angle(order[1], ang[n, 1])), axis_angle(order[2], ang[n, 2]))
        np.testing.assert_allclose(q[n], ref, atol=1e-12)
    # torch side (roma) gives the same rotation (up to sign)
    qt = Q.euler_to_quat_torch(torch.from_numpy(ang), order).numpy()
    np.testing.assert_allclose(np.abs(np.sum(qt * q, -1)), 1.0, atol=1e-9)


@pytest.mark.parametrize("order", ORDERS)
def test_euler_round_trip(order):
    rng = np.random.default_rng(4)
    q = rand_quat(rng, (50,))
    back = Q.euler_to_quat_np(Q.quat_to_euler_np(q, order), order)
    np.testing.assert_allclose(np.abs(np.sum(back * q, -1)), 1.0, atol=1e-9)
    # gimbal lock (middle angle +-90) still round-trips as a rotation
    ang = np.array([[30.0, 90.0, 10.0], [-20.0, -90.0, 50.0]])
    q2 = Q.euler_to_quat_np(ang, order)
    back2 = Q.euler_to_quat_np(Q.quat_to_euler_np(q2, order), order)
    np.testing.assert_allclose(np.abs(np.sum(back2 * q2, -1)), 1.0, atol=1e-6)


def test_slerp_endpoints_midpoint_and_torch_agree():
    rng = np.random.default_rng(5)
    q0, q1 = rand_quat(rng, (20,)), rand_quat(rng, (20,))
    np.testing.assert_allclose(np.abs(np.sum(Q.slerp_np(q0, q1, 0.0) * q0, -1)), 1, atol=1e-9)
    np.testing.assert_allclose(np.abs(np.sum(Q.slerp_np(q0, q1, 1.0) * q1, -1)), 1, atol=1e-9)
    mid = Q.slerp_np(q0, q1, 0.5)
    np.testing.assert_allclose(Q.qangle(q0, mid), Q.qangle(mid, q1), atol=1e-7)
    np.testing.assert_allclose(Q.qangle(q0, mid) * 2, Q.qangle(q0, q1), atol=1e-7)
    t = rng.uniform(size=20)
    ours = Q.slerp_torch(torch.from_numpy(q0), torch.from_numpy(q1), torch.from_numpy(t)).numpy()
    np.testing.assert_allclose(ours, Q.slerp_np(q0, q1, t), atol=1e-7)
    # against roma's independent implementation (away from the linear-fallback zone)
    steps = torch.linspace(0, 1, 5, dtype=torch.float64)
    far = np.abs(np.sum(q0 * q1, -1)) < 0.95
    ref = Q.slerp_roma(torch.from_numpy(q0[far]), torch.from_numpy(q1[far]), steps).numpy()
    for i, s in enumerate(steps.numpy()):
        mine = Q.slerp_np(q0[far], q1[far], s)
        np.testing.assert_allclose(np.abs(np.sum(mine * ref[i], -1)), 1, atol=1e-9)


def test_slerp_linear_fallback_for_close_quaternions():
    q0 = axis_angle("x", 0.0)
    q1 = axis_angle("x", 2.0)  # 1 - cos(1 deg) < 0.01 -> linear branch
    out = Q.slerp_np(q0, q1, 0.25)
    lin = 0.75 * q0 + 0.25 * q1
    np.testing.assert_allclose(out, lin / np.linalg.norm(lin), atol=1e-12)


def test_remove_discontinuities_numpy_torch_and_sequential_reference():
    rng = np.random.default_rng(6)
    q = rand_quat(rng, (30, 3))
    q = np.cumsum(q * 0.05, 0) + np.array([1.0, 0, 0, 0])
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    flipped = q * rng.choice([-1.0, 1.0], size=(30, 3, 1))
    fixed = Q.remove_discontinuities(flipped)
    # sequential reference: flip q_t when -q_t is closer to the fixed q_{t-1}
    ref = flipped.copy()
    for t in range(1, 30):
        d = np.sum(ref[t - 1] * ref[t], -1)
        ref[t] = np.where((d < 0)[:, None], -ref[t], ref[t])
    np.testing.assert_allclose(fixed, ref)
    assert (np.sum(fixed[1:] * fixed[:-1], -1) >= 0).all()
    np.testing.assert_allclose(Q.remove_discontinuities(torch.from_numpy(flipped)).numpy(), fixed)


def test_wxyz_xyzw_roundtrip_matches_roma():
    rng = np.random.default_rng(7)
    q = torch.from_numpy(rand_quat(rng, (5,)))
    assert torch.equal(Q.xyzw_to_wxyz(Q.wxyz_to_xyzw(q)), q)
    m = roma.unitquat_to_rotmat(Q.wxyz_to_xyzw(q)).numpy()
    np.testing.assert_allclose(m, Q.quat_to_matrix_np(q.numpy()), atol=1e-12)


# ---------------------------------------------------------------------------------------------
def small_skeleton():
    parents = [-1, 0, 1, 2, 1, 4, 0, 6]
    offsets = np.array([[0, 0, 0], [0, 10, 0], [5, 0, 0], [5, 0, 0], [-5, 0, 0], [-5, 0, 0], [0, -10, 0], [0, -10, 0]], float)
    return Skeleton([f"j{i}" for i in range(8)], parents, offsets)


def test_fk_identity_pose_is_offset_sum():
    sk = small_skeleton()
    q = np.zeros((1, 8, 4))
    q[..., 0] = 1
    _, gp = sk.fk(q, sk.local_positions(np.zeros((1, 3))))
    np.testing.assert_allclose(gp[0, 3], [10, 10, 0])
    np.testing.assert_allclose(gp[0, 7], [0, -20, 0])


def test_fk_rotation_of_parent_moves_children():
    sk = small_skeleton()
    q = np.zeros((8, 4))
    q[:, 0] = 1
    q[1] = axis_angle("z", 90)  # rotate the joint above joints 2-5
    _, gp = sk.fk(q, sk.local_positions(np.zeros(3)))
    np.testing.assert_allclose(gp[2], [0, 15, 0], atol=1e-12)  # (5,0,0) rotated to (0,5,0) above (0,10,0)


def test_fk_ik_round_trip_numpy_and_torch():
    rng = np.random.default_rng(8)
    sk = small_skeleton()
    lq = rand_quat(rng, (3, 5, 8))
    lp = sk.local_positions(rng.normal(size=(3, 5, 3)))
    gq, gp = sk.fk(lq, lp)
    lq2, lp2 = sk.ik(gq, gp)
    np.testing.assert_allclose(lq2, lq, atol=1e-12)
    np.testing.assert_allclose(lp2, lp, atol=1e-10)
    tgq, tgp = fk(torch.from_numpy(lq), torch.from_numpy(lp), sk.parents)
    np.testing.assert_allclose(tgq.numpy(), gq, atol=1e-12)
    np.testing.assert_allclose(tgp.numpy(), gp, atol=1e-12)
    tlq, tlp = ik(tgq, tgp, sk.parents)
    np.testing.assert_allclose(tlq.numpy(), lq, atol=1e-12)


def test_skeleton_adjacency_hops_and_validation():
    sk = small_skeleton()
    m1 = sk.adjacency(1)
    assert m1[1, 0] == m1[0, 1] == 1 and m1[3, 3] == 1 and m1[3, 1] == 0
    m2 = sk.adjacency(2)
    assert m2[3, 1] == 1 and m2[3, 0] == 0
    assert sk.adjacency(1, self_loops=False)[0, 0] == 0
    assert Skeleton.from_dict(sk.to_dict()) == sk
    with pytest.raises(ValueError, match="parents must come first"):
        Skeleton(["a", "b", "c"], [-1, 2, 0], np.zeros((3, 3)))
    with pytest.raises(ValueError, match="root"):
        Skeleton(["a"], [0], np.zeros((1, 3)))
