"""Quaternion helpers pinned by hand-derived values (independent of the functions under test).

Complements ``test_geometry.py`` (numpy vs torch vs roma agreement) with cases that catch small realistic bugs:
sign conventions, boundary rules of the reference code, precision of float32 inputs, shapes and gradients.
"""
import numpy as np
import pytest
import torch

from inbetweening.geometry import quaternion as Q


def unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def about(axis, rad):
    """Unit quaternion wxyz of a rotation of ``rad`` about the unit ``axis`` (closed form)."""
    a = unit(axis)
    return np.concatenate([[np.cos(rad / 2)], np.sin(rad / 2) * a])


def assert_quat(got, want, atol=2e-9):
    """``got`` equals ``want`` in direction to ``atol`` (qnormalize's eps leaves |got| = 1 - 1e-8)."""
    got = np.asarray(got.detach().numpy() if isinstance(got, torch.Tensor) else got)
    norm = np.linalg.norm(got, axis=-1, keepdims=True)
    np.testing.assert_allclose(norm, 1.0, atol=3e-8, rtol=0)
    np.testing.assert_allclose(got / norm, want, atol=atol, rtol=0)


# ------------------------------------------------------------------ qbetween
def test_qbetween_unnormalised_value_is_the_half_way_formula():
    # w = |a||b| + a.b, xyz = a x b (the reference's unnormalised form), written out by hand
    a, b = np.array([1.0, 2.0, 3.0]), np.array([-2.0, 0.5, 1.0])
    w = np.sqrt(14.0) * np.sqrt(5.25) + (-2.0 + 1.0 + 3.0)
    cross = [2.0 * 1.0 - 3.0 * 0.5, 3.0 * -2.0 - 1.0 * 1.0, 1.0 * 0.5 - 2.0 * -2.0]
    np.testing.assert_allclose(Q.qbetween(a, b), [w, *cross], rtol=1e-14)
    # +x onto 2*(+y): 90 degrees about +z
    np.testing.assert_allclose(Q.qbetween(np.array([1.0, 0, 0]), np.array([0, 2.0, 0])), [2.0, 0, 0, 2.0])


def test_qbetween_rotates_a_onto_b():
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(20, 3)) * 3, rng.normal(size=(20, 3)) * 0.5
    q = Q.qnormalize(Q.qbetween(a, b))
    got = Q.qrot(q, a) / np.linalg.norm(a, axis=-1, keepdims=True)
    np.testing.assert_allclose(got, b / np.linalg.norm(b, axis=-1, keepdims=True), atol=1e-6)  # qnormalize's eps
    qt = Q.qnormalize(Q.qbetween(torch.from_numpy(a), torch.from_numpy(b)))
    np.testing.assert_allclose(qt.numpy(), q, atol=1e-14)


# ------------------------------------------------------------------ remove_discontinuities
@pytest.mark.parametrize("lib", ["numpy", "torch"])
def test_remove_discontinuities_reference_rule_flips_only_negative_dots(lib):
    # the reference flips q_t when dot(q_t, q_{t-1}) < 0; an orthogonal neighbour (dot exactly 0) is kept
    q = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, -0.6, 0.8, 0], [0, -0.8, 0.6, 0]])
    # dots: q1.q0 = 0 (keep), q2.q1 = -0.6 (flip), flipped q2 = (0, .6, -.8, 0) . q3 = -0.96 (flip)
    want = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0.6, -0.8, 0], [0, 0.8, -0.6, 0]])
    x = torch.from_numpy(q) if lib == "torch" else q
    got = Q.remove_discontinuities(x)
    got = got.numpy() if lib == "torch" else got
    np.testing.assert_array_equal(got, want)


