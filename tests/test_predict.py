"""Animator-facing in-betweening: :class:`inbetweening.Inbetweener` and ``python -m inbetweening.predict``."""
from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import BLOCK_TORCH
from inbetweening import Inbetweener
from inbetweening.api.inbetweener import InbetweenError
from inbetweening.cli import predict
from inbetweening.data.bvh import BVH, parse_bvh, read_bvh
from inbetweening.data.bvh_writer import format_bvh, write_bvh
from inbetweening.data.datasets import fold_static_root
from inbetweening.data.synthetic import generate_clip, make_bvh
from inbetweening.geometry.interp import interpolate_keyframes
from inbetweening.geometry.quaternion import qinv, qmul, qrot
from inbetweening.predictor.checkpoint import CheckpointError
from inbetweening.training.module import InbetweenModule

REPO_MODELS = Path(__file__).resolve().parents[1] / "models"


def _clip(frames: int = 120, seed: int = 0) -> BVH:
    """A synthetic LAFAN-layout clip, passed through the writer/reader like a real file."""
    return parse_bvh(format_bvh(make_bvh(*generate_clip(np.random.default_rng(seed), frames))), source="clip.bvh")


def _same_rotations(a: np.ndarray, b: np.ndarray, atol: float) -> bool:
    return bool(np.all(np.abs(np.abs((a * b).sum(-1)) - 1) < atol))


def _yaw(deg: float) -> np.ndarray:
    return np.array([math.cos(math.radians(deg) / 2), 0.0, math.sin(math.radians(deg) / 2), 0.0])


def bandai_style(clip: BVH, top_yaw=90.0, top_pos=(10.0, 0.0, -5.0)) -> BVH:
    """The same motion under a ``joint_Root`` above ``Hips``, every joint with 6 channels (pos + ZXY): a static one,
    or a moving one with ``top_yaw (F,)`` and ``top_pos (F, 3)`` per frame (a take whose joint_Root carries the
    locomotion)."""
    f, j = clip.num_frames, clip.num_joints
    top_q = np.stack([_yaw(d) for d in np.broadcast_to(np.asarray(top_yaw, float), (f,))])
    top_p = np.broadcast_to(np.asarray(top_pos, float), (f, 3))
    q = clip.local_rotations()
    pos = clip.channel_positions()
    q_bn = np.concatenate([top_q[:, None], q], axis=1)
    q_bn[:, 1] = qmul(qinv(top_q), q[:, 0])
    pos_bn = np.concatenate([top_p[:, None], pos], axis=1)
    pos_bn[:, 1] = qrot(qinv(top_q), pos[:, 0] - top_p)
    channels = [("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")] * (j + 1)
    bn = BVH(["joint_Root"] + clip.names, [-1] + [p + 1 for p in clip.parents.tolist()],
             np.vstack([np.zeros(3), clip.offsets]), channels, {k + 1: v for k, v in clip.end_sites.items()},
             clip.frame_time, np.zeros((f, 6 * (j + 1))), source="bandai.bvh")
    return parse_bvh(format_bvh(bn.with_motion(q_bn, pos_bn)), source="bandai.bvh")


@pytest.fixture(scope="module")
def ib(tiny_checkpoint) -> Inbetweener:
    return Inbetweener.from_checkpoint(tiny_checkpoint)


@pytest.fixture(scope="module")
def clip() -> BVH:
    return _clip()


# ------------------------------------------------------------------ form A: keyframes of a clip
def test_fill_keyframes_keeps_rows_and_hierarchy(ib, clip, tmp_path):
    path = tmp_path / "in.bvh"
    write_bvh(clip, path)
    out = ib.fill(path, keyframes=[0, 30, 75])
    assert out.num_frames == 76
    assert np.array_equal(out.motion[[0, 30, 75]], clip.motion[[0, 30, 75]])
    assert np.isfinite(out.motion).all()
    assert not np.allclose(out.motion[1:30], out.motion[0])  # frames were actually generated
    write_bvh(out, tmp_path / "out.bvh")
    back = parse_bvh((tmp_path / "out.bvh").read_bytes(), source="out.bvh")
    assert back.names == clip.names and back.channels == clip.channels
    assert np.array_equal(back.parents, clip.parents) and np.array_equal(back.offsets, clip.offsets)
    assert back.num_frames == 76 and back.frame_time == clip.frame_time
    assert np.array_equal(back.motion[[0, 30, 75]], clip.motion[[0, 30, 75]])  # 6-decimal input: exact round trip


