"""The learned retargeter at run time (src/inbetweening/retarget/learned.py) and its command line
``python -m inbetweening.retarget`` (src/inbetweening/retarget/cli.py): a BVH of the target rig out, one-line errors
with exit status 2 for a rig the checkpoint was not trained for, a malformed BVH, an output path that is the input."""
from __future__ import annotations

import numpy as np
import pytest

from inbetweening.data.bvh import BVH, read_bvh
from inbetweening.data.bvh_writer import write_bvh
from inbetweening.retarget.cli import main
from inbetweening.retarget.learned import LearnedRetarget
from retarget_fixtures import rig_of, source_clips, source_skeleton, tiny_checkpoint


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("retarget")
    sk = source_skeleton()
    ckpt = tiny_checkpoint(d / "cmu.ckpt", sk)
    c = source_clips(sk, 1)[0]
    top = BVH(list(sk.names), list(sk.parents), sk.offsets, [("Xposition", "Yposition", "Zposition", "Zrotation",
              "Xrotation", "Yrotation")] * sk.num_joints, {}, 1 / 30, np.zeros((1, 6 * sk.num_joints)), "src.bvh")
    write_bvh(top.with_motion(c.local_q, sk.local_positions(c.root_pos)), d / "src.bvh")
    write_bvh(rig_of(sk, "cmu"), d / "cmu.bvh")
    write_bvh(rig_of(sk, "extras"), d / "other.bvh")
    return d, ckpt, c


def _fails(capsys, args, match):
    with pytest.raises(SystemExit) as e:
        main(args)
    err = capsys.readouterr().err.strip()
    assert e.value.code == 2 and len(err.splitlines()) == 1 and err.startswith("error: "), err
    assert match in err, err


def test_the_command_writes_the_target_rig(files, capsys):
    d, ckpt, c = files
    main([f"ckpt_path={ckpt}", f"input={d / 'src.bvh'}", f"output={d / 'out.bvh'}", f"target_rig={d / 'cmu.bvh'}"])
    out = read_bvh(d / "out.bvh")
    assert out.names == read_bvh(d / "cmu.bvh").names and out.num_frames == c.num_frames
    learned = LearnedRetarget.from_checkpoint(ckpt)
    lq, lp, _ = learned(c.root_pos, c.local_q)
    back = learned.rig.positions(out.local_rotations(), out.local_positions())
    assert np.abs(back - learned.rig.positions(lq, lp)).max() < 0.05  # the file holds the network's motion
    main([f"ckpt_path={ckpt}", f"input={d / 'src.bvh'}", f"output={d / 'analytic.bvh'}", "method=analytic"])
    a_q, a_p = learned.rig.analytic(c.root_pos, c.local_q)
    got = read_bvh(d / "analytic.bvh")
    assert np.abs(learned.rig.positions(got.local_rotations(), got.local_positions())
                  - learned.rig.positions(a_q, a_p)).max() < 0.05


def test_a_rig_it_was_not_trained_for(files, capsys):
    d, ckpt, _ = files
    _fails(capsys, [f"ckpt_path={ckpt}", f"input={d / 'src.bvh'}", f"output={d / 'o.bvh'}",
                    f"target_rig={d / 'other.bvh'}"], "is not the target rig")


def test_a_malformed_bvh(files, capsys):
    d, ckpt, _ = files
    (d / "bad.bvh").write_text((d / "src.bvh").read_text()[:400])
    _fails(capsys, [f"ckpt_path={ckpt}", f"input={d / 'bad.bvh'}", f"output={d / 'o.bvh'}"], "bad.bvh")


def test_output_is_the_input(files, capsys):
    d, ckpt, _ = files
    _fails(capsys, [f"ckpt_path={ckpt}", f"input={d / 'src.bvh'}", f"output={d / 'src.bvh'}"], "is the input file")


def test_another_source_skeleton_and_a_non_retarget_checkpoint(files, capsys):
    d, ckpt, _ = files
    _fails(capsys, [f"ckpt_path={ckpt}", f"input={d / 'cmu.bvh'}", f"output={d / 'o.bvh'}"], "skeleton mismatch")
    from retarget_fixtures import ROOT

    _fails(capsys, [f"ckpt_path={ROOT / 'models' / 'bn2_reference' / 'model.ckpt'}", f"input={d / 'src.bvh'}",
                    f"output={d / 'o.bvh'}"], "is not a retargeting checkpoint")
