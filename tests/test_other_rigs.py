"""Takes of other rigs as training data (``data.extra``, :mod:`inbetweening.training.other_rigs`): a character generated
from the model's own motion (other names, metres, Z up, extra bones, 60 fps, a T-pose as its first frame) comes back as
that motion on the model's skeleton at the dataset's rate, checked with the test's own pose comparison (heights and
horizontal distances from the hips, which no turn about the up axis changes); a rig that cannot be mapped is one line
naming the file; the datamodule trains on the added clips."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from characters import character, model_walk
from inbetweening.api.inbetweener import Inbetweener
from inbetweening.data.bvh_writer import write_bvh
from inbetweening.data.errors import DatasetError
from inbetweening.training.other_rigs import other_rig_clips

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "models" / "bn2_reference" / "model.ckpt"


@pytest.fixture(scope="module")
def skeleton():
    return Inbetweener.from_checkpoint(MODEL).skeleton


def _body(skeleton, root, q):
    """Each joint's height over the hips and horizontal distance from them, per frame (cm)."""
    p = skeleton.pose(root, q)[1]
    rel = p - p[:, :1]
    return rel[..., 1], np.linalg.norm(rel[..., [0, 2]], axis=-1)


def _rig_file(folder: Path, skeleton, frames=121, tpose_first=True):
    root, q = model_walk(skeleton, frames)
    rig, _ = character(skeleton, root, q, extras=True)  # UE names, metres, Z up, twist bones and fingers
    if tpose_first:
        rest = rig.with_motion(rig.local_rotations()[:1] * 0 + np.array([1.0, 0, 0, 0]), rig.channel_positions()[:1])
        rig = rig.with_motion(np.concatenate([rest.local_rotations(), rig.local_rotations()]),
                              np.concatenate([rest.channel_positions(), rig.channel_positions()]))
    folder.mkdir(parents=True, exist_ok=True)
    write_bvh(rig.with_motion(rig.local_rotations(), rig.channel_positions(), frame_time=1 / 60), folder / "take.bvh")
    return root, q


def test_another_rig_comes_back_as_the_models_motion_at_the_datasets_rate(skeleton, tmp_path):
    root, q = _rig_file(tmp_path / "rig", skeleton)
    clips = other_rig_clips(tmp_path / "rig", skeleton, 30.0, tmp_path / "cache")
    assert [c.name for c in clips] == ["rig/take"]
    c = clips[0]
    assert c.num_frames == 61 and c.local_q.shape == (61, skeleton.num_joints, 4)  # 120 frames at 60 fps, T-pose gone
    want_h, want_d = _body(skeleton, root[::2], q[::2])
    got_h, got_d = _body(skeleton, c.root_pos, c.local_q)
    assert np.abs(got_h - want_h).max() < 1.0 and np.abs(got_d - want_d).max() < 1.0
    # cached: the same clips again, read from the cache entry
    entry = list((tmp_path / "cache" / "other_rigs").glob("rig-*.npz"))
    assert len(entry) == 1
    again = other_rig_clips([tmp_path / "rig"], skeleton, 30.0, tmp_path / "cache")
    assert np.array_equal(again[0].local_q, c.local_q) and np.array_equal(again[0].root_pos, c.root_pos)


def test_the_tpose_frame_is_dropped_only_where_there_is_one(skeleton, tmp_path):
    _rig_file(tmp_path / "plain", skeleton, frames=61, tpose_first=False)
    assert other_rig_clips(tmp_path / "plain", skeleton, 60.0, tmp_path / "cache")[0].num_frames == 61


def test_a_rig_that_cannot_be_mapped_is_one_line_naming_the_file(skeleton, tmp_path):
    folder = tmp_path / "worm"
    folder.mkdir()
    (folder / "worm.bvh").write_text("HIERARCHY\nROOT a\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition "
                                     "Zrotation Xrotation Yrotation\n JOINT b\n {\n  OFFSET 0 1 0\n  CHANNELS 3 Zrotation "
                                     "Xrotation Yrotation\n  End Site\n  {\n   OFFSET 0 1 0\n  }\n }\n}\nMOTION\nFrames: 2\n"
                                     "Frame Time: 0.033333\n0 0 0 0 0 0 0 0 0\n0 0 0 0 0 0 0 0 0\n")
    with pytest.raises(DatasetError, match=r"worm") as e:
        other_rig_clips(folder, skeleton, 30.0, tmp_path / "cache")
    assert "\n" not in str(e.value)
    with pytest.raises(DatasetError, match=r"^data.extra: '.*missing' does not exist"):
        other_rig_clips(tmp_path / "missing", skeleton, 30.0, tmp_path / "cache")


def test_a_dataset_of_another_skeleton_cannot_take_other_rigs(tmp_path):
    from inbetweening.data.datasets import load_dataset

    d = load_dataset("synthetic", cache_dir=tmp_path, synthetic={"num_clips": 5, "min_frames": 70, "max_frames": 70})
    with pytest.raises(DatasetError, match=r"^data.extra: other rigs are moved onto a skeleton of the humanoid slots"):
        other_rig_clips(tmp_path, d.skeleton, 30.0, tmp_path / "cache")
