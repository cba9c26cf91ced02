"""data=bvh: a folder of any rig's BVH files as a dataset, its spec derived from the files (data/bvh_folder.py)."""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from conftest import TINY, compose_cfg, model_overrides
from inbetweening.data.bvh import BVH, read_bvh
from inbetweening.data.bvh_folder import FolderOptions, derive_spec, hash_split
from inbetweening.data.bvh_writer import write_bvh
from inbetweening.data.clips import top_is_static
from inbetweening.data.contacts import REFERENCE_HEIGHT_CM, find_feet
from inbetweening.data.convention import FileConvention, parse_unit
from inbetweening.data.datasets import load_dataset
from inbetweening.data.errors import BVHError, DatasetError
from inbetweening.data.mirror import derive_mirror
from inbetweening.geometry.quaternion import euler_to_quat_np, qinv, qmul, qnormalize, qrot
from inbetweening.geometry.skeleton import fk
from rigs import FPS, TRUE, write_other_rig

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def rig(tmp_path_factory) -> Path:
    return write_other_rig(tmp_path_factory.mktemp("rig"))


def test_the_other_rig_is_derived_as_it_was_made(rig):
    """Up axis, unit, forward axis, feet, folded top joint, frame rate and joint count: the generator's truth."""
    spec, rep = derive_spec([rig], FolderOptions())
    assert rep["up_axis"] == TRUE["up_axis"] and rep["unit"] == TRUE["unit"] and rep["unit_cm"] == TRUE["unit_cm"]
    assert rep["forward_axis"] == TRUE["forward_axis"] == list(spec.forward_axis)
    assert rep["feet"] == TRUE["feet"] == list(spec.feet) and rep["feet_from"] == "joint names"
    assert rep["skeleton"] == {"joints": TRUE["joints"], "root": "hips", "folded_top_joint": TRUE["folded"]}
    assert rep["fps"] == spec.fps == FPS and rep["resampled_files"] == 0
    assert rep["forward_measure"]["agreement"] > 0.9
    # the thresholds scale with the body: the synthetic body is taller than Bandai-Namco-2's
    k = rep["body_height_cm"] / REFERENCE_HEIGHT_CM
    assert 1.0 < k < 1.2 and spec.contact_height == pytest.approx(15.0 * k, rel=1e-4) \
        and spec.contact_speed == pytest.approx(30 * k, rel=1e-4)
    assert ("thigh.L", "thigh.R") in spec.mirror and len(spec.mirror) == 7
    assert rep["train_files"] + rep["test_files"] == 12 and rep["test_files"] >= 1


def test_the_clips_are_in_the_project_frame(rig, tmp_path):
    """Y up and centimetres after loading: the hips sit about a metre above the floor, whatever the file said."""
    data = load_dataset("bvh", path=rig, cache_dir=tmp_path)
    assert data.convention == FileConvention("z", 100.0) and data.contact.feet == ("foot.L", "foot.R")
    c = data.train[0]
    gp = data.skeleton.pose(c.root_pos, c.local_q)[1]
    assert 80 < np.median(c.root_pos[:, 1]) < 100  # synthetic hips: 95 cm minus the gait's bob
    assert np.percentile(gp[:, data.skeleton.index("foot.L"), 1], 10) < 15  # the feet reach the floor (y = 0)
    again = load_dataset("bvh", path=rig, cache_dir=tmp_path)  # from the cache, with everything derived
    assert again.derived == data.derived and again.mirror == data.mirror and again.contact == data.contact