def test_fill_uneven_gaps_and_dropped_frames(ib, clip):
    keys = [5, 12, 40, 41, 100]
    res = ib.fill_detailed(clip, keyframes=keys)
    assert res.bvh.num_frames == 96 and res.known_frames == [0, 7, 35, 36, 95]
    assert np.array_equal(res.bvh.motion[res.known_frames], clip.motion[keys])
    assert res.pseudo_keyframes and all(36 < p < 95 for p in res.pseudo_keyframes)  # the 58-frame gap was split
    assert np.isfinite(res.bvh.motion).all()


def test_fill_gap_form(ib, clip):
    keys = clip.motion[[0, 10, 20]]
    keys_only = BVH(clip.names, clip.parents, clip.offsets, clip.channels, clip.end_sites, clip.frame_time, keys)
    out = ib.fill(keys_only, gap=9)
    assert out.num_frames == 3 + 2 * 9
    assert np.array_equal(out.motion[[0, 10, 20]], keys)
    # non-root channels only hold rotations here; the root's position columns are generated
    assert np.isfinite(out.motion).all()


def test_long_gap_is_segmented_or_refused(ib, clip):
    assert ib.max_gap == ib.trained_gap == 30  # transition_max of the training run
    res = ib.fill_detailed(clip, keyframes=[0, 80])
    assert res.pseudo_keyframes == [27, 53]  # 3 segments, gaps of 26, 25 and 26 frames
    assert np.array_equal(res.bvh.motion[[0, 80]], clip.motion[[0, 80]])
    with pytest.raises(InbetweenError, match=r"gap between keyframes 0 and 80 is 79 frames, longer than max_gap=30"):
        ib.fill(clip, keyframes=[0, 80], segment=False)
    assert ib.fill_detailed(clip, keyframes=[0, 80], max_gap=10).pseudo_keyframes == list(range(10, 80, 10))
    with pytest.raises(InbetweenError, match="max_gap"):
        ib.fill(clip, keyframes=[0, 80], max_gap=1000)


def test_fill_arrays_ignores_unknown_frames_and_is_yaw_equivariant(ib, clip):
    root, q = clip.local_positions()[:50, 0], clip.local_rotations()[:50]
    known = [0, 20, 49]
    r1, q1 = ib.fill_arrays(root, q, known)
    holes = np.setdiff1d(np.arange(50), known)
    r_nan, q_nan = root.copy(), q.copy()
    r_nan[holes], q_nan[holes] = np.nan, np.nan
    r2, q2 = ib.fill_arrays(r_nan, q_nan, known)
    assert np.array_equal(r1, r2) and np.array_equal(q1, q2)  # unknown frames are never read
    assert np.array_equal(r1[known], root[known]) and np.array_equal(q1[known], q[known])
    # the windows are normalised: turning and moving the whole clip turns and moves the result
    y, t = _yaw(63.0), np.array([250.0, 0.0, -80.0])
    q_rot = q.copy()
    q_rot[:, 0] = qmul(y[None], q[:, 0])
    r3, q3 = ib.fill_arrays(qrot(y[None], root) + t, q_rot, known)
    np.testing.assert_allclose(r3, qrot(y[None], r1) + t, atol=1e-3)
    assert _same_rotations(q3[:, 0], qmul(y[None], q1[:, 0]), 1e-5)
    assert _same_rotations(q3[:, 1:], q1[:, 1:], 1e-5)


def test_interpolation_model_reproduces_interpolation(clip):
    """With the interpolation baseline as the network, normalise -> predict -> undo is exactly lerp/slerp (the feet
    not locked: locking is a stage after the network, tests/test_foot_lock.py)."""
    sk = clip.skeleton()
    module = InbetweenModule(model={"name": "interpolation"}, skeleton=sk.to_dict(), pos_mean=[0.0] * 66,
                             pos_std=[50.0] * 66, forward_axis=(0.0, 0.0, 1.0), centre="window")
    res = Inbetweener(module, foot_lock=False).fill_detailed(clip, keyframes=[0, 30, 75, 119])
    ri, qi = interpolate_keyframes(res.root, res.local_q, res.known_frames)
    np.testing.assert_allclose(res.root, ri, atol=1e-3)
    assert _same_rotations(res.local_q, qi, 1e-6)


