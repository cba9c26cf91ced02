"""Any humanoid character through the front ends: the Python API (``Inbetweener``) and ``python -m inbetweening.predict``
fill a clip of another skeleton with the shipped model by retargeting (the bone map detected, or overridden), keep
every key of every bone exactly, and refuse a rig that cannot be mapped with one line and an override template.
Characters are generated from a real Bandai-Namco-2 walk of the model's skeleton (tests/characters.py); real rigs of
other skeletons come from Debian's assimp-testmodels (skipped where absent)."""
from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pytest

from characters import character
from inbetweening.api.inbetweener import Inbetweener, InbetweenError
from inbetweening.cli import predict
from inbetweening.data.bvh import BVH, read_bvh
from inbetweening.data.bvh_writer import write_bvh
from inbetweening.data.clips import clip_in_skeleton
from inbetweening.geometry.interp import interpolate_keyframes
from inbetweening.geometry.quaternion import remove_discontinuities
from inbetweening.geometry.skeleton import fk
from inbetweening.runtime.retarget import euler_sign

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "models" / "bn2_reference" / "model.ckpt"
DATA = ROOT.parent / "shared" / "datasets" / "bandai-namco-2.zip"
WALK = "Bandai-Namco-Research-Motiondataset-2/data/dataset-2_walk_normal_010.bvh"  # a standard-split test clip
CMU = Path("/usr/share/assimp/models/BVH/01_01.bvh")


@pytest.fixture(scope="module")
def ib():
    return Inbetweener.from_checkpoint(MODEL)


@pytest.fixture(scope="module")
def motion(ib, tmp_path_factory):
    """A real motion of the model's skeleton: the first 91 frames of a Bandai-Namco-2 standard-test walk, in the
    project's frame."""
    if not DATA.exists():
        pytest.skip("Bandai-Namco-2 is not beside the checkout")
    path = tmp_path_factory.mktemp("walk") / "walk.bvh"
    with zipfile.ZipFile(DATA) as z:
        path.write_bytes(z.read(WALK))
    _, root, q = clip_in_skeleton(read_bvh(path), ib.skeleton)
    convention = ib.runtime.info.convention
    if not convention.is_project:
        root, q = convention.to_project(root, q)
    return root[:91], q[:91]


@pytest.fixture(scope="module")
def character_file(ib, motion, tmp_path_factory):
    rig, slots = character(ib.skeleton, *motion, a_pose=30.0, scale={"legs": 1.1, "UpperArm_L": 0.9, "UpperArm_R": 0.9})
    path = tmp_path_factory.mktemp("character") / "mannequin.bvh"
    write_bvh(rig, path)
    return path, slots


def test_the_api_fills_another_humanoid_with_every_key_exact(ib, motion, character_file):
    path, slots = character_file
    rig = read_bvh(path)
    keys = [0, 20, 45, 90]
    res = ib.fill_detailed(path, keyframes=keys)
    assert res.bone_map is not None and res.bone_map.slots == slots  # detected from the UE-style names
    out = res.bvh
    assert out.names == rig.names and out.channels == rig.channels and out.num_frames == 91
    assert np.array_equal(out.motion[keys], rig.motion[keys])  # every bone's keys, bit for bit
    assert np.isfinite(out.motion).all()
    # the fill on the character is as good as the model's own fill of the same keys (ratio to interpolation)
    root, q = motion
    q = q.copy()
    q[:1] = euler_sign(q[:1])  # the signs a file gives quaternions (the network reads q and -q differently)
    q = remove_discontinuities(q, axis=0)
    hidden = ~np.isin(np.arange(91), keys)
    native = ib.fill_arrays(np.where(hidden[:, None], np.nan, root), np.where(hidden[:, None, None], np.nan, q), keys)
    gen = np.flatnonzero(hidden)
    lerp = interpolate_keyframes(root, q, keys)
    sk = ib.skeleton
    t, f, i = (sk.pose(*m)[1][gen] for m in ((root, q), native[:2], lerp))
    native_ratio = np.linalg.norm(f - t, axis=-1).mean() / np.linalg.norm(i - t, axis=-1).mean()
    parents = rig.skeleton().parents
    rig_t = fk(rig.local_rotations(), rig.channel_positions(), parents)[1][gen]
    rig_f = fk(out.local_rotations(), out.channel_positions(), parents)[1][gen]
    lp_i, lq_i = interpolate_keyframes(rig.channel_positions().reshape(91, -1), rig.local_rotations(), keys)
    rig_i = fk(lq_i, lp_i.reshape(91, -1, 3), parents)[1][gen]
    rig_ratio = np.linalg.norm(rig_f - rig_t, axis=-1).mean() / np.linalg.norm(rig_i - rig_t, axis=-1).mean()
    assert rig_ratio <= max(native_ratio + 0.02, 1.0)  # (a wiggle, not a motion: both near interpolation here; real
    # clips: tests/test_character_invariance.py)
    assert not np.allclose(out.motion[1:20], out.motion[0])  # frames were generated


