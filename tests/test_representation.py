"""The representation package: GlobalPosLocalQuat (``[z-scored global position, local quaternion]``) pinned by a
hand-derived pose, numpy/torch encoding, the registry and the layout every other part asks for."""
import json

import numpy as np
import pytest
import torch

from inbetweening.geometry.skeleton import Skeleton
from inbetweening.representation import (
    DEFAULT_REPRESENTATION,
    REPRESENTATIONS,
    GlobalPosLocalQuat,
    Representation,
    build_representation,
    representation_class,
)

S2 = np.sqrt(0.5)
SK = Skeleton(("root", "arm"), (-1, 0), np.array([[0.0, 0, 0], [2.0, 0, 0]]))
MEAN = np.array([1.0, 0.0, -1.0, 0.5, 1.0, 2.0])
STD = np.array([2.0, 4.0, 0.5, 1.0, 8.0, 0.25])
REP = GlobalPosLocalQuat(SK, MEAN, STD)


def pose():
    """One frame: root at (3, 2, 1) turned 90 degrees about +y; the arm (offset +2x) ends at (3, 2, -1)."""
    root = torch.tensor([[3.0, 2.0, 1.0]], dtype=torch.float64)  # (T=1, 3)
    q = torch.tensor([[[S2, 0, S2, 0], [1.0, 0, 0, 0]]], dtype=torch.float64)  # (1, J=2, 4)
    gp = np.array([[3.0, 2.0, 1.0], [3.0, 2.0, -1.0]])  # Ry(90) takes +x to -z
    return root, q, gp


def test_encode_hand_derived():
    root, q, gp = pose()
    f = REP.encode(root, q)
    assert f.shape == (1, 2, 7) and REP.features == 7
    assert (REP.pos, REP.quat) == (slice(0, 3), slice(3, 7))
    want_pos = (gp - MEAN.reshape(2, 3)) / STD.reshape(2, 3)  # per joint coordinate
    np.testing.assert_allclose(f[0, :, REP.pos].numpy(), want_pos, atol=1e-14, rtol=0)
    assert torch.equal(f[0, :, REP.quat], q[0])  # local rotations as given


def test_decode_and_global_positions_invert_encode():
    root, q, gp = pose()
    f = REP.encode(root, q)
    scaled = f.clone()
    scaled[..., REP.quat] *= 3.0  # decode normalises
    r, lq = REP.decode(scaled)
    np.testing.assert_allclose(r.numpy(), root.numpy(), atol=1e-14, rtol=0)
    np.testing.assert_allclose(lq.numpy(), q.numpy(), atol=1e-8, rtol=0)
    np.testing.assert_allclose(REP.global_positions(f)[0].numpy(), gp, atol=1e-14, rtol=0)
    # normalise_positions is the inverse of global_positions on the position channels
    np.testing.assert_allclose(REP.normalise_positions(REP.global_positions(f)).numpy(), f[..., REP.pos].numpy(),
                               atol=1e-14, rtol=0)
    # batched and float32: statistics follow the features' dtype
    f32 = f.float()[None].expand(3, 1, 2, 7)
    r32, _ = REP.decode(f32)
    assert r32.dtype == torch.float32 and r32.shape == (3, 1, 3)
    np.testing.assert_allclose(r32[2].numpy(), root.numpy(), atol=1e-5)


def _windows(seed=0, b=3, t=20, j=2):
    rng = np.random.default_rng(seed)
    root = np.cumsum(rng.normal(size=(b, t, 3)), axis=1)
    q = rng.normal(size=(b, t, j, 4))
    return root, q / np.linalg.norm(q, axis=-1, keepdims=True)