def test_convention_round_trip_and_rotation():
    rng = np.random.default_rng(0)
    root, q = rng.normal(size=(5, 3)), qnormalize(rng.normal(size=(5, 4, 4)))
    for conv in (FileConvention("z", 100.0), FileConvention("y", 2.54)):
        r2, q2 = conv.to_file(*conv.to_project(root, q))
        assert np.allclose(r2, root, atol=1e-12) and np.allclose(q2, q, atol=1e-12)
    up = FileConvention("z", 100.0).to_project(np.array([[0.0, 0.0, 1.0]]), q[:1])[0]
    assert np.allclose(up, [[0.0, 100.0, 0.0]])  # 1 m along Z up = 100 cm along Y up
    same = FileConvention()
    r3, q3 = same.to_project(root, q)
    assert np.array_equal(r3, root) and np.array_equal(q3, q)  # the project's own files: bit for bit
    assert parse_unit("m") == ("m", 100.0) and parse_unit(2.54) == ("inch", 2.54)
    with pytest.raises(ValueError, match="data.unit must be one of"):
        parse_unit("furlong")


def test_mixed_frame_rates_are_resampled_to_the_most_common(rig, tmp_path):
    folder = tmp_path / "mixed"
    shutil.copytree(rig, folder)
    slow = read_bvh(rig / "take_00.bvh")
    slow.motion, slow.frame_time = slow.motion[::2].copy(), 2 / FPS  # the same take at 30 fps
    write_bvh(slow, folder / "take_00_30fps.bvh")
    spec, rep = derive_spec([folder], FolderOptions())
    assert rep["file_rates"] == {"30": 1, "60": 12} and rep["fps"] == 60.0 and rep["resampled_files"] == 1
    clips = {f: c for f, c, _, _ in spec.reader(spec, folder)}
    a, b = clips["take_00.bvh"], clips["take_00_30fps.bvh"]
    assert b.num_frames == 2 * (slow.num_frames - 1) + 1
    assert np.allclose(b.root_pos[::2], a.root_pos[: b.num_frames : 2])  # the 30 fps frames land on their times
    assert np.abs(b.root_pos[1::2] - a.root_pos[1 : b.num_frames : 2]).max() < 1.0  # in between: interpolated (cm)
    spec30, rep30 = derive_spec([folder], FolderOptions(fps=30))
    assert rep30["fps"] == 30.0 and rep30["resampled_files"] == 12


def test_overrides_win_and_are_reported(rig):
    spec, rep = derive_spec([rig], FolderOptions(up_axis="z", unit="cm", forward_axis=[0, 0, 1], feet=["shin.L"],
                                                 test_pattern=["take_0[0-2].bvh"], contact_height=3.0))
    assert rep["unit_cm"] == 1.0 and spec.forward_axis == (0.0, 0.0, 1.0) and spec.feet == ("shin.L",)
    assert rep["test_files"] == 3 and spec.split("take_01.bvh") == "test" and spec.split("take_05.bvh") == "train"
    assert spec.contact_height == 3.0 and set(rep["overrides"]) == {"up_axis", "unit", "forward_axis", "feet",
                                                                     "test_pattern", "contact_height"}


def test_hash_split_is_stable_per_file():
    names = [f"clip_{i:03d}.bvh" for i in range(200)]
    rule = hash_split(names)
    test = {n for n in names if rule(n) == "test"}
    assert 10 <= len(test) <= 30  # about one in ten
    more = hash_split(names + [f"new_{i}.bvh" for i in range(50)])
    assert {n for n in names if more(n) == "test"} == test  # adding files moves no existing file
    few = hash_split(["a.bvh", "b.bvh", "c.bvh"])
    assert sum(few(n) == "test" for n in ("a.bvh", "b.bvh", "c.bvh")) >= 1


def test_feet_without_foot_names_are_the_lowest_leaves_of_two_limbs():
    names = ("root", "l1", "l2", "l3", "r1", "r2", "r3", "s1", "head", "a1", "a2")
    parents = (-1, 0, 1, 2, 0, 4, 5, 0, 7, 7, 9)
    heights = np.array([90, 50, 10, 2, 50, 10, 3, 120, 150, 110, 80.0])
    feet, how = find_feet(names, parents, heights)
    assert feet == ("l2", "l3", "r2", "r3") and "lowest leaf" in how
    assert find_feet(("Hips", "mixamorig:LeftFoot", "mixamorig:RightFoot"), (-1, 0, 0), np.zeros(3))[0] == (
        "mixamorig:LeftFoot", "mixamorig:RightFoot")