def test_a_wrong_guess_is_overridden_and_an_unknown_bone_refused(ib, character_file):
    path, slots = character_file
    res = ib.fill_detailed(path, keyframes=[0, 30, 60], bone_map={slots["Chest"]: None, "spine_02": "Chest"})
    assert res.bone_map.slots["Chest"] == "spine_02" and res.bone_map.how["Chest"] == "override"
    with pytest.raises(InbetweenError, match="no_such_bone"):
        ib.fill(path, keyframes=[0, 30], bone_map={"no_such_bone": "Chest"})


def _snake(path: Path) -> Path:
    n = 8
    names = [f"segment_{i}" for i in range(n)]
    rig = BVH(names, np.arange(-1, n - 1), np.array([[0.0, 0.0, 10.0]] * n), [("Xposition", "Yposition", "Zposition",
              "Zrotation", "Xrotation", "Yrotation")] + [("Zrotation", "Xrotation", "Yrotation")] * (n - 1),
              {n - 1: np.array([0.0, 0.0, 5.0])}, 1 / 30, np.zeros((40, 6 + 3 * (n - 1))), str(path))
    write_bvh(rig, path)
    return path


def test_predict_prints_and_saves_the_map_and_refuses_a_snake_with_a_template(character_file, tmp_path, capsys):
    path, _ = character_file
    out = tmp_path / "filled.bvh"
    assert predict.run([f"input={path}", "keyframes=[0,30,60,90]", f"output={out}"]) == 0
    printed = capsys.readouterr().out
    saved = tmp_path / "filled.bvh.bone_map.yaml"
    assert "bone map" in printed and saved.is_file() and "pelvis" in saved.read_text()
    assert predict.run([f"input={path}", "keyframes=[0,30,60,90]", f"output={tmp_path / 'again.bvh'}",
                        f"bone_map={saved}"]) == 0  # the saved map, passed back
    assert np.array_equal(read_bvh(tmp_path / "again.bvh").motion, read_bvh(out).motion)
    snake = _snake(tmp_path / "snake.bvh")
    with pytest.raises(SystemExit) as e:
        predict.run([f"input={snake}", "keyframes=[0,20]", f"output={tmp_path / 'snake_out.bvh'}"])
    err = capsys.readouterr().err
    assert e.value.code == 2 and err.count("\n") == 1 and "not a humanoid" in err and "Traceback" not in err
    template = tmp_path / "snake_out.bvh.bone_map.yaml"
    assert template.is_file() and "segment_0" in template.read_text() and str(template) in err
    assert not (tmp_path / "snake_out.bvh").exists()  # nothing written but the template


@pytest.mark.skipif(not CMU.is_file(), reason="assimp-testmodels not installed")
def test_a_real_cmu_clip_at_120_fps(ib, tmp_path):
    """CMU's skeleton (31 joints, LHipJoint, LowerBack on the hips, 120 fps): keys every second of the file, the output
    keeps the keys' rows and the file's hierarchy, the body stays upright and its hips move with the keys'."""
    clip = read_bvh(CMU)
    keys = list(range(0, 601, 120))
    res = ib.fill_detailed(clip, keyframes=keys)
    out = res.bvh
    assert res.bone_map.slots["Spine"] == "LowerBack" and res.bone_map.slots["UpperArm_L"] == "LeftArm"
    assert np.array_equal(out.motion[keys], clip.motion[keys]) and out.frame_time == clip.frame_time
    gp = fk(out.local_rotations(), out.channel_positions(), out.parents)[1]
    head, hips = out.names.index("Head"), out.names.index("Hips")
    assert (gp[:, head, 1] > gp[:, hips, 1]).all()  # upright on every generated frame
    step = np.linalg.norm(np.diff(gp[:, hips], axis=0), axis=-1)
    assert step.max() < 1.0  # no jump between frames (CMU units: the body is about 25 tall)


def test_partial_keys_on_another_humanoid_keep_their_bones_and_move_the_fill(ib, character_file):
    path, slots = character_file
    rig = read_bvh(path)
    arm = [slots[s] for s in ("UpperArm_L", "LowerArm_L", "Hand_L")]
    keys = [0, 45, 90]
    out = ib.fill(path, keyframes=keys, partial={20: arm})
    whole = ib.fill(path, keyframes=keys)
    ends = np.cumsum([len(ch) for ch in rig.channels])
    cols = np.concatenate([np.arange(ends[j] - len(rig.channels[j]), ends[j]) for j in map(rig.names.index, arm)])
    assert np.array_equal(out.motion[20, cols], rig.motion[20, cols])
    assert np.array_equal(out.motion[keys], rig.motion[keys]) and np.isfinite(out.motion).all()
    hand = rig.names.index(slots["Hand_L"])
    gp = {k: read.skeleton().pose(read.channel_positions()[:, 0], read.local_rotations())[1][:, hand]
          for k, read in (("out", out), ("whole", whole), ("rig", rig))}
    # the hand passes through its key: closer to where it was keyed than the fill without the partial key
    assert np.linalg.norm(gp["out"][20] - gp["rig"][20]) < 0.5 * np.linalg.norm(gp["whole"][20] - gp["rig"][20])
    assert not np.allclose(out.motion[21:45], whole.motion[21:45])