# ------------------------------------------------------------------ Euler / matrices
def test_euler_to_quat_shapes_and_float32_input():
    rng = np.random.default_rng(1)
    ang = rng.uniform(-180, 180, size=(2, 5, 3))
    q = Q.euler_to_quat_np(ang, "zxy")
    assert q.shape == (2, 5, 4) and q.dtype == np.float64
    # one rotation written out: zxy = q_z(a) * q_x(b) * q_y(c)
    a, b, c = np.radians(ang[1, 3])
    qz, qx, qy = about([0, 0, 1], a), about([1, 0, 0], b), about([0, 1, 0], c)
    np.testing.assert_allclose(q[1, 3], Q.qmul(Q.qmul(qz, qx), qy), atol=1e-15, rtol=0)
    # float32 angles are converted before the trigonometry (full float64 precision of the float32 values)
    a32 = ang.astype(np.float32)
    np.testing.assert_allclose(Q.euler_to_quat_np(a32, "zxy"), Q.euler_to_quat_np(a32.astype(np.float64), "zxy"),
                               atol=1e-15, rtol=0)


def test_quat_to_matrix_batched_shape():
    q = np.broadcast_to(about([0, 0, 1], np.pi / 2), (2, 3, 4))
    m = Q.quat_to_matrix_np(q)
    assert m.shape == (2, 3, 3, 3)
    np.testing.assert_allclose(m[1, 2], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15, rtol=0)


def test_quat_to_euler_single_quaternion_radians_and_precision():
    q = Q.euler_to_quat_np(np.array([10.0, -20.0, 30.0]), "zxy")
    e = Q.quat_to_euler_np(q, "zxy")  # a single (4,) quaternion -> (3,)
    assert e.shape == (3,)
    np.testing.assert_allclose(e, [10.0, -20.0, 30.0], atol=1e-10)
    np.testing.assert_allclose(Q.quat_to_euler_np(q, "zxy", degrees=False), np.radians([10.0, -20.0, 30.0]),
                               atol=1e-12)
    q32 = q.astype(np.float32)
    np.testing.assert_allclose(Q.quat_to_euler_np(q32, "zxy"), Q.quat_to_euler_np(q32.astype(np.float64), "zxy"),
                               atol=1e-12, rtol=0)


def test_quat_to_euler_bad_order_message():
    with pytest.raises(ValueError, match="three different axes"):
        Q.quat_to_euler_np(np.array([1.0, 0, 0, 0]), "xxy")


@pytest.mark.parametrize("order", ["xyz", "zxy", "yzx", "xzy", "zyx", "yxz"])
@pytest.mark.parametrize("mid", [90.0, -90.0])
def test_quat_to_euler_gimbal_lock_round_trip(order, mid):
    rng = np.random.default_rng(3)
    for first in rng.uniform(-170, 170, size=4):
        ang = np.array([first, mid, 0.0])
        q = Q.euler_to_quat_np(ang, order)
        back = Q.quat_to_euler_np(q, order)
        np.testing.assert_allclose(back[1], mid, atol=1e-4)
        assert back[2] == 0.0  # the convention at the lock: last angle := 0
        r = Q.euler_to_quat_np(back, order)
        assert abs(abs(np.dot(r, q)) - 1.0) < 1e-9  # the same rotation


# ------------------------------------------------------------------ slerp
def test_slerp_orthogonal_endpoints_keep_q1_sign():
    # dot exactly 0: the reference only negates q1 when dot < 0, so the path goes from +q0 towards +q1
    q0, q1 = np.array([1.0, 0, 0, 0]), np.array([0, 1.0, 0, 0])
    want = np.array([np.cos(np.pi / 8), np.sin(np.pi / 8), 0, 0])  # a quarter of the 90-degree arc
    assert_quat(Q.slerp_np(q0, q1, 0.25), want)
    assert_quat(Q.slerp_torch(torch.from_numpy(q0), torch.from_numpy(q1), 0.25), want)


def test_slerp_angle_interpolation_closed_form_and_float32_inputs():
    # rotations about one axis: slerp interpolates the angle
    t = np.array([0.1, 0.5, 0.9])
    q0, q1 = about([0, 1, 0], 0.3), about([0, 1, 0], 2.1)
    want = np.stack([about([0, 1, 0], 0.3 + tt * 1.8) for tt in t])
    assert_quat(Q.slerp_np(q0[None], q1[None], t), want)
    assert_quat(Q.slerp_torch(torch.from_numpy(q0)[None], torch.from_numpy(q1)[None], torch.from_numpy(t)), want)
    # a Python float t is used at the quaternions' precision (float64), on a long arc where float32 would show
    assert_quat(Q.slerp_torch(torch.tensor(about([0, 1, 0], 0.0)), torch.tensor(about([0, 1, 0], 3.0)), 0.3),
                about([0, 1, 0], 0.9))
    # float32 endpoints are taken to float64 before normalising (numpy path)
    a, b = q0.astype(np.float32), q1.astype(np.float32)
    np.testing.assert_allclose(Q.slerp_np(a, b, 0.3), Q.slerp_np(a.astype(np.float64), b.astype(np.float64), 0.3),
                               atol=1e-15, rtol=0)


