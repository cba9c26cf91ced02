"""The animator tools never destroy data: an output that is the input is refused unless --force."""
from __future__ import annotations

import numpy as np
import pytest

from inbetweening.cli import export, predict
from inbetweening.data.bvh import read_bvh
from inbetweening.data.bvh_writer import write_bvh
from inbetweening.data.synthetic import generate_clip, make_bvh


@pytest.fixture
def clip_path(tmp_path):
    q, r = generate_clip(np.random.default_rng(3), 80)
    path = tmp_path / "clip.bvh"
    write_bvh(make_bvh(q, r), path)
    return path


def test_predict_refuses_to_overwrite_its_input(tiny_checkpoint, clip_path, capsys):
    before = clip_path.read_bytes()
    with pytest.raises(SystemExit) as e:
        predict.run([f"ckpt_path={tiny_checkpoint}", f"input={clip_path}", f"output={clip_path}", "keyframes=[10,40,70]"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("error: output:") and "is the input file" in err and "--force" in err
    assert len(err.strip().splitlines()) == 1
    assert clip_path.read_bytes() == before
    # a different spelling of the same path is the same file
    alias = clip_path.parent / "sub" / ".." / clip_path.name
    with pytest.raises(SystemExit):
        predict.run([f"ckpt_path={tiny_checkpoint}", f"input={clip_path}", f"output={alias}", "keyframes=[10,40,70]"])
    assert clip_path.read_bytes() == before
    # the checkpoint is protected too, and render= as well
    with pytest.raises(SystemExit):
        predict.run([f"ckpt_path={tiny_checkpoint}", f"input={clip_path}", f"output={tiny_checkpoint}",
                     "keyframes=[10,40,70]"])
    with pytest.raises(SystemExit):
        predict.run([f"ckpt_path={tiny_checkpoint}", f"input={clip_path}", f"output={clip_path.parent / 'o.bvh'}",
                     f"render={clip_path}", "keyframes=[10,40,70]"])
    assert clip_path.read_bytes() == before


def test_predict_force_overwrites_atomically(tiny_checkpoint, clip_path, capsys):
    assert predict.run([f"ckpt_path={tiny_checkpoint}", f"input={clip_path}", f"output={clip_path}",
                        "keyframes=[10,40,70]", "--force"]) == 0
    out = read_bvh(clip_path)
    assert out.motion.shape[0] == 61
    assert [p.name for p in clip_path.parent.iterdir()] == [clip_path.name]  # no temporary file left


def test_export_refuses_to_overwrite_the_checkpoint(tiny_checkpoint, capsys):
    before = tiny_checkpoint.read_bytes()
    with pytest.raises(SystemExit) as e:
        export.run([f"ckpt_path={tiny_checkpoint}", "format=ckpt", f"output={tiny_checkpoint}"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("error: output:") and "is the checkpoint being exported" in err
    assert tiny_checkpoint.read_bytes() == before