def test_encode_windows_numpy_torch_and_nan():
    root, q = _windows()
    root[0, 5] = np.nan
    f = REP.encode_windows(root, q)
    ft = REP.encode_windows(torch.from_numpy(root), torch.from_numpy(q), dtype=torch.float64)
    assert f.dtype == torch.float32 and ft.dtype == torch.float64 and f.shape == (3, 20, 2, 7)
    assert torch.isnan(f[0, 5, :, :3]).all() and torch.isfinite(f[1]).all()
    np.testing.assert_allclose(f[1].numpy(), ft[1].numpy(), rtol=1e-6, atol=1e-6)
    # the numpy fast path is the torch path's arithmetic, bit for bit (float64)
    f64 = REP.encode_windows(root, q, dtype=torch.float64)
    assert torch.equal(f64[1:], ft[1:])
    assert torch.equal(torch.from_numpy(REP.encode_np(root, q))[1:], REP.encode(*map(torch.from_numpy, (root, q)))[1:])


def test_position_scale_is_the_mean_std():
    assert REP.position_scale() == pytest.approx(float(STD.mean()), rel=1e-6)


def test_registry_and_layout():
    assert DEFAULT_REPRESENTATION == "global_pos_local_quat" and REPRESENTATIONS[DEFAULT_REPRESENTATION] is GlobalPosLocalQuat
    assert issubclass(GlobalPosLocalQuat, Representation)
    rep = build_representation("global_pos_local_quat", SK, MEAN, STD)
    assert isinstance(rep, GlobalPosLocalQuat) and np.array_equal(rep.mean, MEAN) and np.array_equal(rep.std, STD)
    assert representation_class("global_pos_local_quat") is GlobalPosLocalQuat
    for bad in (lambda: build_representation("euler", SK, MEAN, STD), lambda: representation_class("euler")):
        with pytest.raises(ValueError, match=r"representation: unknown representation 'euler'"):
            bad()
    layout = GlobalPosLocalQuat.layout()
    assert layout == {"features": 7, "position": [0, 3], "rotation": [3, 7]}
    assert json.loads(json.dumps(layout)) == layout  # plain values
    assert GlobalPosLocalQuat.channels() == {"position": slice(0, 3), "rotation": slice(3, 7)}
    meta = rep.metadata()
    assert meta["representation"] == "global_pos_local_quat" and meta["features_per_joint"] == 7
    assert meta["position_slice"] == [0, 3] and meta["quaternion_slice"] == [3, 7]


# ------------------------------------------------------------------ a second representation is one class
class _WithHeight(GlobalPosLocalQuat):
    """A test representation: the method's 7 channels plus each joint's height again as an 8th channel group
    (``height``), so nothing that assumes 7 channels or a fixed layout can pass unnoticed."""

    name = "test_with_height"
    features = 8

    @classmethod
    def channels(cls):
        return {**super().channels(), "height": slice(7, 8)}

    def encode(self, root, local_q):
        f = super().encode(root, local_q)
        return torch.cat([f, f[..., 1:2]], dim=-1)

    def encode_np(self, root, local_q):
        f = super().encode_np(root, local_q)
        return np.concatenate([f, f[..., 1:2]], axis=-1)


