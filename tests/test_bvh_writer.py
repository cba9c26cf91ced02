"""``inbetweening.data.bvh_writer``: standard BVH text, exact round trips through the reader, file objects, and
depth-first column order."""
import numpy as np
import pytest

from inbetweening.data.bvh import BVH, parse_bvh, read_bvh
from inbetweening.data.bvh_writer import format_bvh, write_bvh
from test_bvh import SMALL, bn_text, lafan_text


@pytest.mark.parametrize("precision", [6, 10])
@pytest.mark.parametrize("make", [lafan_text, bn_text])
def test_write_read_round_trip(tmp_path, make, precision):
    b = parse_bvh(make()[0], "orig.bvh")
    path = tmp_path / "out.bvh"
    write_bvh(b, path, precision=precision)
    raw = path.read_bytes()
    assert b"\r" not in raw and raw.endswith(b"\n")
    c = read_bvh(path)
    assert c.source == "out.bvh"
    assert c.names == b.names and c.parents.tolist() == b.parents.tolist() and c.channels == b.channels
    assert c.frame_time == b.frame_time
    assert sorted(c.end_sites) == sorted(b.end_sites)
    tol = 0.5 * 10.0**-precision * (1 + 1e-9)
    np.testing.assert_allclose(c.offsets, b.offsets, rtol=0, atol=tol)
    np.testing.assert_allclose(c.motion, b.motion, rtol=1e-6 if precision == 6 else 1e-10, atol=tol)
    # writing what was read reproduces the text exactly
    assert format_bvh(c, precision) == raw.decode()


def test_format_is_standard():
    b = parse_bvh(bn_text(frames=3)[0])
    text = format_bvh(b)
    lines = text.split("\n")
    assert lines[0] == "HIERARCHY" and lines[1] == "ROOT joint_Root" and lines[2] == "{"
    assert lines[3].startswith("\tOFFSET ") and lines[4].startswith("\tCHANNELS 6 Xposition")
    assert "\tJOINT Hips" in lines and "\t\t\t\t\t\tEnd Site" in lines
    i = lines.index("MOTION")
    assert lines[i + 1] == "Frames: 3" and lines[i + 2].startswith("Frame Time: ")
    assert len(lines[i + 3].split()) == 132 and lines[-1] == ""
    assert text.count("{") == text.count("}")


def test_write_to_file_objects(tmp_path):
    import io

    b = parse_bvh(SMALL)
    s = io.StringIO()
    write_bvh(b, s)
    bb = io.BytesIO()
    write_bvh(b, bb)
    assert s.getvalue().encode() == bb.getvalue() == format_bvh(b).encode()


def test_write_permutes_columns_for_non_dfs_order():
    # joints in BFS order: root, A, B (child of root), A1 (child of A) -> written DFS as root, A, A1, B
    b = BVH(
        names=["R", "A", "B", "A1"],
        parents=np.array([-1, 0, 0, 1]),
        offsets=np.zeros((4, 3)),
        channels=[("Xrotation",), ("Yrotation",), ("Zrotation",), ("Xrotation",)],
        end_sites={},
        frame_time=0.1,
        motion=np.array([[1.0, 2.0, 3.0, 4.0]]),
    )
    c = parse_bvh(format_bvh(b))
    assert c.names == ["R", "A", "A1", "B"]
    np.testing.assert_array_equal(c.motion, [[1.0, 2.0, 4.0, 3.0]])
