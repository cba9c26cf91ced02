"""Skeleton and FK/IK pinned by hand-derived poses (a branching tree, so parent lookups matter)."""
import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from inbetweening.geometry.skeleton import Skeleton, fk, ik

S2 = np.sqrt(0.5)
# 90 degrees about +z, wxyz
RZ90 = np.array([S2, 0.0, 0.0, S2])
IDENT = np.array([1.0, 0.0, 0.0, 0.0])

# root(0) -> spine(1) -> head(2); root(0) -> leg(3): joint 3's parent is not joint 2
NAMES = ("root", "spine", "head", "leg")
PARENTS = (-1, 0, 1, 0)
OFFSETS = np.array([[0.0, 0, 0], [1.0, 0, 0], [0.0, 1, 0], [0.0, 0, 2]])


def skel():
    return Skeleton(NAMES, PARENTS, OFFSETS)


def pose():
    """Local rotations (J, 4) and local positions (J, 3) of one frame, with the global result written by hand."""
    q = np.stack([RZ90, RZ90, IDENT, IDENT])
    p = np.array([[1.0, 2.0, 3.0], *OFFSETS[1:]])
    # root: Rz90 at (1,2,3); spine: Rz90*Rz90 = Rz180 at (1,2,3) + Rz90 (1,0,0) = (1,3,3);
    # head: Rz180 at (1,3,3) + Rz180 (0,1,0) = (1,2,3); leg: Rz90 at (1,2,3) + Rz90 (0,0,2) = (1,2,5)
    want_q = np.stack([RZ90, [0.0, 0, 0, 1.0], [0.0, 0, 0, 1.0], RZ90])
    want_p = np.array([[1.0, 2, 3], [1.0, 3, 3], [1.0, 2, 3], [1.0, 2, 5]])
    return q, p, want_q, want_p


@pytest.mark.parametrize("lib", ["numpy", "torch"])
def test_fk_hand_derived_branching_pose(lib):
    q, p, want_q, want_p = pose()
    if lib == "torch":
        gq, gp = fk(torch.from_numpy(q), torch.from_numpy(p), PARENTS)
        gq, gp = gq.numpy(), gp.numpy()
    else:
        gq, gp = fk(q, p, PARENTS)
    np.testing.assert_allclose(gq, want_q, atol=1e-15)
    np.testing.assert_allclose(gp, want_p, atol=1e-15)


def test_ik_inverts_fk_and_method_forms():
    q, p, want_q, want_p = pose()
    lq, lp = ik(want_q, want_p, PARENTS)
    np.testing.assert_allclose(lq, q, atol=1e-15)
    np.testing.assert_allclose(lp, p, atol=1e-15)
    sk = skel()
    np.testing.assert_allclose(sk.fk(q, p)[1], want_p, atol=1e-15)
    np.testing.assert_allclose(sk.ik(want_q, want_p)[0], q, atol=1e-15)
    # batched (B, T, J, ...) with random rotations: ik(fk(x)) == x
    rng = np.random.default_rng(0)
    qr = rng.normal(size=(2, 3, 4, 4))
    qr /= np.linalg.norm(qr, axis=-1, keepdims=True)
    pr = sk.local_positions(rng.normal(size=(2, 3, 3)))
    lq, lp = ik(*fk(qr, pr, PARENTS), PARENTS)
    np.testing.assert_allclose(lq, qr, atol=1e-12)
    np.testing.assert_allclose(lp, pr, atol=1e-12)


@pytest.mark.parametrize("lib", ["numpy", "torch"])
def test_local_positions_root_then_offsets(lib):
    sk = skel()
    root = np.array([[[5.0, 6.0, 7.0], [8.0, 9.0, 10.0]]])  # (1, 2, 3)
    x = torch.from_numpy(root) if lib == "torch" else root
    out = sk.local_positions(x)
    out = out.numpy() if lib == "torch" else out
    assert out.shape == (1, 2, 4, 3)
    np.testing.assert_array_equal(out[0, 1, 0], [8.0, 9.0, 10.0])
    np.testing.assert_array_equal(out[0, 0, 1:], OFFSETS[1:])
    np.testing.assert_array_equal(sk.offsets[0], [0.0, 0, 0])  # the skeleton's own offsets are not modified


def test_adjacency_hops_and_self_loops():
    sk = skel()
    m1 = np.array([[1, 1, 0, 1], [1, 1, 1, 0], [0, 1, 1, 0], [1, 0, 0, 1]], dtype=np.float32)
    np.testing.assert_array_equal(sk.adjacency(1), m1)
    m2 = np.ones((4, 4), dtype=np.float32)
    m2[2, 3] = m2[3, 2] = 0  # head - spine - root - leg: 3 bones apart
    np.testing.assert_array_equal(sk.adjacency(2), m2)
    np.testing.assert_array_equal(sk.adjacency(3), np.ones((4, 4)))
    np.testing.assert_array_equal(sk.adjacency(0), np.eye(4))
    np.testing.assert_array_equal(sk.adjacency(1, self_loops=False), m1 - np.eye(4))
    assert sk.adjacency().dtype == np.float32


def test_offsets_as_plain_values_become_a_float64_table():
    sk = Skeleton(["a", "b"], [-1, 0], [0, 0, 0, 1, 2, 3])  # lists, flat
    assert sk.offsets.shape == (2, 3) and sk.offsets.dtype == np.float64
    np.testing.assert_array_equal(sk.offsets[1], [1.0, 2.0, 3.0])
    assert isinstance(sk.names, tuple) and isinstance(sk.parents, tuple)


