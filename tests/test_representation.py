"""Model features ``[z-scored global position, local quaternion]`` pinned by a hand-derived pose."""
import numpy as np
import torch

from inbetweening.geometry.skeleton import Skeleton
from inbetweening.predictor import features as F

S2 = np.sqrt(0.5)
SK = Skeleton(("root", "arm"), (-1, 0), np.array([[0.0, 0, 0], [2.0, 0, 0]]))
MEAN = np.array([1.0, 0.0, -1.0, 0.5, 1.0, 2.0])
STD = np.array([2.0, 4.0, 0.5, 1.0, 8.0, 0.25])


def pose():
    """One frame: root at (3, 2, 1) turned 90 degrees about +y; the arm (offset +2x) ends at (3, 2, -1)."""
    root = torch.tensor([[3.0, 2.0, 1.0]], dtype=torch.float64)  # (T=1, 3)
    q = torch.tensor([[[S2, 0, S2, 0], [1.0, 0, 0, 0]]], dtype=torch.float64)  # (1, J=2, 4)
    gp = np.array([[3.0, 2.0, 1.0], [3.0, 2.0, -1.0]])  # Ry(90) takes +x to -z
    return root, q, gp


def test_encode_hand_derived():
    root, q, gp = pose()
    f = F.encode(root, q, SK, MEAN, STD)
    assert f.shape == (1, 2, 7) and F.FEATURES == 7
    want_pos = (gp - MEAN.reshape(2, 3)) / STD.reshape(2, 3)  # per joint coordinate
    np.testing.assert_allclose(f[0, :, F.POS].numpy(), want_pos, atol=1e-14, rtol=0)
    assert torch.equal(f[0, :, F.QUAT], q[0])  # local rotations as given


def test_decode_and_global_positions_invert_encode():
    root, q, gp = pose()
    f = F.encode(root, q, SK, MEAN, STD)
    scaled = f.clone()
    scaled[..., F.QUAT] *= 3.0  # decode normalises
    r, lq = F.decode(scaled, MEAN, STD)
    np.testing.assert_allclose(r.numpy(), root.numpy(), atol=1e-14, rtol=0)
    np.testing.assert_allclose(lq.numpy(), q.numpy(), atol=1e-8, rtol=0)
    np.testing.assert_allclose(F.global_positions(f, MEAN, STD)[0].numpy(), gp, atol=1e-14, rtol=0)
    # batched and float32: statistics follow the features' dtype
    f32 = f.float()[None].expand(3, 1, 2, 7)
    r32, _ = F.decode(f32, MEAN, STD)
    assert r32.dtype == torch.float32 and r32.shape == (3, 1, 3)
    np.testing.assert_allclose(r32[2].numpy(), root.numpy(), atol=1e-5)
