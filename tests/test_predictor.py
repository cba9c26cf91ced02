"""The Predictor: one object from windows to predictions, built from plain values, restored from checkpoints."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from inbetweening import representation as R
from inbetweening.data import windows as W
from inbetweening.evaluation import benchmark as B
from inbetweening.geometry import canonical
from inbetweening.geometry.quaternion import qrot
from inbetweening.geometry.skeleton import Skeleton
from inbetweening.models import build_network
from inbetweening.models.base import DEFAULT_LAYOUT, FEATURE_DIM
from inbetweening.predictor.checkpoint import CheckpointError, load_predictor, predictor_state, upgrade_module_state
from inbetweening.predictor.masks import JointGaps, transition_known
from inbetweening.predictor.predictor import CENTRES, LEGACY_CENTRE, Predictor, WindowPrediction, check_centre, upgrade_hparams
from inbetweening.training.module import InbetweenModule

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "models" / "bn2_reference" / "model.ckpt"
SK = Skeleton(("root", "spine", "head", "leg"), (-1, 0, 1, 0),
              np.array([[0.0, 0, 0], [0.0, 1.0, 0], [0.0, 1.0, 0], [0.3, -1.0, 0]]))
MEAN = np.linspace(-1, 1, 12)
STD = np.array([2.0, 1.0, 3.0, 0.5, 1.5, 4.0, 1.0, 2.5, 0.25, 3.0, 1.0, 0.75])
MODEL = {"name": "frame_transformer", "d_model": 16, "depth": 1, "heads": 2, "ffn_dim": 16, "dropout": 0.0,
         "max_frames": 64, "residual_to_interpolation": False}


def hparams(**kw) -> dict:
    hp = {"model": MODEL, "skeleton": SK.to_dict(), "pos_mean": MEAN.tolist(), "pos_std": STD.tolist(),
          "mask": "lerp", "centre": "known", "n_past": 10, "forward_axis": [0.0, 0.0, 1.0]}
    return {**hp, **kw}


def predictor(seed=0, **kw) -> Predictor:
    torch.manual_seed(seed)
    p = Predictor.from_hparams(hparams(**kw))
    with torch.no_grad():  # a network that really mixes every input frame
        for prm in p.parameters():
            prm.add_(0.05 * torch.randn_like(prm))
    return p.eval()


def windows(seed=0, b=3, t=18):
    rng = np.random.default_rng(seed)
    root = np.cumsum(rng.normal(size=(b, t, 3)), axis=1) * 5
    q = rng.normal(size=(b, t, 4, 4))
    return root, q / np.linalg.norm(q, axis=-1, keepdims=True)


def test_hparams_round_trip_plain_values_same_predictions():
    p = predictor(1)
    hp = p.hparams()
    assert json.loads(json.dumps(hp)) == hp  # plain values only
    assert hp["centre"] == "known" and hp["representation"] == "global_pos_local_quat"
    q = Predictor.from_hparams(hp)
    q.load_state_dict(p.state_dict())
    assert list(p.state_dict()) == list(q.state_dict()) and all(k.startswith("net.") for k in p.state_dict())
    root, lq = windows()
    a = p.predict_transitions(root, lq, 7)
    b = q.eval().predict_transitions(root, lq, 7)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    untrained = Predictor.from_hparams(hp).eval()
    assert not np.allclose(untrained.predict_transitions(root, lq, 7)[0], a[0], atol=1e-3)


def test_centring_is_required_and_checked():
    hp = hparams()
    del hp["centre"]
    with pytest.raises(ValueError, match=r"centre: required"):
        Predictor.from_hparams(hp)
    assert upgrade_hparams(hp)["centre"] == "window"  # what checkpoints made before the option did
    assert upgrade_hparams(hparams(centre="known"))["centre"] == "known"
    assert set(CENTRES) == {"known", "last", "window"} and LEGACY_CENTRE == "window"
    assert [check_centre(c) for c in CENTRES] == list(CENTRES)
    with pytest.raises(ValueError, match=r"centre must be one of \['known', 'last', 'window'\], got 'middle'"):
        Predictor.from_hparams(hparams(centre="middle"))
    with pytest.raises(ValueError, match=r"centre must be one of .*got 'middle'"):
        check_centre("middle")
    with pytest.raises(TypeError, match="centre"):
        Predictor(torch.nn.Identity(), SK, MEAN, STD, mask="lerp")
    with pytest.raises(TypeError, match="centre"):
        InbetweenModule(model={"name": "interpolation"}, skeleton=SK.to_dict(), pos_mean=MEAN.tolist(),
                        pos_std=STD.tolist())
    with pytest.raises(ValueError, match="mask must be one of"):
        Predictor.from_hparams(hparams(mask="blur"))


@pytest.mark.parametrize("centre", ["known", "last", "window"])
def test_predict_known_values_bit_exact_and_unknown_input_never_read(centre):
    p = predictor(2, centre=centre)
    root, q = windows(2)
    known = p.transition_known(3, 18, 7)
    out = p.predict_windows(root, q, known)
    assert isinstance(out, WindowPrediction) and out.root.dtype == out.local_q.dtype == torch.float64
    assert out.root.shape == (3, 18, 3) and out.local_q.shape == (3, 18, 4, 4) and out.pred.shape == (3, 18, 4, 7)
    k = known[..., 0]
    # known values come back bit-exactly, in the input's frame (prediction and interpolation alike)
    for r, lq in ((out.root, out.local_q), (out.interp_root, out.interp_q)):
        assert torch.equal(r[k], torch.from_numpy(root)[k]) and torch.equal(lq[known], torch.from_numpy(q)[known])
    assert not torch.allclose(out.root[~k], out.interp_root[~k], atol=1e-3)  # the network predicted something
    garbage_r, garbage_q = root.copy(), q.copy()
    garbage_r[:, 10:17], garbage_q[:, 10:17] = np.nan, np.nan
    nan = p.predict_windows(garbage_r, garbage_q, known)
    garbage_r[:, 10:17], garbage_q[:, 10:17] = 1e6, 0.5
    big = p.predict_windows(garbage_r, garbage_q, known)
    assert torch.isfinite(nan.pred).all() and torch.isfinite(nan.root).all() and torch.isfinite(nan.local_q).all()
    for o in (nan, big):
        assert torch.equal(o.pred, out.pred) and torch.equal(o.root, out.root) and torch.equal(o.local_q, out.local_q)
        assert all(torch.equal(torch.as_tensor(a), torch.as_tensor(b)) for a, b in zip(o.frame, out.frame))
    assert not out.pred.requires_grad


def test_training_forward_has_gradients_and_the_target_in_the_canonical_frame():
    p = predictor(3)
    root, q = windows(3)
    known = p.transition_known(3, 18, 7)
    pred, interp, target = p(torch.from_numpy(root), torch.from_numpy(q), known)
    assert pred.requires_grad and pred.shape == target.shape == interp.shape == (3, 18, 4, 7)
    # the target is the input's features in the canonical frame (the one centring stage), not the input's own
    feats, frame = p.canonical_features(root, q, known)
    assert torch.equal(target, feats)
    croot, cq = canonical.canonicalise(root, q, *frame)
    torch.testing.assert_close(target, p.encode(croot, cq))
    assert not torch.allclose(target, p.encode(root, q), atol=1e-2)
    centre_root, _ = p.decode(target)  # known frames' mean root XZ at the origin
    np.testing.assert_allclose(canonical.masked_mean(centre_root[..., [0, 2]], known[..., 0]).numpy(), 0.0, atol=1e-5)
    pred.abs().mean().backward()
    assert any(prm.grad is not None and prm.grad.abs().sum() > 0 for prm in p.parameters())
    _, _, _, raw = p(torch.from_numpy(root), torch.from_numpy(q), known, with_raw=True)
    assert raw.shape == pred.shape
    # legacy "window" is the same frame as "known"
    window = predictor(3, centre="window")
    assert torch.equal(window(root, q, known)[2], target)


# ------------------------------------------------------------------ the canonical frame (the one centring stage)
def _yaw(angle: float) -> np.ndarray:
    return np.array([np.cos(angle / 2), 0.0, np.sin(angle / 2), 0.0])


def test_canonical_frame_hand_derived_known_and_last():
    """forward_axis +Z; the root at the last context frame (9) is turned 0.3 rad about +Y, so it faces
    Ry(0.3) +Z = Ry(0.3 - pi/2) +X: the rotation is that yaw (the other frames' yaws do not count).  ``known``:
    the known frames' mean root XZ (unknown frames are NaN: never read); ``last``: frame 9's root XZ; Y is 0."""
    t = 14
    root = np.zeros((1, t, 3))
    root[0, :, 0] = np.arange(t) * 2.0
    root[0, :, 1] = 90.0
    root[0, :, 2] = -np.arange(t) * 1.0
    q = np.tile(np.array([1.0, 0, 0, 0]), (1, t, 4, 1))
    q[0, :, 0] = _yaw(-0.4)
    q[0, 9, 0] = _yaw(0.3)
    known = torch.from_numpy(transition_known(1, t, 4, 10, 3).numpy())  # frames 0..9 and 13 known
    root[0, 10:13], q[0, 10:13] = np.nan, np.nan
    kf = np.r_[0:10, 13]
    for centre, want_xz in (("known", [root[0, kf, 0].mean(), root[0, kf, 2].mean()]), ("last", [18.0, -9.0])):
        c, rot = predictor(0, centre=centre).canonical_frame(root, q, known)
        assert c.shape == (1, 1, 3) and rot.shape == (1, 1, 4) and isinstance(c, np.ndarray)
        np.testing.assert_allclose(c[0, 0], [want_xz[0], 0.0, want_xz[1]], atol=1e-12)
        np.testing.assert_allclose(np.abs((rot[0, 0] * _yaw(0.3 - np.pi / 2)).sum()), 1.0, atol=1e-9)
        # canonicalised, the root faces +X at the last context frame
        _, cq = canonical.canonicalise(root, q, c, rot)
        fwd = qrot(cq[0, 9, 0], np.array([0.0, 0.0, 1.0]))
        np.testing.assert_allclose(fwd, [1.0, 0.0, 0.0], atol=1e-9)
    assert np.array_equal(predictor(0, centre="window").canonical_frame(root, q, known)[0],
                          predictor(0, centre="known").canonical_frame(root, q, known)[0])


def test_canonical_frame_uses_the_last_context_frame_and_the_roots_known_frames():
    """Per-sample masks: the frame is the last one before the first unknown root value (the first known frame when
    the window starts unknown); the root's known frames decide (other joints' masks do not); NaN is never read."""
    rng = np.random.default_rng(5)
    root = rng.normal(size=(4, 12, 3)) * 10
    q = rng.normal(size=(4, 12, 4, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    known = torch.zeros(4, 12, 4, dtype=torch.bool)
    known[0, :5] = True
    known[0, 11] = True
    known[1, 3:7] = True  # starts unknown: the first known frame
    known[2, 0] = True
    known[3, :, 1:] = True  # other joints known everywhere, the root at frame 6 only
    known[3, 6, 0] = True
    frames = [4, 3, 0, 6]
    root_nan, q_nan = root.copy(), q.copy()
    k = known[..., 0].numpy()
    root_nan[~k] = np.nan
    q_nan[~known.numpy()] = np.nan
    last = predictor(0, centre="last")
    kn = predictor(0, centre="known")
    c_last, rot = last.canonical_frame(root_nan, q_nan, known)
    c_known, rot_known = kn.canonical_frame(root_nan, q_nan, known)
    assert np.isfinite(c_last).all() and np.isfinite(rot).all() and np.isfinite(c_known).all()
    assert np.array_equal(rot, rot_known)  # the rotation does not depend on the centre mode
    for b, f in enumerate(frames):
        np.testing.assert_allclose(c_last[b, 0], [root[b, f, 0], 0.0, root[b, f, 2]], atol=1e-12)
        np.testing.assert_allclose(c_known[b, 0, [0, 2]], root[b, k[b]][:, [0, 2]].mean(0), atol=1e-12)
        want = canonical.facing_rotation(q[b, f, 0], (0.0, 0.0, 1.0))
        np.testing.assert_allclose(rot[b, 0], want / np.linalg.norm(want), atol=1e-12)


def test_canonical_frame_numpy_and_torch_agree():
    p = predictor(0, centre="last")
    root, q = windows(6, b=3, t=18)
    known = p.transition_known(3, 18, 5)
    for centre in ("known", "last"):
        p.centre = centre
        cn, rn = p.canonical_frame(root, q, known)
        ct, rt = p.canonical_frame(torch.from_numpy(root), torch.from_numpy(q), known)
        assert isinstance(ct, torch.Tensor) and ct.dtype == rt.dtype == torch.float64
        np.testing.assert_allclose(ct.numpy(), cn, rtol=0, atol=1e-12)
        np.testing.assert_allclose(rt.numpy(), rn, rtol=0, atol=1e-12)
        fn, _ = p.canonical_features(root, q, known)
        ft, _ = p.canonical_features(torch.from_numpy(root), torch.from_numpy(q), known)
        torch.testing.assert_close(fn, ft, rtol=0, atol=1e-6)


@pytest.mark.parametrize("mask", ["lerp", "zero"])
def test_every_centre_is_leak_free(mask):
    """Change ONLY the ground truth of the frames to predict: the prediction does not change, for every centre mode,
    even when the windows come whole-window-normalised by the benchmark protocol (which does see those frames):
    the predictor re-centres on the known frames only (legacy ``window`` included, which used to leak)."""
    n_past, n = 10, 8
    root, q = windows(1, b=2, t=n_past + n + 1)
    other_root = root.copy()
    other_root[:, n_past : n_past + n] += np.array([40.0, 3.0, -25.0])  # the unknown frames move far away
    other_q = q.copy()
    other_q[:, n_past : n_past + n] = q[:, :1]
    known = transition_known(2, n_past + n + 1, 4, n_past, n)
    for centre in ("known", "last", "window"):
        p = predictor(2, centre=centre, mask=mask)
        outs = []
        for r, qq in ((root, q), (other_root, other_q)):
            Xn, Qn = W.centre_and_rotate(SK.local_positions(r), qq, SK.parents, forward_axis=(0.0, 0.0, 1.0))
            out = p.predict_windows(Xn[:, :, 0], Qn, known)
            assert torch.equal(out.local_q[known], torch.from_numpy(Qn)[known])  # keyframes and context bit-exact
            # compare world positions relative to the first frame's root, which the unknown frames do not move
            gp = p.world_positions(out)
            outs.append((gp - gp[:, :1, :1]).numpy())
        change = np.abs(outs[0] - outs[1]).max()
        assert change < 1e-9, (centre, change)
    # the check can tell: the same windows' known frames moved do change the prediction
    moved = root.copy()
    moved[:, -1] += np.array([40.0, 0.0, -25.0])
    p = predictor(2, mask=mask)
    a, b = (p.world_positions(p.predict_windows(r, q, known)) for r in (root, moved))
    assert not torch.allclose(a[:, n_past : n_past + n] - a[:, :1, :1], b[:, n_past : n_past + n] - b[:, :1, :1],
                              atol=1e-3)


def test_encode_decode_and_the_benchmark_contract():
    p = predictor(4)
    root, q = windows(4, b=5)
    feats = p.encode(root, q, dtype=torch.float64)
    r, lq = p.decode(feats)
    np.testing.assert_allclose(r.numpy(), root, atol=1e-9)
    np.testing.assert_allclose(lq.numpy(), q, atol=1e-8)
    np.testing.assert_allclose(p.global_positions(feats).numpy(), SK.pose(root, q)[1], atol=1e-9)
    holes_r, holes_q = root.copy(), q.copy()
    holes_r[:, 10:17], holes_q[:, 10:17] = np.nan, np.nan
    pr, pq = p.predict_transitions(holes_r, holes_q, 7)
    assert pr.shape == (5, 7, 3) and pq.shape == (5, 7, 4, 4) and pr.dtype == np.float64
    small = p.predict_transitions(holes_r, holes_q, 7, batch_size=2)
    np.testing.assert_allclose(pr, small[0], atol=1e-5)
    # the same numbers as the parts: encode -> predict -> decode, transition frames
    known = p.transition_known(5, 18, 7)
    out = p.predict_windows(root, q, known)
    assert np.array_equal(pr, out.root[:, 10:17].numpy()) and np.array_equal(pq, out.local_q[:, 10:17].numpy())
    want_r, want_q = canonical.uncanonicalise(*p.decode(out.pred), *out.frame)  # decode, back to the input's frame
    np.testing.assert_allclose(pr, want_r[:, 10:17].numpy(), atol=1e-9)
    np.testing.assert_allclose(pq, want_q[:, 10:17].numpy(), atol=1e-12)
    # world_positions: the predicted position channels in the input frame; on the known frames FK of the input
    np.testing.assert_allclose(p.world_positions(out)[known].numpy(), SK.pose(root, q)[1][known.numpy()], atol=1e-4)


def test_predict_transitions_matches_the_numpy_interpolation_and_ignores_batching():
    root, q = windows(3, b=5, t=10 + 7 + 1)
    root[:, 10:17] = np.nan
    q[:, 10:17] = np.nan
    for centre in ("known", "last", "window"):
        interp = Predictor.from_hparams(hparams(model={"name": "interpolation"}, centre=centre)).eval()
        r, qq = interp.predict_transitions(root, q, 7)
        assert r.dtype == np.float64 and r.shape == (5, 7, 3) and qq.shape == (5, 7, 4, 4)
        wr, wq = B.interpolation(root, q, 7)
        w = np.linspace(0, 1, 9)[1:-1]  # the torch path uses exact weights; the numpy reference float32 ones
        np.testing.assert_allclose(r, root[:, 9:10] + w[None, :, None] * (root[:, 17:18] - root[:, 9:10]), atol=1e-5)
        np.testing.assert_allclose(np.abs((qq * wq).sum(-1)), 1.0, atol=1e-5)
    p = predictor(4)
    big = p.predict_transitions(root, q, 7)
    small = p.predict_transitions(root, q, 7, batch_size=2)
    np.testing.assert_allclose(big[0], small[0], atol=1e-5)
    np.testing.assert_allclose(big[1], small[1], atol=1e-6)
    other = predictor(4, n_past=8).predict_transitions(root[:, 2:], q[:, 2:], 7)
    assert other[0].shape == (5, 7, 3)


def test_representation_registry_and_layout():
    rep = R.build_representation("global_pos_local_quat", SK, MEAN, STD)
    assert (rep.features, rep.pos, rep.quat) == (7, slice(0, 3), slice(3, 7))
    with pytest.raises(ValueError, match=r"representation: unknown representation 'euler'"):
        R.build_representation("euler", SK, MEAN, STD)
    meta = {k: json.loads(v) for k, v in predictor(6).metadata(["x", "known"]).items()}
    assert meta["features_per_joint"] == 7 and meta["position_slice"] == [0, 3]
    assert meta["quaternion_slice"] == [3, 7] and meta["centre"] == "known" and meta["inputs"] == ["x", "known"]
    x, known, interp = predictor(6).example_inputs(2, 5)
    assert x.shape == (2, 16, 4, 7) and torch.equal(x[known], interp[known])
    np.testing.assert_allclose(x[..., 3:].norm(dim=-1).numpy(), 1.0, atol=1e-5)


# ------------------------------------------------------------------ checkpoints
def _lightning_checkpoint(module: InbetweenModule, path: Path, old: bool) -> Path:
    """A checkpoint as Lightning writes it; ``old``: the layout before the predictor (``net.*``, no centre)."""
    sd = dict(module.state_dict())
    hp = dict(module.hparams)
    if old:
        sd = {k.replace("predictor.", "", 1): v for k, v in sd.items()}
        hp.pop("centre")
        hp.pop("representation")
    torch.save({"state_dict": sd, "hyper_parameters": hp, "pytorch-lightning_version": "2.5.0"}, path)
    return path


@pytest.mark.parametrize("old", [True, False])
def test_old_and_new_checkpoint_layouts_load(tmp_path, old):
    torch.manual_seed(0)
    module = InbetweenModule(model=MODEL, skeleton=SK.to_dict(), pos_mean=MEAN.tolist(), pos_std=STD.tolist(),
                             forward_axis=(0.0, 0.0, 1.0), centre="window")
    with torch.no_grad():
        for prm in module.parameters():
            prm.add_(0.05 * torch.randn_like(prm))
    assert all(k.startswith("predictor.net.") for k in module.state_dict())
    path = _lightning_checkpoint(module.eval(), tmp_path / "m.ckpt", old)
    raw = torch.load(path, weights_only=True)
    assert any(k.startswith("net.") for k in raw["state_dict"]) == old and ("centre" in raw["hyper_parameters"]) != old
    loaded = InbetweenModule.load_from_checkpoint(path, map_location="cpu").eval()
    pred = load_predictor(path)
    assert loaded.centre == pred.centre == "window"
    root, q = windows(7)
    want = module.predictor.predict_transitions(root, q, 7)
    for got in (loaded.predictor.predict_transitions(root, q, 7), pred.predict_transitions(root, q, 7)):
        assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
    assert not pred.training and not any(k.startswith("predictor.") for k in pred.state_dict())


def test_state_dict_layout_helpers():
    t = torch.zeros(1)
    assert upgrade_module_state({"net.a": t, "other": t}).keys() == {"predictor.net.a", "other"}
    assert predictor_state({"predictor.net.a": t, "x.y": t}).keys() == {"net.a"}
    assert predictor_state({"net.a": t, "val_bench.s": t}).keys() == {"net.a"}


def test_architecture_mismatch_is_a_checkpoint_error(tmp_path):
    ckpt = torch.load(REFERENCE, map_location="cpu", weights_only=True)
    ckpt["hyper_parameters"]["model"] = dict(ckpt["hyper_parameters"]["model"], d_model=32)
    torch.save(ckpt, tmp_path / "other.ckpt")
    with pytest.raises(CheckpointError, match="does not match this version's models"):
        load_predictor(tmp_path / "other.ckpt")


def test_reference_checkpoint_predictor_equals_the_module_and_loads_without_lightning():
    """The shipped checkpoint (old layout, centre=known): the predictor loaded alone and the Lightning module's
    give identical transitions, and loading it for inference imports no Lightning/training code."""
    pred = load_predictor(REFERENCE)
    module = InbetweenModule.load_from_checkpoint(REFERENCE, map_location="cpu").eval()
    assert pred.centre == module.centre == "known" and pred.skeleton.num_joints == 21
    rng = np.random.default_rng(0)
    root = np.cumsum(rng.normal(size=(2, 26, 3)), axis=1)
    q = rng.normal(size=(2, 26, 21, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    a, b = pred.predict_transitions(root, q, 15), module.predictor.predict_transitions(root, q, 15)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    code = ("import sys; from inbetweening.predictor.checkpoint import load_predictor; "
            "from inbetweening.api.inbetweener import Inbetweener; "
            f"ib = Inbetweener(load_predictor({str(REFERENCE)!r})); "
            "bad = [m for m in sys.modules if m.startswith(('lightning', 'inbetweening.training'))]; "
            "assert not bad, bad; print('ok')")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr[-2000:]


# ------------------------------------------------------------------ the module's mask group, the network's layout
def test_module_takes_the_mask_group_dict():
    common = {"model": MODEL, "skeleton": SK.to_dict(), "pos_mean": MEAN.tolist(), "pos_std": STD.tolist(),
              "centre": "known"}
    joints = InbetweenModule(mask={"name": "joints", "gap_min": 4, "gap_max": 9, "frac_min": 0.2, "frac_max": 0.4},
                             **common)
    assert joints.mask_name == joints.predictor.mask_name == "joints"
    assert joints.joint_gaps == JointGaps(4, 9, 0.2, 0.4)
    zero = InbetweenModule(mask={"name": "zero"}, **common)
    assert zero.mask_name == "zero" and zero.joint_gaps == JointGaps()
    assert InbetweenModule(mask="lerp", **common).mask_name == "lerp"


def test_the_network_is_built_with_the_representations_layout():
    assert DEFAULT_LAYOUT == R.GlobalPosLocalQuat.layout() and FEATURE_DIM == 7
    net = build_network(MODEL, SK)
    assert (net.pos, net.quat, net.feature_dim) == (slice(0, 3), slice(3, 7), 7)
    other = {"features": 8, "position": [4, 7], "rotation": [0, 4]}
    wide = build_network(MODEL, SK, other)
    assert (wide.pos, wide.quat, wide.feature_dim) == (slice(4, 7), slice(0, 4), 8)
    x = torch.randn(2, 12, 4, 8)
    x[..., 0:4] = torch.nn.functional.normalize(x[..., 0:4], dim=-1)
    known = transition_known(2, 12, 4, 5, 4)
    with torch.no_grad():
        out = wide.eval()(x, known, x)
    assert out.shape == x.shape and torch.equal(out[known], x[known])
    np.testing.assert_allclose(out[..., 0:4].norm(dim=-1).numpy(), 1.0, atol=1e-5)  # the layout's rotation channels


def test_the_blend_weighs_the_prediction_against_the_interpolation_per_gap_length():
    """``blend``: weight 0 gives the interpolation, 1 the network, in between positions linearly and rotations by
    slerp; the weight is chosen by the gap a frame lies in (longer gaps take the last one); known values stay
    bit-exact; the training forward never blends; the blend is a plain value of the checkpoint."""
    from inbetweening.predictor.predictor import check_blend

    root, q = windows(4, t=24)
    plain = predictor(4)
    known = plain.transition_known(3, 24, 7)
    known[:, 12] = True  # two gaps per window: 2 frames (10-11) and 4 frames (13-16)
    base = plain.predict_windows(root, q, known)
    for table, want in (([0.0], "interp"), ([1.0], "pred")):
        b = predictor(4, blend=table).predict_windows(root, q, known)
        ref = base.interp_root if want == "interp" else base.root
        np.testing.assert_allclose(b.root.numpy(), ref.numpy(), atol=1e-5)
    half = predictor(4, blend=[1.0, 0.0, 1.0, 0.5])  # gap 2 -> 0, gap 4 and longer -> 0.5
    out = half.predict_windows(root, q, known)
    k = known[..., 0]
    assert torch.equal(out.root[k], torch.from_numpy(root)[k]) and torch.equal(out.local_q[known],
                                                                              torch.from_numpy(q)[known])
    np.testing.assert_allclose(out.root[:, 10:12].numpy(), base.interp_root[:, 10:12].numpy(), atol=1e-5)
    mid = (base.interp_root[:, 13:17] + base.root[:, 13:17]) / 2
    np.testing.assert_allclose(out.root[:, 13:17].numpy(), mid.numpy(), atol=1e-4)
    w = half.blend_weights(known)
    assert w[0, :, 0].tolist() == [1.0] * 10 + [0.0, 0.0, 1.0] + [0.5] * 4 + [1.0] * 7
    assert Predictor.from_hparams(half.hparams()).blend == (1.0, 0.0, 1.0, 0.5)
    assert json.loads(half.metadata()["blend"]) == [1.0, 0.0, 1.0, 0.5]
    assert plain.hparams()["blend"] is None and upgrade_hparams({"centre": "known"}).get("blend") is None
    trained = [p(root, q, known)[0] for p in (plain, half)]  # the training forward: the network as it is
    assert torch.equal(trained[0], trained[1])
    for bad in ([], [0.5, 1.5], [float("nan")], "x", 3):
        with pytest.raises(ValueError, match="blend: must be"):
            check_blend(bad)