def test_a_second_representation_is_one_class(monkeypatch, tmp_path):
    """Registered as one class, it is used by the network's contract, the masks, the predictor (windows in, windows
    out, keys bit-exact), every loss term and the ONNX export, with no other change."""
    from inbetweening import representation as R
    from inbetweening.data.synthetic import PARENTS
    from inbetweening.models import MODELS
    from inbetweening.predictor.predictor import Predictor
    from inbetweening.training.losses import LOSS_TERMS, total_loss

    monkeypatch.setitem(R.REPRESENTATIONS, _WithHeight.name, _WithHeight)
    g = np.random.default_rng(3)
    j = len(PARENTS)
    sk = Skeleton(tuple(f"j{i}" for i in range(j)), PARENTS, g.normal(0, 10, (j, 3)))
    mean, std = g.normal(0, 1, j * 3), g.uniform(1, 5, j * 3)
    hp = {"model": {"name": "graph_transformer", **MODELS["graph_transformer"].TINY, "residual_to_interpolation": True},
          "skeleton": sk.to_dict(), "pos_mean": mean.tolist(), "pos_std": std.tolist(), "centre": "known",
          "representation": _WithHeight.name, "forward_axis": [0.0, 0.0, 1.0]}
    p = Predictor.from_hparams(hp)
    assert p.net.feature_dim == 8 and p.net.quat == slice(3, 7)
    b, t = 2, 14
    root = g.normal(0, 50, (b, t, 3))
    q = g.normal(size=(b, t, j, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    known = p.transition_known(b, t, 3)
    out = p.predict_windows(root, q, known)
    k = known.numpy()
    assert np.array_equal(out.local_q.numpy()[k], q[k]) and np.array_equal(out.root.numpy()[k[..., 0]], root[k[..., 0]])
    assert out.feats.shape == (b, t, j, 8) and torch.isfinite(out.local_q).all()
    # residual model at its zero init: the interpolation exactly (positions lerp, rotations slerp, height held)
    assert torch.allclose(out.root, out.interp_root) and torch.allclose(out.local_q, out.interp_q)
    pred, interp, target = p(torch.as_tensor(root), torch.as_tensor(q), known)
    weights = {k_: 1.0 for k_ in LOSS_TERMS if k_ != "keyframe"}
    loss, terms = total_loss(pred, target, ~known, weights, p.representation)
    loss.backward()
    assert set(terms) == set(weights) and torch.isfinite(loss)
    assert p.representation.metadata()["features_per_joint"] == 8
    ort = pytest.importorskip("onnxruntime")
    assert ort is not None
    from inbetweening.api.export import export_onnx

    info = export_onnx(p, tmp_path / "m.onnx")
    assert info["max_abs_diff"] <= 1e-4


# ------------------------------------------------------------------ foot contact channels
def _walker():
    """A 2-joint 'leg' (root at hip height, a foot 90 cm below) over 8 frames at 30 fps: the foot stands (frames 0-3),
    then the whole body moves 3 cm per frame (90 cm/s: too fast for contact), at the floor."""
    from inbetweening.data.contacts import FootContact
    from inbetweening.representation import GlobalPosLocalQuatContact

    sk = Skeleton(("hip", "foot_l"), (-1, 0), np.array([[0.0, 0, 0], [0.0, -90.0, 0]]))
    rep = GlobalPosLocalQuatContact(sk, np.zeros(6), np.ones(6), contact=FootContact(("foot_l",), 15.0, 30.0), fps=30.0)
    x = np.array([0, 0, 0, 0, 3, 6, 9, 12], dtype=float)
    root = np.stack([x, np.full(8, 92.0), np.zeros(8)], -1)
    q = np.zeros((8, 2, 4))
    q[..., 0] = 1.0
    return rep, root, q


def test_contact_channel_labels_planted_feet():
    rep, root, q = _walker()
    f = rep.encode_windows(root, q, dtype=torch.float64)
    assert f.shape == (8, 2, 8) and rep.channels()["contact"] == slice(7, 8)
    assert f[:, 1, 7].tolist() == [1, 1, 1, 0, 0, 0, 0, 0]  # frame 3 moves on to frame 4: its forward speed is 90 cm/s
    assert f[:, 0, 7].tolist() == [0] * 8  # not a foot
    torch_f = rep.encode(torch.as_tensor(root), torch.as_tensor(q))
    assert torch.equal(torch_f, f)  # numpy and torch: the same labels
    high = root.copy()
    high[:, 1] += 20  # the foot 22 cm above the floor: never planted
    assert rep.encode_windows(high, q, dtype=torch.float64)[:, 1, 7].sum() == 0
    assert torch.equal(rep.contacts(f)[:, 1], f[:, 1, 7])


def test_contact_channel_of_unknown_and_isolated_frames():
    """Unknown (NaN) frames stay NaN; a known frame between unknown ones is judged on its height alone."""
    rep, root, q = _walker()
    root, q = root.copy(), q.copy()
    root[[1, 2, 4, 6]] = np.nan
    q[[1, 2, 4, 6]] = np.nan
    for f in (rep.encode_windows(root, q, dtype=torch.float64)[:, 1, 7],
              rep.encode(torch.as_tensor(root), torch.as_tensor(q))[:, 1, 7]):
        assert torch.isnan(f[[1, 2, 4, 6]]).all()
        assert f[[0, 3, 5, 7]].tolist() == [1.0] * 4  # isolated (frame 7: frame 6 unknown, no frame 8): height only