def test_structure_helpers():
    sk = skel()
    assert sk.num_joints == 4 and sk.index("leg") == 3
    assert sk.children(0) == [1, 3] and sk.children(2) == []
    np.testing.assert_array_equal(sk.bone_pairs(), [[1, 0], [2, 1], [3, 0]])
    lone = Skeleton(("r",), (-1,), np.zeros((1, 3))).bone_pairs()
    assert lone.shape == (0, 2) and lone.dtype == np.int64
    np.testing.assert_array_equal(sk.adjacency(), sk.adjacency(1))  # default: the parent/child matrix M
    d = sk.to_dict()
    assert d == {"names": list(NAMES), "parents": list(PARENTS), "offsets": OFFSETS.tolist()}
    back = Skeleton.from_dict(d)
    assert back == sk and hash(back) == hash(sk) and back.same_topology(sk)
    other = Skeleton(NAMES, PARENTS, OFFSETS * 2)
    assert other != sk and other.same_topology(sk)
    assert not Skeleton(("a", "b", "c", "d"), PARENTS, OFFSETS).same_topology(sk)
    assert sk != "not a skeleton"


@pytest.mark.parametrize(
    "names, parents, offsets, match",
    [
        (("a", "b"), (-1,), np.zeros((2, 3)), "2 names, 1 parents, 2 offsets"),
        (("a", "b"), (-1, 0), np.zeros((3, 3)), "2 names, 2 parents, 3 offsets"),
        ((), (), np.zeros((0, 3)), r"^Skeleton: joint 0 must be the root \(parent -1\)$"),
        (("a", "b"), (0, 0), np.zeros((2, 3)), r"^Skeleton: joint 0 must be the root"),
        (("a", "b"), (-1, 1), np.zeros((2, 3)), "joint 'b' has parent 1; parents must come first"),
        (("a", "b", "c"), (-1, 2, 0), np.zeros((3, 3)), "joint 'b' has parent 2; parents must come first"),
        (("a", "b"), (-1, -1), np.zeros((2, 3)), "joint 'b' has parent -1"),
    ],
)
def test_invalid_skeletons(names, parents, offsets, match):
    with pytest.raises(ValueError, match=match):
        Skeleton(names, parents, offsets)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.integers(0, 10**6), min_size=1, max_size=30), st.integers(0, 2**31 - 1),
       st.sampled_from([(), (7,), (2, 5)]))
def test_numpy_fk_level_by_level_is_the_joint_by_joint_torch_fk(choices, seed, lead):
    """The numpy path (every joint of one depth at once) and the torch path (joint by joint) on random trees, poses
    and leading axes: the same numbers, bit for bit (float64), so a fill on either library agrees exactly."""
    parents = [-1] + [c % (j + 1) for j, c in enumerate(choices)]  # any tree with parents first
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(*lead, len(parents), 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    p = rng.normal(size=(*lead, len(parents), 3))
    gq, gp = fk(q, p, parents)
    tq, tp = fk(torch.from_numpy(q), torch.from_numpy(p), parents)
    assert np.array_equal(gq, tq.numpy()) and np.array_equal(gp, tp.numpy())


def _fk_joint_by_joint(q, p, parents):
    """The test's own FK: one joint after another, its parent's global rotation times its local one."""
    gq, gp = [q[..., 0, :]], [p[..., 0, :]]
    for j in range(1, len(parents)):
        a = gq[parents[j]]
        w, x, y, z = a.unbind(-1)
        bw, bx, by, bz = q[..., j, :].unbind(-1)
        gq.append(torch.stack([w * bw - x * bx - y * by - z * bz, w * bx + x * bw + y * bz - z * by,
                               w * by - x * bz + y * bw + z * bx, w * bz + x * by - y * bx + z * bw], -1))
        u, v = a[..., 1:], p[..., j, :]
        t = 2.0 * torch.cross(u, v, dim=-1)
        gp.append(v + a[..., :1] * t + torch.cross(u, t, dim=-1) + gp[parents[j]])
    return torch.stack(gq, -2), torch.stack(gp, -2)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.integers(0, 1000), min_size=1, max_size=12), st.integers(0, 2**31 - 1))
def test_torch_fk_level_by_level_matches_joint_by_joint(picks, seed):
    """The torch FK goes level by level (every joint of one depth at once, the joints then put back in order); on any
    tree, its joints in any parents-first order, it equals a joint-by-joint FK to rounding, and gradients flow."""
    parents = [-1] + [pick % (j + 1) for j, pick in enumerate(picks)]  # joint j+1's parent: any joint before it
    g = torch.Generator().manual_seed(seed)
    q = torch.randn(2, 3, len(parents), 4, generator=g, dtype=torch.float64)
    q = (q / q.norm(dim=-1, keepdim=True)).requires_grad_(True)
    p = torch.randn(2, 3, len(parents), 3, generator=g, dtype=torch.float64)
    gq, gp = fk(q, p, parents)
    wq, wp = _fk_joint_by_joint(q, p, parents)
    assert torch.allclose(gq, wq, atol=1e-12) and torch.allclose(gp, wp, atol=1e-12)
    (gp.sum() + gq.sum()).backward()
    assert q.grad is not None and torch.isfinite(q.grad).all()