# ------------------------------------------------------------------ skeletons
def test_bandai_namco_static_root_is_folded_and_unfolded(ib, clip):
    bn = bandai_style(clip)
    keys = [0, 25, 50]
    res_bn = ib.fill_detailed(bn, keyframes=keys)
    res = ib.fill_detailed(clip, keyframes=keys)
    out = res_bn.bvh
    assert out.names == bn.names and out.channels == bn.channels and out.num_frames == 51
    assert np.array_equal(out.motion[keys], bn.motion[keys])
    assert np.array_equal(out.motion[:, :6], np.broadcast_to(bn.motion[0, :6], (51, 6)))  # joint_Root static
    # the model saw the same motion as for the plain file ...
    np.testing.assert_allclose(res_bn.root, res.root, atol=1e-2)
    assert _same_rotations(res_bn.local_q, res.local_q, 1e-6)
    # ... and the written Hips-under-joint_Root channels give back the predicted global Hips transform
    refolded, _ = fold_static_root(out, "out")
    np.testing.assert_allclose(refolded.root_pos, res_bn.root, atol=1e-5)
    assert _same_rotations(refolded.local_q, res_bn.local_q, 1e-10)


def test_a_moving_joint_root_is_folded_and_unfolded(ib, clip, tmp_path, tiny_checkpoint):
    """A take whose ``joint_Root`` carries the locomotion (a walk and a turn): the model sees the same motion as for
    the plain file, the keys stay the input's rows bit for bit, ``joint_Root`` moves between its key values on the
    generated frames (no step at the nearest key) and Hips under it gives the predicted global motion."""
    f = clip.num_frames
    t = np.arange(f) / (f - 1)
    moving = bandai_style(clip, top_yaw=80.0 * t - 30.0, top_pos=np.stack([250.0 * t, 0 * t, -60.0 * t], axis=1))
    assert np.ptp(moving.motion[:, [0, 2, 5]], axis=0).min() > 50  # X, Z and yaw (the Yrotation channel) move
    keys = [0, 25, 50]
    res_mv, res = ib.fill_detailed(moving, keyframes=keys), ib.fill_detailed(clip, keyframes=keys)
    out = res_mv.bvh
    assert out.names == moving.names and out.channels == moving.channels and out.num_frames == 51
    assert np.array_equal(out.motion[keys], moving.motion[keys])  # the keys: the input's rows
    np.testing.assert_allclose(res_mv.root, res.root, atol=1e-2)
    assert _same_rotations(res_mv.local_q, res.local_q, 1e-6)
    for k0, k1 in ((0, 25), (25, 50)):  # joint_Root's position: linear between its two keys
        w = (np.arange(k0, k1 + 1) - k0)[:, None] / (k1 - k0)
        lerp = moving.motion[k0, :3] + w * (moving.motion[k1, :3] - moving.motion[k0, :3])
        np.testing.assert_allclose(out.motion[k0 : k1 + 1, :3], lerp, atol=1e-9)
    refolded, _ = fold_static_root(out, "out")
    np.testing.assert_allclose(refolded.root_pos, res_mv.root, atol=1e-4)  # the predicted Hips, Euler in between
    assert _same_rotations(refolded.local_q, res_mv.local_q, 1e-9)
    write_bvh(moving, tmp_path / "moving.bvh")  # python -m inbetweening.predict: the same, in a valid file
    assert predict.run([f"ckpt_path={tiny_checkpoint}", f"input={tmp_path / 'moving.bvh'}", "keyframes=0,25,50",
                        f"output={tmp_path / 'moving_filled.bvh'}"]) == 0
    back, given = read_bvh(tmp_path / "moving_filled.bvh"), read_bvh(tmp_path / "moving.bvh")
    assert back.names == moving.names and back.channels == moving.channels and back.num_frames == 51
    assert np.array_equal(back.motion[keys], given.motion[keys])
    np.testing.assert_allclose(back.motion, out.motion, atol=PRINT_ATOL, rtol=0)