def test_side_markers_of_common_rigs():
    assert derive_mirror(["hips", "thigh.L", "thigh.R", "foot_l", "foot_r", "mixamorig:LeftArm",
                          "mixamorig:RightArm", "L_hand", "R_hand"]) == (
        ("thigh.L", "thigh.R"), ("foot_l", "foot_r"), ("mixamorig:LeftArm", "mixamorig:RightArm"), ("L_hand", "R_hand"))


# ------------------------------------------------------------------ bad input: one clear error
def _one_file(rig: Path, folder: Path, name: str = "take_00.bvh") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copy(rig / name, folder / name)
    return folder


def test_bad_folders_get_one_clear_error(rig, tmp_path):
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "notes.txt").write_text("no motion here")
    with pytest.raises(DatasetError, match=r"data.path: .*empty holds no BVH file"):
        derive_spec([tmp_path / "empty"], FolderOptions())
    with pytest.raises(DatasetError, match=r"1 BVH file\(s\) .* a split needs at least two"):
        derive_spec([_one_file(rig, tmp_path / "one")], FolderOptions())
    broken = _one_file(rig, tmp_path / "broken")
    _one_file(rig, broken, "take_01.bvh")
    (broken / "take_02.bvh").write_text((rig / "take_02.bvh").read_text().replace("MOTION", "MOTON"))
    with pytest.raises(BVHError, match=r"^take_02.bvh:\d+: "):
        derive_spec([broken], FolderOptions())
    with pytest.raises(DatasetError, match=r"data.test_pattern: 'nothing\*' matches none of the 12 files"):
        derive_spec([rig], FolderOptions(test_pattern="nothing*"))
    with pytest.raises(DatasetError, match=r"data.path: .*missing does not exist"):
        load_dataset("bvh", path=tmp_path / "missing", cache_dir=tmp_path / "c")


def test_mixed_skeletons_name_the_first_file_that_differs(rig, tmp_path):
    mixed = _one_file(rig, tmp_path / "mixed")
    _one_file(rig, mixed, "take_01.bvh")
    text = (rig / "take_02.bvh").read_text().replace("JOINT neck", "JOINT neck_twist")
    (mixed / "take_02.bvh").write_text(text)
    with pytest.raises(DatasetError, match=r"^take_02.bvh: mixed skeletons: .*joint 10 is 'neck_twist', in take_00.bvh "
                                           r"it is 'neck'"):
        derive_spec([mixed], FolderOptions())
    fewer = read_bvh(rig / "take_03.bvh")  # a file without the top joint (it is folded elsewhere: another skeleton)
    fewer.names, fewer.parents = fewer.names[1:], fewer.parents[1:] - 1
    fewer.offsets, fewer.channels = fewer.offsets[1:], fewer.channels[1:]
    fewer.end_sites = {j - 1: o for j, o in fewer.end_sites.items()}
    fewer.motion = fewer.motion[:, 6:]
    fewer.parents[0] = -1
    write_bvh(fewer, mixed / "take_02.bvh")
    spec, _ = derive_spec([mixed], FolderOptions())  # the same joints once Armature is folded: one skeleton
    assert spec.feet == ("foot.L", "foot.R")
    with pytest.raises(DatasetError, match=r"take_02.bvh: mixed skeletons: .*\(20 joints, take_00.bvh has 21\)"):
        derive_spec([mixed], FolderOptions(fold_root=False))


