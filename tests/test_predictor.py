"""The Predictor: one object from windows to predictions, built from plain values, restored from checkpoints."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from inbetweening.predictor.features import known_centre_shift

from inbetweening.geometry.interp import interpolate_keyframes
from inbetweening.geometry.quaternion import qmul, qrot
from inbetweening.geometry.skeleton import Skeleton
from inbetweening.predictor import representation as R
from inbetweening.predictor.checkpoint import CheckpointError, load_predictor, predictor_state, upgrade_module_state
from inbetweening.predictor.predictor import Predictor, upgrade_hparams
from inbetweening.training.module import InbetweenModule

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "models" / "bn2_reference" / "model.ckpt"
SK = Skeleton(("root", "spine", "head", "leg"), (-1, 0, 1, 0),
              np.array([[0.0, 0, 0], [0.0, 1.0, 0], [0.0, 1.0, 0], [0.3, -1.0, 0]]))
MEAN = np.linspace(-1, 1, 12)
STD = np.array([2.0, 1.0, 3.0, 0.5, 1.5, 4.0, 1.0, 2.5, 0.25, 3.0, 1.0, 0.75])
MODEL = {"name": "frame_transformer", "d_model": 16, "depth": 1, "heads": 2, "ffn_dim": 16, "dropout": 0.0,
         "max_frames": 64}


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
    with pytest.raises(ValueError, match=r"centre must be one of \['window', 'known', 'last'\], got 'middle'"):
        Predictor.from_hparams(hparams(centre="middle"))
    with pytest.raises(TypeError, match="centre"):
        Predictor(torch.nn.Identity(), SK, MEAN, STD, mask="lerp")
    with pytest.raises(TypeError, match="centre"):
        InbetweenModule(model={"name": "interpolation"}, skeleton=SK.to_dict(), pos_mean=MEAN.tolist(),
                        pos_std=STD.tolist())
    with pytest.raises(ValueError, match="mask must be one of"):
        Predictor.from_hparams(hparams(mask="blur"))


@pytest.mark.parametrize("centre", ["known", "window"])
def test_predict_known_values_bit_exact_and_unknown_input_never_read(centre):
    p = predictor(2, centre=centre)
    root, q = windows(2)
    known = p.transition_known(3, 18, 7)
    feats, pred, interp = p.predict_windows(root, q, known)
    assert torch.equal(pred[known], feats[known]) and torch.equal(interp[known], feats[known])
    garbage_r, garbage_q = root.copy(), q.copy()
    garbage_r[:, 10:17], garbage_q[:, 10:17] = np.nan, np.nan
    _, pred_nan, _ = p.predict_windows(garbage_r, garbage_q, known)
    garbage_r[:, 10:17], garbage_q[:, 10:17] = 1e6, 0.5
    _, pred_big, _ = p.predict_windows(garbage_r, garbage_q, known)
    assert torch.isfinite(pred_nan).all()
    assert torch.equal(pred_nan, pred) and torch.equal(pred_big, pred)
    assert not pred.requires_grad


def test_training_forward_has_gradients_and_the_target_in_its_frame():
    p = predictor(3)
    root, q = windows(3)
    feats = p.encode(root, q)
    known = p.transition_known(3, 18, 7)
    pred, interp, target = p(feats, known)
    assert pred.requires_grad and pred.shape == feats.shape == interp.shape
    torch.testing.assert_close(feats - target, known_centre_shift(feats, known, STD).expand_as(feats))
    pred.abs().mean().backward()
    assert any(prm.grad is not None and prm.grad.abs().sum() > 0 for prm in p.parameters())
    window = predictor(3, centre="window")
    assert torch.equal(window(feats, known)[2], feats)


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
    _, pred, _ = p.predict_windows(root, q, known)
    want_r, want_q = p.decode(pred)
    np.testing.assert_allclose(pr, want_r[:, 10:17].numpy(), atol=1e-5)
    np.testing.assert_allclose(pq, want_q[:, 10:17].numpy(), atol=1e-6)


def test_fill_window_interpolation_network_is_keyframe_interpolation_and_equivariant():
    p = Predictor.from_hparams(hparams(model={"name": "interpolation"})).eval()
    root, q = windows(5, b=1, t=16)
    root, q = root[0], q[0]
    r, lq = p.fill_window(root, q)  # n_past 10, 5 transition frames, target
    assert r.shape == (5, 3) and lq.shape == (5, 4, 4)
    np.testing.assert_allclose(np.linalg.norm(lq, axis=-1), 1.0, atol=1e-12)
    ir, iq = interpolate_keyframes(root, q, [9, 15])
    np.testing.assert_allclose(r, ir[10:15], atol=1e-3)
    np.testing.assert_allclose(np.abs((lq * iq[10:15]).sum(-1)), 1.0, atol=1e-5)
    # a world yaw + shift of the window moves the prediction alike
    y = np.array([np.cos(0.6), 0.0, np.sin(0.6), 0.0])
    moved_q = q.copy()
    moved_q[:, 0] = qmul(y[None], q[:, 0])
    r2, lq2 = p.fill_window(qrot(y[None], root) + np.array([40.0, 0.0, -7.0]), moved_q)
    np.testing.assert_allclose(r2, qrot(y[None], r) + np.array([40.0, 0.0, -7.0]), atol=1e-3)
    np.testing.assert_allclose(np.abs((lq2[:, 1:] * lq[:, 1:]).sum(-1)), 1.0, atol=1e-5)


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
            "from inbetweening.tools.inbetweener import Inbetweener; "
            f"ib = Inbetweener(load_predictor({str(REFERENCE)!r})); "
            "bad = [m for m in sys.modules if m.startswith(('lightning', 'inbetweening.training'))]; "
            "assert not bad, bad; print('ok')")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr[-2000:]