@pytest.mark.parametrize("lib", ["numpy", "torch"])
def test_slerp_linear_fallback_weights(lib):
    # 1 - |dot| < 0.01: normalised linear blend (1 - t) q0 + t q1 (the reference's fallback)
    q0, q1 = about([1, 0, 0], 0.0), about([1, 0, 0], 0.2)  # dot = cos(0.1) = 0.995
    t = 0.3
    want = unit((1 - t) * q0 + t * q1)
    if lib == "torch":
        got = Q.slerp_torch(torch.from_numpy(q0), torch.from_numpy(q1), t).numpy()
    else:
        got = Q.slerp_np(q0, q1, t)
    assert_quat(got, want)
    # just outside the fallback (dot = cos(0.075) ~ 0.9972 is inside; cos(0.15) ~ 0.9888 is outside): true slerp
    q2 = about([1, 0, 0], 0.3)
    f = Q.slerp_torch if lib == "torch" else Q.slerp_np
    a, b = (torch.from_numpy(q0), torch.from_numpy(q2)) if lib == "torch" else (q0, q2)
    got = f(a, b, t)
    got = got.numpy() if lib == "torch" else got
    assert_quat(got, about([1, 0, 0], 0.09))


def test_slerp_torch_gradient_finite_for_identical_endpoints():
    q = torch.tensor(about([0, 0, 1], 0.7), requires_grad=True)
    r = torch.tensor(about([0, 0, 1], 0.7), requires_grad=True)
    out = Q.slerp_torch(q, r, torch.tensor(0.4, dtype=torch.float64))
    out.sum().backward()
    assert torch.isfinite(q.grad).all() and torch.isfinite(r.grad).all()
    assert_quat(out, about([0, 0, 1], 0.7))


def test_slerp_roma_takes_the_short_arc():
    q0 = torch.tensor([about([0, 1, 0], 0.2)])
    q1 = -torch.tensor([about([0, 1, 0], 0.6)])  # same rotation as +, on the far hemisphere
    got = Q.slerp_roma(q0, q1, torch.tensor([0.5], dtype=torch.float64))[0, 0]
    want = about([0, 1, 0], 0.4)
    assert abs(abs(float((got * torch.from_numpy(want)).sum())) - 1.0) < 1e-12


def test_qnormalize_unit_length_and_zero_stays_finite():
    q = np.array([[3.0, 0, 4.0, 0], [0.0, 0, 0, 0]])
    np.testing.assert_allclose(Q.qnormalize(q), [[0.6, 0, 0.8, 0], [0, 0, 0, 0]], atol=1e-8, rtol=0)
    tiny = Q.qnormalize(torch.tensor([1e-9, 0.0, 0.0, 0.0], dtype=torch.float64))  # below eps: shrinks, never blows up
    assert torch.isfinite(tiny).all() and float(tiny[0]) == pytest.approx(1e-9 / (1e-9 + 1e-8))


def test_qangle_degrees_and_sign_invariance():
    a, b = about([0, 0, 1], 0.2), about([0, 0, 1], 1.2)
    assert Q.qangle(a, b) == pytest.approx(1.0, abs=1e-7)
    assert Q.qangle(a, -b) == pytest.approx(1.0, abs=1e-7)
    t = Q.qangle(torch.from_numpy(np.stack([a, a])), -torch.from_numpy(np.stack([b, a])))
    assert isinstance(t, torch.Tensor) and t.shape == (2,)
    np.testing.assert_allclose(t.numpy(), [1.0, 0.0], atol=1e-7)
    assert Q.qangle(np.stack([a, b]), np.stack([b, b])).shape == (2,)