def _top_motion(f: int, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """A top joint carrying a dash (file frame: Z up, metres): yaw about Z and a run along X with a sideways sway."""
    t = np.linspace(0.0, 1.0, f)
    yaw = scale * (70.0 * t - 25.0)
    top_q = euler_to_quat_np(np.stack([np.zeros(f), np.zeros(f), yaw], axis=1), "xyz")
    return top_q, scale * np.stack([4.0 * t, 0.3 * np.sin(7.0 * t), np.zeros(f)], axis=1)


def _moving_top(b: BVH) -> BVH:
    """The take with its still top joint (``Armature``) now carrying a dash, the hips re-expressed under it: the
    same world motion, the top joint's translation and yaw changing every frame."""
    top_q, top_p = _top_motion(b.num_frames)
    q, p = b.local_rotations(), b.channel_positions()
    hips_q, hips_p = qmul(q[:, 0], q[:, 1]), p[:, 0] + qrot(q[:, 0], p[:, 1])
    q[:, 0], p[:, 0] = top_q, top_p
    q[:, 1], p[:, 1] = qmul(qinv(top_q), hips_q), qrot(qinv(top_q), hips_p - top_p)
    return b.with_motion(q, p)


def _under_top(b: BVH, name: str, top_q: np.ndarray, top_p: np.ndarray) -> BVH:
    """The take under one more top joint ``name`` (6 channels), the old top's channels re-expressed under it."""
    q, p = b.local_rotations(), b.channel_positions()
    q0, p0 = qmul(qinv(top_q), q[:, 0]), qrot(qinv(top_q), p[:, 0] - top_p)
    shell = BVH([name, *b.names], np.concatenate([[-1], b.parents + 1]), np.vstack([np.zeros(3), b.offsets]),
                [b.channels[0], *b.channels], {j + 1: o for j, o in b.end_sites.items()}, b.frame_time,
                np.zeros((b.num_frames, b.motion.shape[1] + len(b.channels[0]))))
    return shell.with_motion(np.concatenate([top_q[:, None], q0[:, None], q[:, 1:]], axis=1),
                             np.concatenate([top_p[:, None], p0[:, None], p[:, 1:]], axis=1))


def test_a_top_joint_that_moves_in_some_takes_folds_in_every_take(rig, tmp_path):
    """A folder whose top joint carries the locomotion in one take (a dash: translation and yaw) and is still in the
    others loads as one skeleton, the moving take folded by composition: its joints' world trajectories are the
    file's (FK of the file's own channels, in the project's frame) to 1e-6 cm."""
    folder = tmp_path / "dash"
    shutil.copytree(rig, folder)
    write_bvh(_moving_top(read_bvh(rig / "take_05.bvh")), folder / "take_05.bvh")
    moving = read_bvh(folder / "take_05.bvh")
    assert not top_is_static(moving) and np.ptp(moving.motion[:, :3], axis=0).max() > 3.0  # metres
    assert top_is_static(read_bvh(folder / "take_04.bvh"))
    spec, rep = derive_spec([folder], FolderOptions())
    assert rep["skeleton"] == {"joints": TRUE["joints"], "root": "hips", "folded_top_joint": "Armature"}
    assert (rep["up_axis"], rep["unit"], rep["forward_axis"]) == (TRUE["up_axis"], TRUE["unit"], TRUE["forward_axis"])
    read = {f: (c, sk) for f, c, sk, _ in spec.reader(spec, folder)}
    assert len(read) == 12 and len({sk.names for _, sk in read.values()}) == 1
    clip, sk = read["take_05.bvh"]
    conv = FileConvention(rep["up_axis"], rep["unit_cm"])
    world = fk(moving.local_rotations(), moving.channel_positions(), list(moving.parents))[1][:, 1:]  # below Armature
    want = conv.unit_cm * qrot(np.broadcast_to(conv.rotation, world.shape[:-1] + (4,)), world)
    assert np.abs(clip.root_pos - want[:, 0]).max() <= 1e-6  # the hips' world trajectory (cm)
    assert np.abs(sk.pose(clip.root_pos, clip.local_q)[1] - want).max() <= 1e-6  # every joint
    data = load_dataset("bvh", path=folder, cache_dir=tmp_path / "c")  # data=bvh data.path=<folder>
    assert data.skeleton.names == sk.names and len(data.train) + len(data.test) == 12


def test_a_moving_top_joint_above_a_chain_is_still_mixed(rig, tmp_path):
    """A top joint that moves in one take and holds still in the others, above a child that does not branch (here
    above ``Armature``): not hips-like, so not folded where it moves; the folder is refused with one line saying so,
    and ``data.fold_root=true`` folds it everywhere."""
    folder = tmp_path / "chain"
    folder.mkdir()
    for i in range(4):
        b = read_bvh(rig / f"take_{i:02d}.bvh")
        top_q, top_p = _top_motion(b.num_frames, scale=1.0 if i == 2 else 0.0)
        write_bvh(_under_top(b, "Scene", top_q, top_p), folder / f"take_{i:02d}.bvh")
    with pytest.raises(DatasetError, match=r"^take_02.bvh: mixed skeletons: the top joint 'Scene' moves in take_02.bvh "
                                           r"and its child 'Armature' is not where the body branches.*data.fold_root"):
        derive_spec([folder], FolderOptions())
    _, rep = derive_spec([folder], FolderOptions(fold_root=True, forward_axis=[0, 0, 1]))  # Armature: no travel
    assert rep["skeleton"] == {"joints": TRUE["joints"] + 1, "root": "Armature", "folded_top_joint": "Scene"}


def test_too_short_and_motionless_files(rig, tmp_path):
    short = tmp_path / "short"
    short.mkdir()
    for i in range(3):
        b = read_bvh(rig / f"take_{i:02d}.bvh")
        b.motion = b.motion[:40]
        write_bvh(b, short / f"take_{i:02d}.bvh")
    with pytest.raises(DatasetError, match=r"no training window of 50 frames could be cut: the longest training clip "
                                           r"has 40 frames"):
        load_dataset("bvh", path=short, cache_dir=tmp_path / "c", folder=FolderOptions(forward_axis=[0, -1, 0]))
    still = tmp_path / "still"
    still.mkdir()
    for i in range(3):
        b = read_bvh(rig / f"take_{i:02d}.bvh")
        b.motion[:, 6:9] = b.motion[:1, 6:9]  # the root never leaves its spot
        write_bvh(b, still / f"take_{i:02d}.bvh")
    with pytest.raises(DatasetError, match=r"data.forward_axis: no clip travels .* set data.forward_axis=\[x,y,z\]"):
        derive_spec([still], FolderOptions())


def test_bvh_keys_are_refused_by_the_named_datasets(tmp_path):
    with pytest.raises(DatasetError, match=r"data.test_pattern: only data=bvh derives its spec from the files"):
        load_dataset("synthetic", cache_dir=tmp_path, folder=FolderOptions(test_pattern="*_subject1.bvh"))


def test_cli_error_is_one_line_with_exit_2(tmp_path, cache_dir, capsys):
    from inbetweening.training.job import run_cli
    from inbetweening.training.train import train

    (tmp_path / "empty").mkdir()
    cfg = compose_cfg("train", ["data=bvh", f"data.path={tmp_path / 'empty'}", "logger=none", "callbacks=none"],
                      tmp_path / "run", cache_dir)
    with pytest.raises(SystemExit) as e:
        run_cli(train, cfg)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.startswith("error:")]
    assert e.value.code == 2 and len(lines) == 1 and "Traceback" not in err
    assert lines[0].startswith("error: data.path: ") and lines[0].endswith("holds no BVH file (*.bvh)")


