"""The window protocol's training side (data/windows.py): ClipWindows sampling, mirroring, time warp, task options."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from conftest import TINY, compose_cfg
from inbetweening.data import windows as W
from inbetweening.data.datasets import load_dataset
from inbetweening.data.mirror import fit_mirror_frames, mirror_motion, mirror_permutation
from inbetweening.data.windows import ClipWindows
from inbetweening.geometry.skeleton import Skeleton
from inbetweening.training.builders import make_datamodule
from inbetweening.training.config import ConfigError, validate

DATA = [o for o in TINY if o.startswith("data.")]
SHARED_BN2 = __import__("pathlib").Path(__file__).resolve().parents[2] / "shared/datasets/bandai-namco-2.zip"


def _dm(tmp_path, cache_dir, *extra):
    cfg = compose_cfg("train", [*DATA, *extra], tmp_path, cache_dir)
    dm = make_datamodule(cfg)
    dm.setup("fit")
    return dm


# ------------------------------------------------------------------------------------------ clip windows
def test_clip_windows_at_the_benchmark_stride_are_the_prepared_windows(cache_dir):
    d = load_dataset("synthetic", cache_dir=cache_dir, synthetic={"num_clips": 6, "min_frames": 120, "max_frames": 160})
    X, Q = W.extract_windows(d.train, d.skeleton, 50, 20)
    cw = ClipWindows(d.train, d.skeleton, 50, 20)
    assert len(cw) == len(X)
    root, q = cw.windows(np.arange(len(cw)))  # the clips' own frame: the raw protocol windows, bit for bit
    np.testing.assert_array_equal(root, X[:, :, 0])
    np.testing.assert_array_equal(q, Q)
    # normalised the protocol's way, they are the prepared (scored) windows, bit for bit
    Xn, Qn = W.prepare_windows(d.train, d.skeleton, 50, 20, d.forward_axis)
    Xc, Qc = W.centre_and_rotate(d.skeleton.local_positions(root), q, d.skeleton.parents, d.forward_axis)
    np.testing.assert_array_equal(Xc, Xn)
    np.testing.assert_array_equal(Qc, Qn)
    assert not np.allclose(root, Xn[:, :, 0])  # and ClipWindows does not normalise
    assert len(ClipWindows(d.train, d.skeleton, 50, 2)) > 8 * len(X)  # dense sampling


def _dcc_skeleton() -> Skeleton:
    """Joint frames as DCC tools export them (Bandai-Namco): bones along local +X on the left, -X on the right."""
    names = ("Hips", "Spine", "Head", "UpperLeg_L", "LowerLeg_L", "UpperLeg_R", "LowerLeg_R")
    parents = (-1, 0, 1, 0, 3, 0, 5)
    offsets = np.array([[0, 90, 0], [15, 0, 0], [6, 0, 0], [-2, -6.5, 0], [39, 0, 0], [-2, 6.5, 0], [-39, 0, 0.0]])
    return Skeleton(names, parents, offsets)


@pytest.mark.parametrize("skeleton", ["synthetic", "dcc"])
def test_fk_of_a_mirrored_clip_is_the_mirrored_fk(skeleton, cache_dir):
    if skeleton == "synthetic":
        d = load_dataset("synthetic", cache_dir=cache_dir, synthetic={"num_clips": 5, "min_frames": 100, "max_frames": 120})
        sk, pairs, q, root = d.skeleton, d.mirror, d.train[0].local_q, d.train[0].root_pos
    else:
        sk = _dcc_skeleton()
        pairs = (("UpperLeg_L", "UpperLeg_R"), ("LowerLeg_L", "LowerLeg_R"))
        rng = np.random.default_rng(0)
        q = np.array([1.0, 0, 0, 0]) + 0.4 * rng.normal(size=(200, 7, 4))
        q /= np.linalg.norm(q, axis=-1, keepdims=True)
        root = rng.normal(size=(200, 3)) * 30
    perm = mirror_permutation(pairs, sk.names)
    frames, asym = fit_mirror_frames(sk.offsets, sk.parents, perm, q)
    assert asym < 1e-9
    r2, q2 = mirror_motion(root, q, perm, frames, sk.parents)
    _, gp = sk.pose(root, q)
    _, gp2 = sk.pose(r2, q2)
    np.testing.assert_allclose(gp2, gp[:, perm] * np.array([-1.0, 1.0, 1.0]), atol=1e-9)
    r3, q3 = mirror_motion(r2, q2, perm, frames, sk.parents)  # mirroring twice gives the motion back
    np.testing.assert_allclose(r3, root, atol=1e-12)
    np.testing.assert_allclose(np.abs((q3 * q).sum(-1)), 1.0, atol=1e-12)


@pytest.mark.skipif(not SHARED_BN2.exists(), reason="Bandai-Namco-2 not found")
def test_bandai_namco_mirror_is_exact_to_a_tenth_of_a_millimetre(cache_dir):
    d = load_dataset("bandai_namco", path=SHARED_BN2, cache_dir=cache_dir)
    sk, perm = d.skeleton, mirror_permutation(d.mirror, d.skeleton.names)
    frames, asym = fit_mirror_frames(sk.offsets, sk.parents, perm, np.concatenate([c.local_q for c in d.train[:50]]))
    c = d.train[0]
    r2, q2 = mirror_motion(c.root_pos, c.local_q, perm, frames, sk.parents)
    err = np.abs(sk.pose(r2, q2)[1] - sk.pose(c.root_pos, c.local_q)[1][:, perm] * np.array([-1.0, 1, 1])).max()
    assert asym < 1e-3 and err < 0.1  # cm: the release's skeleton is symmetric to ~0.04 cm


def test_clip_sampling_data_module_mirrors_about_half_the_windows(tmp_path, cache_dir):
    dm = _dm(tmp_path, cache_dir, "data.train_offset=5", "data.mirror=true",
             "data.context_min=1", "data.keyframes_max=3", "data.keyframe_prob=0.5")
    plain = _dm(tmp_path, cache_dir, "data.train_offset=5")
    assert len(dm.clip_windows) == len(plain.clip_windows) > 0
    loader = dm.train_dataloader()
    batch = next(iter(loader))
    again = next(iter(dm.train_dataloader()))
    assert set(batch) == {"root", "q", "known", "loss_mask", "n_trans", "n_context"}
    assert all(torch.equal(batch[k], again[k]) for k in batch)  # a pure function of seed, epoch, batch
    assert batch["q"].shape[:3] == batch["known"].shape and batch["root"].shape == batch["q"].shape[:2] + (3,)
    assert torch.equal(batch["loss_mask"], ~batch["known"])
    idx = [i for *_, i in next(iter(loader.batch_sampler))]
    g = torch.Generator().manual_seed(0)
    plain_root, plain_q = plain._train_windows(idx, None)
    mirror_root, mirror_q = dm._train_windows(idx, g)
    same = [torch.equal(a, b) and torch.equal(c, d) for a, b, c, d in zip(plain_root, mirror_root, plain_q, mirror_q)]
    assert 0 < sum(same) < len(same)


# ------------------------------------------------------------------------------------------ time warp (data.speed)
def test_time_warp_plays_the_clip_faster_and_stays_inside_it(cache_dir):
    d = load_dataset("synthetic", cache_dir=cache_dir, synthetic={"num_clips": 6, "min_frames": 120, "max_frames": 160})
    cw = ClipWindows(d.train, d.skeleton, 30, 10)
    idx = np.arange(len(cw))
    plain = cw.windows(idx)
    for a, b in zip(plain, cw.windows(idx, speed=np.ones(len(idx)))):  # speed 1: the very same frames
        np.testing.assert_array_equal(a, b)
    first = int(np.argmax(cw.max_speed(idx) >= 2))  # a window with room for 2x
    s = cw.starts[first]
    frames = s + 2 * np.arange(30)
    root, q = cw.windows([first], speed=[2.0])
    want = cw.root[frames][None], cw.q[frames][None]  # the clip's own frames, not normalised
    np.testing.assert_array_equal(root, want[0])  # whole frames are exact
    np.testing.assert_array_equal(q, want[1])
    # 1.5x: odd frames fall half-way between two frames: root lerp and slerp of the clip's own poses
    from inbetweening.geometry.interp import interpolate_pose
    t = s + 1.5 * np.arange(30)
    f0 = np.floor(t).astype(int)
    r_mid, q_mid = interpolate_pose(cw.root[f0], cw.q[f0], cw.root[f0 + 1], cw.q[f0 + 1], t - f0)
    root, q = cw.windows([first], speed=[1.5])
    want = r_mid[None], q_mid[None]
    np.testing.assert_allclose(root, want[0], atol=1e-6)
    np.testing.assert_allclose(q, want[1], atol=1e-6)
    assert not np.allclose(root, plain[0][first])
    # the last window of a clip has no room to speed up: capped at what stays inside the clip, never past its end
    last = int(np.argmin(cw.max_speed(idx)))
    assert cw.max_speed([last])[0] < 1.2
    for a, b in zip(cw.windows([last], speed=[3.0]), cw.windows([last], speed=cw.max_speed([last]))):
        np.testing.assert_array_equal(a, b)


def test_a_time_warp_that_varies_within_the_window(cache_dir):
    d = load_dataset("synthetic", cache_dir=cache_dir, synthetic={"num_clips": 6, "min_frames": 120, "max_frames": 160})
    cw = ClipWindows(d.train, d.skeleton, 30, 10)
    idx = np.arange(len(cw))
    first = int(np.argmax(cw.max_speed(idx) >= 2))
    # equal ends: the constant speed, exactly
    for a, b in zip(cw.windows([first], speed=[[1.5, 1.5]]), cw.windows([first], speed=[1.5])):
        np.testing.assert_array_equal(a, b)
    # 0.5 -> 1.5: the clip time advances by the mean of the speeds at each step's two ends (the test's own sum)
    rate = 0.5 + np.linspace(0, 1, 30)
    t = cw.starts[first] + np.concatenate([[0.0], np.cumsum((rate[1:] + rate[:-1]) / 2)])
    from inbetweening.geometry.interp import interpolate_pose
    f0 = np.floor(t + 1e-9).astype(int)
    want = interpolate_pose(cw.root[f0], cw.q[f0], cw.root[f0 + 1], cw.q[f0 + 1], t - f0)
    got = cw.windows([first], speed=[[0.5, 1.5]])
    np.testing.assert_allclose(got[0][0], want[0], atol=1e-6)
    np.testing.assert_allclose(got[1][0], want[1], atol=1e-6)
    # too fast for the clip's end: slowed as a whole, the last frame the clip's last
    last = int(np.argmin(cw.max_speed(idx)))
    root, _ = cw.windows([last], speed=[[3.0, 4.0]])
    np.testing.assert_array_equal(root[0, -1], cw.root[cw.ends[last] - 1])


def test_data_module_time_warp_is_seeded_and_changes_the_windows(tmp_path, cache_dir):
    warp = _dm(tmp_path, cache_dir, "data.speed=[1.0,2.0]")
    plain = _dm(tmp_path, cache_dir)
    batch, again = (next(iter(warp.train_dataloader())) for _ in range(2))
    assert all(torch.equal(batch[k], again[k]) for k in batch)  # a pure function of seed, epoch, batch
    idx = [i for *_, i in next(iter(warp.train_dataloader().batch_sampler))]
    (ar, aq), (br, bq) = warp._train_windows(idx, torch.Generator().manual_seed(0)), plain._train_windows(idx, None)
    assert ar.shape == br.shape and aq.shape == bq.shape and torch.isfinite(ar).all() and torch.isfinite(aq).all()
    assert not torch.allclose(ar, br)
    again_r, again_q = plain._train_windows(idx, torch.Generator().manual_seed(0))
    assert torch.equal(again_r, br) and torch.equal(again_q, bq)  # no speed: nothing drawn, the plain windows


def test_config_rejects_bad_task_options(tmp_path, cache_dir):
    for extra, match in [(["data.context_min=0"], "data.context_min/max"),
                         (["data.context_min=5", "data.context_max=11"], "data.context_min/max"),
                         (["data.keyframe_prob=1.5"], "data.keyframe_prob"),
                         (["data.speed=[0.1,1.0]"], r"data.speed: need 0.25 <= lo"),
                         (["data.speed_vary=yes"], "data.speed_vary: must be true or false"),
                         (["data.mix_parts=1"], "data.mix_parts: must be false, true"),
                         (["data.mix_parts=legs"], "data.mix_parts: must be false, true"),
                         (["data.extra_repeat=0"], "data.extra_repeat: must be an integer >= 1"),
                         (["data.speed=fast"], "data.speed: must be null or"),
                         (["centre=middle"], "centre")]:
        cfg = compose_cfg("train", [*DATA, *extra], tmp_path, cache_dir)
        with pytest.raises(ConfigError, match=match):
            validate(cfg)


def test_data_module_varying_warp_and_part_mixing_are_seeded(tmp_path, cache_dir):
    dm = _dm(tmp_path, cache_dir, "data.speed=[0.5,2.0]", "data.speed_vary=true", "data.mix_parts=true")
    plain = _dm(tmp_path, cache_dir)
    batch, again = (next(iter(dm.train_dataloader())) for _ in range(2))
    assert all(torch.equal(batch[k], again[k]) for k in batch)  # a pure function of seed, epoch, batch
    other = next(iter(plain.train_dataloader()))
    assert torch.isfinite(batch["q"]).all() and not torch.equal(batch["q"], other["q"])


def test_data_module_limb_mixing_is_seeded_and_differs_from_upper_body_mixing(tmp_path, cache_dir):
    limbs, upper, plain = (_dm(tmp_path, cache_dir, *extra) for extra in
                           (["data.mix_parts=limbs"], ["data.mix_parts=upper"], []))
    assert len(limbs.parts) > 1 and len(upper.parts) == 1
    assert torch.equal(sum(p.int() for p in limbs.parts) <= upper.parts[0].int(), torch.ones_like(upper.parts[0]))
    a, b, c = (next(iter(m.train_dataloader())) for m in (limbs, upper, plain))
    assert torch.equal(a["q"], next(iter(limbs.train_dataloader()))["q"])  # seeded
    assert not torch.equal(a["q"], c["q"]) and not torch.equal(a["q"], b["q"])