def test_skeleton_mismatch_is_a_clear_error(ib, clip):
    renamed = BVH(["Pelvis"] + clip.names[1:], clip.parents, clip.offsets, clip.channels, clip.end_sites,
                  clip.frame_time, clip.motion)
    with pytest.raises(InbetweenError, match=r"22 joints.*22.*joint 0: file 'Pelvis', checkpoint 'Hips'.*its own "
                                             r"skeleton only"):  # (a model of the humanoid slots retargets it)
        ib.fill(renamed, keyframes=[0, 10])
    j = clip.num_joints - 1  # drop the last joint (RightHand)
    cut = BVH(clip.names[:j], clip.parents[:j], clip.offsets[:j], clip.channels[:j], {}, clip.frame_time,
              clip.motion[:, : 6 + 3 * (j - 1)])
    with pytest.raises(InbetweenError, match=r"has 21 joints, the checkpoint's skeleton has 22.*'RightHand'"):
        ib.fill(cut, keyframes=[0, 10])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"keyframes": [0, 40, 30]}, r"sorted.*40 comes before 30"),
        ({"keyframes": [0, 30, 30]}, "frame 30 is listed twice"),
        ({"keyframes": [0, 130]}, r"frame 130 is out of range for a clip of 120 frames"),
        ({"keyframes": [-1, 10]}, "frame -1 is out of range"),
        ({"keyframes": [5]}, "at least 2 keyframes"),
        ({"keyframes": []}, "at least 2 keyframes"),
        ({"gap": 0}, "gap must be an integer >= 1"),
        ({}, "exactly one of keyframes"),
        ({"keyframes": [0, 10], "gap": 3}, "exactly one of keyframes"),
    ],
)
def test_bad_keyframes(ib, clip, kwargs, match):
    with pytest.raises(InbetweenError, match=match):
        ib.fill(clip, **kwargs)


def test_bad_checkpoint(tmp_path):
    with pytest.raises(CheckpointError, match="does not exist"):
        Inbetweener.from_checkpoint(tmp_path / "missing.ckpt")
    bad = tmp_path / "bad.ckpt"
    bad.write_text("not a checkpoint")
    with pytest.raises(CheckpointError, match="not a readable PyTorch checkpoint"):
        Inbetweener.from_checkpoint(bad)