# ------------------------------------------------------------------ another rig, end to end (train, eval, predict)
@pytest.mark.slow
def test_another_rig_end_to_end(rig, tmp_path, cache_dir):
    """``train.py data=bvh`` on the other rig (metres, XYZ, Z up, 60 fps), ``eval.py`` scores it (both protocols),
    ``predict`` fills one of its clips (keys bit-exact, the output in the file's own frame: metres, Z up), and the
    checkpoint exports to ONNX."""
    common = [f"data.path={rig}", f"paths.cache_dir={cache_dir}"]
    run = tmp_path / "run"
    train = [sys.executable, "train.py", "data=bvh", *common, *[o for o in TINY if not o.startswith("data.synthetic")],
             *model_overrides("graph_transformer"), "trainer.max_steps=30", "callbacks=none", "logger=none",
             "test_keyframes=[15]", "threads=1", f"hydra.run.dir={run}"]
    r = subprocess.run(train, cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    derived = yaml.safe_load((run / "dataset.yaml").read_text())
    assert (derived["up_axis"], derived["unit"], derived["forward_axis"], derived["feet"]) == (
        TRUE["up_axis"], TRUE["unit"], TRUE["forward_axis"], TRUE["feet"])
    assert "Dataset derived from the files" in r.stdout
    ckpt = sorted((run / "checkpoints").glob("*.ckpt"))[-1]
    for protocol in ("lafan", "keyframes"):
        ev = subprocess.run([sys.executable, "eval.py", "data=bvh", *common, f"ckpt_path='{ckpt}'", f"protocol={protocol}",
                             "keyframe_intervals=[15]", f"hydra.run.dir={tmp_path / protocol}"],
                            cwd=ROOT, capture_output=True, text=True, timeout=600)
        assert ev.returncode == 0, ev.stderr[-3000:]
        assert (tmp_path / protocol / "benchmark.json").exists()
    out = tmp_path / "filled.bvh"
    p = subprocess.run([sys.executable, "-m", "inbetweening.predict", f"ckpt_path={ckpt}", f"input={rig / 'take_04.bvh'}",
                        f"output={out}", "keyframes=[0,20,50,80]"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-3000:]
    a, b = read_bvh(rig / "take_04.bvh"), read_bvh(out)
    assert b.names == a.names and b.channels == a.channels and b.frame_time == a.frame_time and b.num_frames == 81
    for k in (0, 20, 50, 80):
        assert np.array_equal(b.motion[k], a.motion[k])
    onnx = tmp_path / "rig.onnx"
    ex = subprocess.run([sys.executable, "-m", "inbetweening.export", f"ckpt_path={ckpt}", "format=onnx", f"output={onnx}"],
                        cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert ex.returncode == 0 and onnx.stat().st_size > 0, ex.stderr[-3000:]
    hips_z = b.motion[:, 8]  # the hips' Zposition channel: metres above the floor, Z up
    assert 0.7 < hips_z.min() and hips_z.max() < 1.1
    assert np.abs(b.motion[:, 6:9] - a.motion[:81, 6:9]).max() < 0.5  # within half a metre of the truth


def test_init_from_another_skeleton_is_one_line(rig, tmp_path, cache_dir, tiny_checkpoint, capsys):
    """Fine-tuning the synthetic 22-joint model on the other rig (20 joints): one line naming both skeletons."""
    from inbetweening.training.job import run_cli
    from inbetweening.training.train import train

    cfg = compose_cfg("train", ["experiment=finetune", "data=bvh", f"data.path={rig}", f"init_from='{tiny_checkpoint}'",
                                "logger=none", "callbacks=none"], tmp_path / "run", cache_dir)
    with pytest.raises(SystemExit) as e:
        run_cli(train, cfg)
    lines = [line for line in capsys.readouterr().err.splitlines() if line.startswith("error:")]
    assert e.value.code == 2 and len(lines) == 1
    assert "22-joint skeleton (Hips, LeftUpLeg" in lines[0] and "data 'bvh' has 20 joints (hips, thigh.L" in lines[0]


def test_a_list_of_sources_and_duplicate_names(rig, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    for i in range(12):
        _one_file(rig, a if i < 6 else b, f"take_{i:02d}.bvh")
    both, rep = derive_spec([a, b], FolderOptions())
    one, _ = derive_spec([rig], FolderOptions())
    assert rep["files"] == 12 and both.forward_axis == one.forward_axis and both.feet == one.feet
    data = load_dataset("bvh", path=[str(a), str(b)], cache_dir=tmp_path / "c")
    assert len(data.train) + len(data.test) == 12 and data.source == f"{a}, {b}"
    _one_file(rig, tmp_path / "dup", "take_03.bvh")
    with pytest.raises(DatasetError, match=r"two files are called take_03.bvh"):
        derive_spec([a, tmp_path / "dup"], FolderOptions())