# ------------------------------------------------------------------ command line
def _cli(*args: str, cwd) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    return subprocess.run([sys.executable, "-m", "inbetweening.predict", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300, check=False)


def test_cli_end_to_end_with_render(tiny_checkpoint, tmp_path):
    from PIL import Image

    write_bvh(_clip(60), tmp_path / "clip.bvh")
    r = _cli(f"ckpt_path={tiny_checkpoint}", "input=clip.bvh", "keyframes=[0,12,24]", "output=out/filled.bvh",
             "--render", "out/filled.gif", "--render-dpi", "40", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "25 frames (3 keyframes, 22 generated" in r.stdout
    out = read_bvh(tmp_path / "out" / "filled.bvh")
    assert out.num_frames == 25
    assert np.array_equal(out.motion[[0, 12, 24]], read_bvh(tmp_path / "clip.bvh").motion[[0, 12, 24]])
    assert (tmp_path / "out" / "filled.gif").read_bytes()[:6] in (b"GIF89a", b"GIF87a")
    with Image.open(tmp_path / "out" / "filled.gif") as im:
        assert im.format == "GIF" and im.n_frames == 25


def test_cli_render_writes_what_the_file_name_says(tiny_checkpoint, tmp_path):
    from PIL import Image

    write_bvh(_clip(40), tmp_path / "clip.bvh")
    common = [f"ckpt_path={tiny_checkpoint}", "input=clip.bvh", "keyframes=[0,12,24]", "render_dpi=40"]
    r = _cli(*common, "output=a.bvh", "render=strip.png", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "strip.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"  # not a GIF under a .png name
    with Image.open(tmp_path / "strip.png") as im:
        assert im.format == "PNG" and getattr(im, "n_frames", 1) == 1
    r = _cli(*common, "output=c.bvh", "render=anim.gif", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "anim.gif").read_bytes()[:6] in (b"GIF89a", b"GIF87a")
    r = _cli(*common, "output=b.bvh", "render=strip.jpg", cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.strip().splitlines() == [
        "error: render: strip.jpg must end in .gif (an animation) or .png (a filmstrip)"], r.stderr
    assert not (tmp_path / "b.bvh").exists()  # refused before any work


def test_render_comparison_marks_the_planted_feet(ib, tmp_path):
    """``predict --render`` draws the feet's trails on the floor, the model's predicted contact thick in the contact
    colour in the model's panel (the left one): a result whose feet are all planted has it there, one whose feet are
    never planted has none; a model that records no feet gets them from the skeleton."""
    import dataclasses

    from matplotlib.colors import to_rgb
    from PIL import Image

    from inbetweening.data.contacts import FootContact
    from inbetweening.rendering.skeleton_plot import CONTACT_COLOR

    res = ib.fill_detailed(_clip(40), keyframes=[0, 12, 24])
    shape = (res.num_frames, res.skeleton.num_joints)

    def model_panel_contact_pixels(result, name, contact):
        path = predict.render_comparison(result, tmp_path / name, 30.0, contact=contact)
        with Image.open(path) as im:
            img = np.asarray(im.convert("RGB"), dtype=float) / 255
        left = img[: -30, : img.shape[1] // 2]  # above the legend (its "foot planted" sample)
        return (np.abs(left - np.asarray(to_rgb(CONTACT_COLOR))).max(axis=-1) < 0.08).sum()

    planted, never = (dataclasses.replace(res, contact=np.full(shape, v)) for v in (1.0, 0.0))
    assert ib.predictor.contact.feet
    assert model_panel_contact_pixels(planted, "planted.png", ib.predictor.contact) > 200
    assert model_panel_contact_pixels(never, "never.png", ib.predictor.contact) == 0
    assert model_panel_contact_pixels(planted, "found.png", FootContact()) > 200  # feet found by their names
    with pytest.raises(ValueError, match="must end in .gif"):
        predict.render_comparison(res, tmp_path / "x.jpg", 30.0)


PRINT_ATOL = 0.5e-6 + 1e-9  # BVH values are written with 6 decimals


def test_cli_in_process_forms(tiny_checkpoint, tmp_path, monkeypatch, capsys):
    write_bvh(_clip(60), tmp_path / "clip.bvh")
    clip = read_bvh(tmp_path / "clip.bvh")  # the input as the CLI reads it
    monkeypatch.chdir(tmp_path)
    assert predict.run(["--ckpt_path", str(tiny_checkpoint), "--input", "clip.bvh", "--gap", "2",
                        "--output", "b.bvh"]) == 0
    b = read_bvh(tmp_path / "b.bvh")
    assert b.num_frames == 60 + 59 * 2
    # content: every input row is a keyframe row (every 3rd output frame), the rest is what fill() generates
    assert np.array_equal(b.motion[::3], clip.motion)
    want_b = Inbetweener.from_checkpoint(tiny_checkpoint).fill(clip, gap=2).motion
    np.testing.assert_allclose(b.motion, want_b, atol=PRINT_ATOL, rtol=0)
    assert predict.run([f"ckpt={tiny_checkpoint}", "input=clip.bvh", "keyframes=0,40", "output=a.bvh",
                        "--no-segment", "--max-gap", "45"]) == 0
    a = read_bvh(tmp_path / "a.bvh")
    assert a.num_frames == 41
    assert np.array_equal(a.motion[[0, 40]], clip.motion[[0, 40]])
    # the options reach the model: one 39-frame gap, not split (max_gap 45, no segmentation)
    want_a = Inbetweener.from_checkpoint(tiny_checkpoint, max_gap=45, segment=False).fill(clip, keyframes=[0, 40])
    np.testing.assert_allclose(a.motion, want_a.motion, atol=PRINT_ATOL, rtol=0)
    assert not np.allclose(a.motion[1:40], Inbetweener.from_checkpoint(tiny_checkpoint).fill(
        clip, keyframes=[0, 40]).motion[1:40], atol=1e-3)  # the default (segmented) result differs
    assert predict.run(["--help"]) == 0
    usage = capsys.readouterr().out
    assert "keyframes=[0,30,75]" in usage and "gap=30" in usage and "Long gaps" in usage


def test_cli_errors_exit_2_with_one_line(tiny_checkpoint, tmp_path, monkeypatch, capsys):
    write_bvh(_clip(60), tmp_path / "clip.bvh")
    r = _cli(f"ckpt_path={tiny_checkpoint}", "input=clip.bvh", "keyframes=0,30,90", "output=o.bvh", cwd=tmp_path)
    assert r.returncode == 2
    assert r.stderr.strip().splitlines() == [
        "error: keyframes: frame 90 is out of range for a clip of 60 frames (valid: 0..59)"]
    assert not (tmp_path / "o.bvh").exists()
    monkeypatch.chdir(tmp_path)
    (tmp_path / "junk.onnx").write_bytes(b"\x00junk")
    cases = [
        (["ckpt_path=missing.ckpt", "input=clip.bvh", "gap=3", "output=o.bvh"],
         "ckpt_path: missing.ckpt does not exist"),
        ([f"ckpt_path={tiny_checkpoint}", "input=nope.bvh", "gap=3", "output=o.bvh"], "input: nope.bvh does not exist"),
        (["input=clip.bvh", "gap=3"], "missing output=..."),  # ckpt_path: the shipped model
        (["ckpt_path=x", "input=clip.bvh", "output=o", "keyframes=0,a"], "keyframes: 'a' is not an integer"),
        (["ckpt_path=x", "input=clip.bvh", "output=o", "gap=3", "colour=red"], "unknown option 'colour'"),
        (["ckpt_path=x", "input=clip.bvh", "output=o"], "give exactly one of keyframes"),
        (["ckpt_path=missing.onnx", "input=clip.bvh", "gap=3", "output=o.bvh"],
         "ckpt_path: missing.onnx does not exist"),
        (["ckpt_path=junk.onnx", "input=clip.bvh", "gap=3", "output=o.bvh"],
         "ckpt_path: junk.onnx is not a readable ONNX model"),
        ([f"ckpt_path={REPO_MODELS / 'bn2_v2' / 'model.onnx'}", "input=clip.bvh", "gap=3", "output=o.bvh",
          "device=cuda"], "device: cuda runs checkpoints (.ckpt)"),
    ]
    for argv, msg in cases:
        with pytest.raises(SystemExit) as exc:
            predict.run(argv)
        assert exc.value.code == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and err.startswith("error: ") and msg in err, err


def test_cli_defaults_to_the_shipped_model(tiny_checkpoint, tmp_path, monkeypatch, capsys):
    """Without ckpt_path the shipped ensemble (models/bn2_partial, bn2_partial_twin and bn2_v2) fills the clip: their
    window graphs (.onnx), or their checkpoints where the fill needs PyTorch (test-time adaptation, another device);
    where a model of it is absent (an installed package without the repository) ckpt_path is required."""
    assert predict.default_checkpoint() == [str(p) for p in predict.SHIPPED_MODELS]
    assert predict.default_checkpoint(torch=True) == [str(p) for p in predict.SHIPPED_CHECKPOINTS]
    for paths, suffix in ((predict.SHIPPED_MODELS, ".onnx"), (predict.SHIPPED_CHECKPOINTS, ".ckpt")):
        assert [p.parent.name for p in paths] == ["bn2_partial", "bn2_partial_twin", "bn2_v2"]
        assert all(p.suffix == suffix for p in paths)
    write_bvh(_clip(60), tmp_path / "clip.bvh")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(predict, "SHIPPED_CHECKPOINTS", (Path(tiny_checkpoint), Path(tiny_checkpoint)))
    assert predict.run(["input=clip.bvh", "keyframes=0,30,59", "output=o.bvh", "fill.adapt_steps=1"]) == 0
    assert (tmp_path / "o.bvh").is_file() and str(tiny_checkpoint) in capsys.readouterr().out
    monkeypatch.setattr(predict, "SHIPPED_MODELS", (tmp_path / "absent.onnx",) * 3)  # the graphs absent: checkpoints
    assert predict.run(["input=clip.bvh", "keyframes=0,30,59", "output=o1.bvh"]) == 0
    assert str(tiny_checkpoint) in capsys.readouterr().out
    monkeypatch.setattr(predict, "SHIPPED_CHECKPOINTS", (Path(tiny_checkpoint), tmp_path / "absent.ckpt"))
    with pytest.raises(SystemExit) as exc:
        predict.run(["input=clip.bvh", "keyframes=0,30,59", "output=o2.bvh"])
    assert exc.value.code == 2 and "missing ckpt_path=..." in capsys.readouterr().err


PREDICT_WITHOUT_TORCH = BLOCK_TORCH + """
from inbetweening.cli.predict import run
code = run(sys.argv[1:])
print("torch" in sys.modules)
sys.exit(code)
"""


def test_the_shipped_fill_runs_without_torch(tmp_path):
    """``predict`` with the shipped default fills on ONNX Runtime with PyTorch blocked (its start-up: BENCHMARKS.md),
    keys bit for bit, and the result is the checkpoints' fill within float32 rounding (1e-3 of a channel's unit)."""
    clip = _clip(91)
    write_bvh(clip, tmp_path / "clip.bvh")
    (tmp_path / "run.py").write_text(PREDICT_WITHOUT_TORCH)
    args = ["input=clip.bvh", "keyframes=[0,30,60,90]"]
    proc = subprocess.run([sys.executable, "run.py", *args, "output=onnx.bvh"], capture_output=True, text=True,
                          cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.split()[-1] == "False" and "model.onnx" in proc.stdout
    got = read_bvh(tmp_path / "onnx.bvh")
    assert np.array_equal(got.motion[[0, 30, 60, 90]], clip.motion[[0, 30, 60, 90]])
    ckpts = "[" + ",".join(str(p) for p in predict.SHIPPED_CHECKPOINTS) + "]"
    assert predict.run([f"input={tmp_path / 'clip.bvh'}", "keyframes=[0,30,60,90]", f"output={tmp_path / 'ckpt.bvh'}",
                        f"ckpt_path={ckpts}"]) == 0
    ref = read_bvh(tmp_path / "ckpt.bvh")
    assert got.motion.shape == ref.motion.shape and np.abs(got.motion - ref.motion).max() < 1e-3


def test_partial_keys_through_the_api_and_the_cli(tiny_checkpoint, tmp_path, monkeypatch, capsys):
    """A frame keyed on some bones only: those bones' channels come back bit for bit, the frame's other bones are
    generated; the CLI's form reaches the same fill; bad partial keys are one line and exit code 2."""
    write_bvh(_clip(60), tmp_path / "clip.bvh")
    clip = read_bvh(tmp_path / "clip.bvh")
    ib = Inbetweener.from_checkpoint(tiny_checkpoint)
    arm = [n for n in clip.names if "Left" in n and ("Arm" in n or "Hand" in n)]
    assert arm
    out = ib.fill(clip, keyframes=[0, 40], partial={20: arm})
    ends = np.cumsum([len(ch) for ch in clip.channels])
    cols = np.concatenate([np.arange(ends[j] - len(clip.channels[j]), ends[j]) for j in map(clip.names.index, arm)])
    assert np.array_equal(out.motion[20, cols], clip.motion[20, cols])  # the keyed bones, bit for bit
    rest = np.setdiff1d(np.arange(clip.motion.shape[1]), cols)
    assert not np.allclose(out.motion[20, rest], clip.motion[20, rest])  # the others are generated
    whole = ib.fill(clip, keyframes=[0, 40])
    assert not np.allclose(out.motion[10], whole.motion[10])  # and the constraint changes the fill around it
    monkeypatch.chdir(tmp_path)
    assert predict.run([f"ckpt={tiny_checkpoint}", "input=clip.bvh", "keyframes=0,40", "output=p.bvh",
                        f"partial=20:{','.join(arm)}"]) == 0
    np.testing.assert_allclose(read_bvh(tmp_path / "p.bvh").motion, out.motion, atol=PRINT_ATOL, rtol=0)
    for bad, says in (("partial=50:Hips", "frame 50 lies outside the keys (0..40)"),
                      ("partial=20:Elbow", "frame 20: no joint named 'Elbow' in clip.bvh's hierarchy"),
                      ("partial=20", "is not FRAME:BONE")):
        with pytest.raises(SystemExit) as e:
            predict.run([f"ckpt={tiny_checkpoint}", "input=clip.bvh", "keyframes=0,40", "output=q.bvh", bad])
        assert e.value.code == 2
        err = capsys.readouterr().err.strip()
        assert says in err and len(err.splitlines()) == 1
