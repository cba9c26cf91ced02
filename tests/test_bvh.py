"""BVH reader: LAFAN1 and Bandai-Namco layouts built in the tests, archives, malformed files (writing:
tests/test_bvh_writer.py)."""

import itertools
import re
import zipfile
from pathlib import Path

import numpy as np
import pytest

from inbetweening.data import bvh_motion as bvh_module
from inbetweening.data.bvh import (
    BVH,
    BVHError,
    iter_bvh_sources,
    parse_bvh,
    read_bvh,
    read_bvh_many,
)
from inbetweening.data.bvh_writer import format_bvh
from inbetweening.geometry.quaternion import euler_to_quat_np
from inbetweening.geometry.skeleton import Skeleton

BN_ZIP = Path(__file__).resolve().parents[1].parent / "shared" / "datasets" / "bandai-namco-2.zip"

LAFAN_NAMES = [
    "Hips", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToe", "RightUpLeg", "RightLeg", "RightFoot", "RightToe",
    "Spine", "Spine1", "Spine2", "Neck", "Head", "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand",
    "RightShoulder", "RightArm", "RightForeArm", "RightHand",
]  # fmt: skip
LAFAN_PARENTS = [-1, 0, 1, 2, 3, 0, 5, 6, 7, 0, 9, 10, 11, 12, 11, 14, 15, 16, 11, 18, 19, 20]
BN_NAMES = [
    "joint_Root", "Hips", "Spine", "Chest", "Neck", "Head", "Shoulder_L", "UpperArm_L", "LowerArm_L", "Hand_L",
    "Shoulder_R", "UpperArm_R", "LowerArm_R", "Hand_R", "UpperLeg_L", "LowerLeg_L", "Foot_L", "Toes_L",
    "UpperLeg_R", "LowerLeg_R", "Foot_R", "Toes_R",
]  # fmt: skip
BN_PARENTS = [-1, 0, 1, 2, 3, 4, 3, 6, 7, 8, 3, 10, 11, 12, 1, 14, 15, 16, 1, 18, 19, 20]
POS = ("Xposition", "Yposition", "Zposition")
LAFAN_ROT = ("Zrotation", "Yrotation", "Xrotation")
BN_ROT = ("Zrotation", "Xrotation", "Yrotation")


# --------------------------------------------------------------------------------------------
# Text builders
# --------------------------------------------------------------------------------------------
def hierarchy_text(names, parents, offsets, channels, indent="\t", comments=False) -> str:
    """Hierarchy lines (DFS order = index order), End Site under every leaf."""
    children = {j: [c for c, p in enumerate(parents) if p == j] for j in range(len(names))}
    lines = ["HIERARCHY"]
    if comments:
        lines.append("# exported by a test   ")

    def joint(j, depth):
        tab = indent * depth
        head = f"{tab}{'ROOT' if depth == 0 else 'JOINT'} {names[j]}"
        lines.append(head + ("   # a comment after the name" if comments and j % 3 == 1 else ""))
        lines.append(tab + "{")
        lines.append(f"{tab}{indent}OFFSET " + " ".join(f"{v:.6f}" for v in offsets[j]))
        lines.append(f"{tab}{indent}CHANNELS {len(channels[j])} " + " ".join(channels[j]) + " ")
        for c in children[j]:
            joint(c, depth + 1)
        if not children[j]:
            end = [
                f"{tab}{indent}End Site",
                f"{tab}{indent}{{",
                f"{tab}{indent * 2}OFFSET 0.0 1.5 0.0",
                f"{tab}{indent}}}",
            ]
            lines.extend(end)
        lines.append(tab + "}")

    joint(0, 0)
    return "\n".join(lines)


def motion_lines(values: np.ndarray, fmt: str = "%.6f") -> list[str]:
    return [" ".join(fmt % v for v in row) for row in values]


def naive_values(lines: list[str]) -> np.ndarray:
    """Reference conversion: Python float() per token."""
    return np.array([[float(t) for t in line.split()] for line in lines if line.strip()])


def lafan_text(frames=12, seed=0):
    """LAFAN1-like file (space indent, root 6 channels ZYX, others 3 ZYX). Returns (text, offsets, values)."""
    rng = np.random.default_rng(seed)
    offsets = np.round(rng.normal(0, 10, (22, 3)), 6)
    channels = [POS + LAFAN_ROT] + [LAFAN_ROT] * 21
    raw = rng.uniform(-179, 179, (frames, 3 + 66))
    raw[:, :3] = rng.normal(0, 100, (frames, 3))
    lines = motion_lines(raw, "%.9g")
    head = hierarchy_text(LAFAN_NAMES, LAFAN_PARENTS, offsets, channels, indent="  ")
    text = head + f"\nMOTION\nFrames: {frames}\nFrame Time: 0.033333\n" + "\n".join(lines) + "\n"
    return text, offsets, naive_values(lines)


def bn_text(frames=10, seed=1, crlf=True):
    """Bandai-Namco-like file: joint_Root + Hips..., 6 channels ZXY everywhere, tabs, comments, CRLF."""
    rng = np.random.default_rng(seed)
    offsets = np.round(rng.normal(0, 10, (22, 3)), 6)
    offsets[0] = 0.0
    channels = [POS + BN_ROT] * 22
    raw = np.zeros((frames, 22, 6))
    raw[:, :, :3] = offsets  # non-root position channels repeat the offsets
    raw[:, 0] = 0.0  # static joint_Root
    raw[:, 1, :3] = rng.normal(0, 100, (frames, 3))
    raw[:, 1:, 3:] = rng.uniform(-179, 179, (frames, 21, 3))
    lines = motion_lines(raw.reshape(frames, -1))
    head = hierarchy_text(BN_NAMES, BN_PARENTS, offsets, channels, indent="\t", comments=True)
    body = head + f"\n\nMOTION\nFrames:\t{frames}\nFrame Time:\t3.33333e-02\n" + "\n".join(lines) + "\n"
    if crlf:
        body = body.replace("\n", "\r\n")
    return body, offsets, naive_values(lines)


SMALL = """HIERARCHY
ROOT Hips
{
\tOFFSET 0 0 0
\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
\tJOINT Spine
\t{
\t\tOFFSET 0 10 0
\t\tCHANNELS 3 Zrotation Xrotation Yrotation
\t\tEnd Site
\t\t{
\t\t\tOFFSET 0 5 0
\t\t}
\t}
}
MOTION
Frames: 3
Frame Time: 0.0333333
1 2 3 10 20 30 1 2 3
4 5 6 40 50 60 4 5 6
7 8 9 70 80 90 7 8 9
"""  # line numbers: HIERARCHY=1, Spine CHANNELS=9, MOTION=16, Frames=17, Frame Time=18, frames=19..21


def edit_line(text: str, lineno: int, new: str | None) -> str:
    lines = text.split("\n")
    if new is None:
        del lines[lineno - 1]
    else:
        lines[lineno - 1] = new
    return "\n".join(lines)


def assert_bvh_error(text, line, pattern, source="walk1.bvh"):
    with pytest.raises(BVHError) as info:
        parse_bvh(text, source=source)
    msg = str(info.value)
    assert msg.startswith(f"{source}:{line}: "), msg
    assert re.search(pattern, msg), msg
    assert info.value.line == line and info.value.source == source


def same_rotations(a, b, atol=1e-9):
    dots = np.abs(np.sum(a * b, axis=-1))
    np.testing.assert_allclose(dots, 1.0, atol=atol)


# --------------------------------------------------------------------------------------------
# Parsing
# --------------------------------------------------------------------------------------------
def test_parse_lafan_layout():
    text, offsets, values = lafan_text()
    b = parse_bvh(text, source="lafan.bvh")
    assert b.names == LAFAN_NAMES and b.parents.tolist() == LAFAN_PARENTS
    assert b.parents.dtype == np.int64 and b.offsets.dtype == np.float64
    np.testing.assert_array_equal(b.offsets, offsets)
    assert b.channels[0] == POS + LAFAN_ROT and all(ch == LAFAN_ROT for ch in b.channels[1:])
    assert b.rotation_order(0) == "zyx" and b.rotation_order(5) == "zyx"
    assert b.num_frames == 12 and b.num_joints == 22 and b.frame_time == 0.033333
    assert b.motion.shape == (12, 69)
    np.testing.assert_array_equal(b.motion, values)  # bit-identical to float()
    assert sorted(b.end_sites) == [4, 8, 13, 17, 21]
    np.testing.assert_array_equal(b.end_sites[13], [0.0, 1.5, 0.0])
    assert b.source == "lafan.bvh"


def test_parse_bandai_namco_layout_crlf_comments_tabs():
    text, offsets, values = bn_text()
    assert "\r\n" in text and "#" in text and "\t" in text
    b = parse_bvh(text.encode(), source="bn.bvh")
    assert b.names == BN_NAMES and b.parents.tolist() == BN_PARENTS
    np.testing.assert_array_equal(b.offsets, offsets)
    assert all(ch == POS + BN_ROT for ch in b.channels)
    assert {b.rotation_order(j) for j in range(22)} == {"zxy"}
    assert b.frame_time == pytest.approx(1 / 30, rel=1e-5)
    np.testing.assert_array_equal(b.motion, values)
    assert np.signbit(b.motion).tolist() == np.signbit(values).tolist()  # -0.000000 stays -0.0


def test_local_rotations_match_euler_to_quat():
    for text, order in [(lafan_text()[0], "zyx"), (bn_text()[0], "zxy")]:
        b = parse_bvh(text)
        q = b.local_rotations()
        assert q.shape == (b.num_frames, 22, 4) and q.dtype == np.float64
        start = 0
        for j, ch in enumerate(b.channels):
            cols = [start + i for i, c in enumerate(ch) if c.endswith("rotation")]
            start += len(ch)
            same_rotations(q[:, j], euler_to_quat_np(b.motion[:, cols], order))
        assert (np.sum(q[1:] * q[:-1], axis=-1) >= 0).all()  # sign-continuous along time
        np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0)


def test_positions_helpers():
    b = parse_bvh(bn_text()[0])
    cp = b.channel_positions()
    assert cp.shape == (b.num_frames, 22, 3)
    np.testing.assert_array_equal(cp, b.motion.reshape(b.num_frames, 22, 6)[:, :, :3])
    lp = b.local_positions()
    np.testing.assert_array_equal(lp[:, 0], b.motion[:, :3])
    np.testing.assert_array_equal(lp[:, 1:], np.broadcast_to(b.offsets[1:], lp[:, 1:].shape))
    la = parse_bvh(lafan_text()[0])
    lp = la.local_positions()
    np.testing.assert_array_equal(lp[:, 0], la.motion[:, :3])
    np.testing.assert_array_equal(la.channel_positions(), lp)  # only the root has position channels


def test_parsed_arrays_are_independent_copies():
    text = bn_text(frames=2)[0]
    a, b = parse_bvh(text), parse_bvh(text)  # the second one comes from the header cache
    a.offsets[1] += 100.0
    a.end_sites[5][0] = 7.0
    a.names[0] = "changed"
    c = parse_bvh(text)
    np.testing.assert_array_equal(b.offsets, c.offsets)
    assert c.names[0] == "joint_Root" and c.end_sites[5][0] == 0.0
    assert c.offsets.flags.writeable and c.motion.flags.writeable


def test_skeleton():
    b = parse_bvh(lafan_text()[0])
    sk = b.skeleton()
    assert isinstance(sk, Skeleton)
    assert sk.names == tuple(LAFAN_NAMES) and sk.parents == tuple(LAFAN_PARENTS)
    np.testing.assert_array_equal(sk.offsets, b.offsets)


def test_number_formats_are_exact(monkeypatch):
    fast_results = []
    fast = bvh_module._fast_decimals
    monkeypatch.setattr(
        bvh_module, "_fast_decimals", lambda *args: fast_results.append(fast(*args)) or fast_results[-1]
    )
    plain = ["1", "-2", "+3.5", ".25", "-.5", "5.", "-0.000000", "0.000001", "123456.123456789", "12345678.1234567",
             "-99999999.9999999", "0.12345678901234"]  # fmt: skip
    other = ["1e-3", "-2.5E+2", "8", "3.14159265358979323846", "123456789.5", "-0"]
    head = "HIERARCHY\nROOT A\n{\nOFFSET 0 0 0\nCHANNELS 3 Xrotation Yrotation Zrotation\n}\nMOTION\n"

    def parse_tokens(tokens):  # 3 channels per frame line: the tokens regrouped 3 by 3
        rows = [" ".join(tokens[i : i + 3]) for i in range(0, len(tokens), 3)]
        b = parse_bvh(head + f"Frames: {len(rows)}\nFrame Time: 1\n" + "\n".join(rows))
        expected = np.array([float(t) for t in tokens])
        assert b.motion.ravel().tolist() == expected.tolist()
        assert np.signbit(b.motion.ravel()).tolist() == np.signbit(expected).tolist()

    parse_tokens(plain)
    assert fast_results[-1] is not None
    fast_results.clear()
    parse_tokens(other)  # exponents: numpy's general path
    assert not fast_results
    parse_tokens(other[3:])  # no exponent but more than 15 digits: the fast path declines
    assert fast_results[-1] is None
    # the plain-decimal fast path must agree bit for bit with float() on random data (mixed decimals)
    rng = np.random.default_rng(5)
    vals = rng.normal(0, 1, 3000) * 10.0 ** rng.integers(-6, 7, 3000)
    strs = [f"{v:.{d}f}" for v, d in zip(vals, rng.integers(0, 8, 3000), strict=True)]
    rows = [" ".join(strs[i : i + 3]) for i in range(0, 3000, 3)]
    b = parse_bvh(head + f"Frames: {len(rows)}\nFrame Time: 1\n" + "\n".join(rows))
    assert fast_results[-1] is not None
    assert b.motion.ravel().tolist() == [float(s) for s in strs]
    assert np.signbit(b.motion.ravel()).tolist() == [s.startswith("-") for s in strs]
    # uniform decimals (the Bandai-Namco "%.6f" case) take the fast path too
    b = parse_bvh(bn_text()[0])
    assert fast_results[-1] is not None


def test_generic_channel_subsets_and_orders():
    text = """HIERARCHY
ROOT R
{
  OFFSET 1 2 3
  CHANNELS 3 Zposition Xposition Yposition
  JOINT A
  {
    OFFSET 0 1 0
    CHANNELS 2 Yrotation Xrotation
    JOINT B
    {
      OFFSET 0 1 0
      JOINT C
      {
        OFFSET 0 1 0
        CHANNELS 4 Xrotation Yposition Yrotation Zrotation
        End Site
        {
          OFFSET 0 1 0
        }
      }
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.5
30 10 20 45 10 10 5 20 30
31 11 21 40 15 11 6 21 31
"""
    b = parse_bvh(text, "subset.bvh")
    assert [b.rotation_order(j) for j in range(4)] == ["", "yx", "", "xyz"]
    assert b.channels[2] == ()
    cp = b.channel_positions()
    np.testing.assert_array_equal(cp[:, 0], [[10, 20, 30], [11, 21, 31]])
    np.testing.assert_array_equal(cp[:, 3, 1], [5, 6])
    np.testing.assert_array_equal(cp[:, 3, [0, 2]], [[0, 0], [0, 0]])
    q = b.local_rotations()
    np.testing.assert_array_equal(q[:, 0], [[1, 0, 0, 0]] * 2)
    np.testing.assert_array_equal(q[:, 2], [[1, 0, 0, 0]] * 2)
    same_rotations(q[:, 1], euler_to_quat_np(b.motion[:, 3:5], "yx"))
    same_rotations(q[:, 3], euler_to_quat_np(b.motion[:, [5, 7, 8]], "xyz"))
    b2 = b.with_motion(q, cp)
    np.testing.assert_allclose(b2.motion, b.motion, atol=1e-9)
    np.testing.assert_array_equal(b2.channel_positions(), cp)
    text2 = format_bvh(b)
    assert "\t\tCHANNELS 0\n" in text2
    b3 = parse_bvh(text2)
    assert b3.channels == b.channels and sorted(b3.end_sites) == [3]
    np.testing.assert_array_equal(b3.motion, b.motion)


def test_cr_only_bom_and_blank_lines():
    text = "\ufeff" + SMALL.replace("MOTION\n", "\n\nMOTION\n\n").replace("4 5 6 40", "\n4 5 6 40") + "\n\n   \n"
    b = parse_bvh(text.encode("utf-8"))
    np.testing.assert_array_equal(b.motion[:, 0], [1, 4, 7])
    b = parse_bvh(SMALL.replace("\n", "\r").encode())
    np.testing.assert_array_equal(b.motion[:, 0], [1, 4, 7])
    b = parse_bvh(SMALL.rstrip("\n").replace(" ", " \t "))  # no final newline, tabs between values
    np.testing.assert_array_equal(b.motion[:, 0], [1, 4, 7])


def test_frames_zero_and_brace_on_name_line():
    text = SMALL.replace("ROOT Hips\n{", "ROOT Hips {").split("MOTION")[0] + "MOTION\nFrames: 0\nFrame Time: 1e-2\n"
    b = parse_bvh(text)
    assert b.motion.shape == (0, 9) and b.num_frames == 0 and b.frame_time == 0.01
    assert b.local_rotations().shape == (0, 2, 4)


def test_bvh_rejects_bad_construction():
    with pytest.raises(BVHError, match="motion has shape"):
        BVH(["R"], [-1], np.zeros((1, 3)), [("Xrotation",)], {}, 0.1, np.zeros((2, 2)))
    with pytest.raises(BVHError, match="unknown channel"):
        BVH(["R"], [-1], np.zeros((1, 3)), [("Wrotation",)], {}, 0.1, np.zeros((2, 1)))
    b = parse_bvh(SMALL)
    b.motion[0, 0] = np.nan
    with pytest.raises(BVHError, match="non-finite"):
        format_bvh(b)


@pytest.mark.parametrize("make", [lafan_text, bn_text])
def test_with_motion_round_trip(make):
    b = parse_bvh(make(frames=20)[0])
    q, p = b.local_rotations(), b.channel_positions()
    c = b.with_motion(q, p)
    assert c.names == b.names and c.channels == b.channels and c.frame_time == b.frame_time
    assert c.motion.shape == b.motion.shape
    same_rotations(c.local_rotations(), q)
    np.testing.assert_array_equal(c.channel_positions(), p)
    d = b.with_motion(q[:5], p[:5], frame_time=0.5)
    assert d.num_frames == 5 and d.frame_time == 0.5
    # through text as well
    e = parse_bvh(format_bvh(c, precision=9))
    same_rotations(e.local_rotations(), q, atol=1e-12)
    with pytest.raises(ValueError):
        b.with_motion(q[:, :5], p)
    with pytest.raises(ValueError):
        b.with_motion(q, p[:3])


# --------------------------------------------------------------------------------------------
# Folders and zip files
# --------------------------------------------------------------------------------------------
def test_zip_and_folder_reading(tmp_path):
    texts = {"b_walk.bvh": lafan_text(4, seed=2)[0], "a_run.bvh": bn_text(3)[0], "c_jump.bvh": SMALL}
    zpath = tmp_path / "set.zip"
    with zipfile.ZipFile(zpath, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name, text in texts.items():
            zf.writestr(f"data/sub/{name}", text)
        zf.writestr("data/readme.txt", "not a bvh")
        zf.writestr("__MACOSX/data/._a_run.bvh", b"\x00\x05junk")
    folder = tmp_path / "folder"
    (folder / "deep" / "er").mkdir(parents=True)
    for i, (name, text) in enumerate(texts.items()):
        target = folder / ("deep/er" if i else "") / name
        target.write_bytes(text.encode())
    (folder / "notes.txt").write_text("x")
    for src in (zpath, folder, str(folder)):
        got = list(iter_bvh_sources(src))
        assert [n for n, _ in got] == ["a_run.bvh", "b_walk.bvh", "c_jump.bvh"]
        assert all(isinstance(d, bytes) for _, d in got)
        many = read_bvh_many(src)
        assert [b.source for b in many] == ["a_run.bvh", "b_walk.bvh", "c_jump.bvh"]
        assert [b.num_frames for b in many] == [3, 4, 3]
        assert [b.num_joints for b in many] == [22, 22, 2]
    assert [n for n, _ in iter_bvh_sources(zpath, "*.txt")] == ["readme.txt"]
    assert [n for n, _ in iter_bvh_sources(folder / "b_walk.bvh")] == ["b_walk.bvh"]


def test_source_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="nowhere"):
        list(iter_bvh_sources(tmp_path / "nowhere"))
    (tmp_path / "empty").mkdir()
    with pytest.raises(BVHError, match=r"empty.*no files matching '\*\.bvh'"):
        list(iter_bvh_sources(tmp_path / "empty"))
    zpath = tmp_path / "none.zip"
    with zipfile.ZipFile(zpath, "w") as zf:
        zf.writestr("a.txt", "x")
    with pytest.raises(BVHError, match=r"none\.zip.*no members"):
        read_bvh_many(zpath)
    (tmp_path / "notes.txt").write_text("x")
    with pytest.raises(BVHError, match=r"notes\.txt: not a folder, a zip file"):
        list(iter_bvh_sources(tmp_path / "notes.txt"))
    bad = tmp_path / "bad.zip"
    with zipfile.ZipFile(bad, "w") as zf:
        zf.writestr("x/broken.bvh", SMALL.replace("7 8 9 70 80 90 7 8 9", "7 8 9 70 80 90 7 8"))
    with pytest.raises(BVHError, match=r"^broken\.bvh:21: expected 9 values, got 8"):
        read_bvh_many(bad)


# --------------------------------------------------------------------------------------------
# Malformed files: one BVHError naming the file and the line
# --------------------------------------------------------------------------------------------
MALFORMED = [
    ("empty", "", 1, "empty file"),
    ("blank", "  \n\n", 1, "empty file"),
    ("no HIERARCHY", edit_line(SMALL, 1, None), 1, "expected HIERARCHY"),
    ("no ROOT", "HIERARCHY\nMOTION\nFrames: 0\nFrame Time: 0.1\n", 2, "missing ROOT"),
    ("JOINT before ROOT", edit_line(SMALL, 2, "JOINT Hips"), 2, "expected ROOT"),
    ("unclosed joint", edit_line(SMALL, 14, None), 15, r"unbalanced braces: 'Hips' \(declared at line 2\)"),
    ("extra close", edit_line(SMALL, 15, "}\n}"), 16, "unbalanced braces: '}' without"),
    ("stray open", edit_line(SMALL, 8, "\t\t{"), 8, "unbalanced braces: '{' without"),
    ("no brace after JOINT", edit_line(SMALL, 7, None), 7, "expected '{' after JOINT Spine"),
    ("no MOTION", "\n".join(SMALL.split("\n")[:15]) + "\n", 15, "missing MOTION"),
    ("junk instead of MOTION", edit_line(SMALL, 16, "MOTON"), 16, "after the hierarchy"),
    ("no Frames", edit_line(SMALL, 17, None), 17, "expected 'Frames: <value>'"),
    ("bad Frames", edit_line(SMALL, 17, "Frames: three"), 17, "invalid frame count 'three'"),
    ("negative Frames", edit_line(SMALL, 17, "Frames: -3"), 17, "invalid frame count"),
    ("no Frame Time", edit_line(SMALL, 18, None), 18, "expected 'Frame Time: <value>'"),
    ("bad Frame Time", edit_line(SMALL, 18, "Frame Time: fast"), 18, "invalid frame time 'fast'"),
    ("zero Frame Time", edit_line(SMALL, 18, "Frame Time: 0"), 18, "invalid frame time"),
    ("nan Frame Time", edit_line(SMALL, 18, "Frame Time: nan"), 18, "invalid frame time"),
    ("no frame lines", SMALL.split("Frame Time")[0] + "Frame Time: 0.1", 19, "found 0 frame lines"),
    ("truncated", edit_line(SMALL, 17, "Frames: 5"), 22, "found 3 frame lines, 'Frames:' declares 5"),
    ("too many lines", edit_line(SMALL, 17, "Frames: 2"), 21, "more frame lines than 'Frames: 2'"),
    ("short line", edit_line(SMALL, 20, "4 5 6 40 50 60 4 5"), 20, "expected 9 values, got 8"),
    ("long line", edit_line(SMALL, 19, "1 2 3 10 20 30 1 2 3 4"), 19, "expected 9 values, got 10"),
    ("non-numeric", edit_line(SMALL, 20, "4 5 6 40 abc 60 4 5 6"), 20, "non-numeric value 'abc'"),
    ("two points", edit_line(SMALL, 21, "7 8 9 70 80 90 7 8.1.2 9"), 21, "non-numeric value '8.1.2'"),
    ("inner sign", edit_line(SMALL, 21, "7 8 9 70 80 90 7 8-1 9"), 21, "non-numeric value '8-1'"),
    ("comma", edit_line(SMALL, 19, "1 2 3 10 20 30 1 2 3,5"), 19, "non-numeric value '3,5'"),
    ("bad exponent", edit_line(SMALL, 19, "1 2 3 10 20 30 1 2 1e"), 19, "non-numeric value '1e'"),
    ("control char", edit_line(SMALL, 20, "4 5 6 40 50 60 4 5 \x006"), 20, "non-numeric value"),
    ("nan", edit_line(SMALL, 21, "7 8 9 70 nan 90 7 8 9"), 21, "non-finite value 'nan'"),
    ("inf", edit_line(SMALL, 20, "4 5 6 40 50 -inf 4 5 6"), 20, "non-finite value '-inf'"),
    ("overflow", edit_line(SMALL, 19, "1 2 3 10 20 30 1 2 1e999"), 19, "non-finite value '1e999'"),
    ("CHANNELS count", edit_line(SMALL, 9, "\t\tCHANNELS 2 Zrotation Xrotation Yrotation"), 9, "declares 2 .* names 3"),
    ("CHANNELS no count", edit_line(SMALL, 9, "\t\tCHANNELS Zrotation"), 9, "CHANNELS needs a count"),
    ("unknown channel", edit_line(SMALL, 9, "\t\tCHANNELS 3 Zrotation Xrotation W"), 9, "unknown channel name 'W'"),
    ("repeated channel", edit_line(SMALL, 9, "\t\tCHANNELS 3 Zrotation Xrotation Xrotation"), 9, "repeated channel"),
    ("short OFFSET", edit_line(SMALL, 8, "\t\tOFFSET 0 10"), 8, "OFFSET needs 3 values"),
    ("bad OFFSET", edit_line(SMALL, 8, "\t\tOFFSET 0 ten 0"), 8, "non-numeric OFFSET"),
    ("missing OFFSET", edit_line(SMALL, 8, None), 13, "has no OFFSET"),
    ("unknown keyword", edit_line(SMALL, 8, "\t\tOFSET 0 10 0"), 8, "unexpected 'OFSET 0 10 0'"),
    ("second ROOT", edit_line(SMALL, 6, "\tROOT Spine"), 6, "second ROOT"),
]  # fmt: skip


@pytest.mark.parametrize("name,text,line,pattern", MALFORMED, ids=[m[0] for m in MALFORMED])
def test_malformed(name, text, line, pattern):
    assert_bvh_error(text, line, pattern)


def test_malformed_with_crlf_and_comments_line_numbers():
    text = SMALL.replace("ROOT Hips", "ROOT Hips # the root\n# a whole-line comment").replace("\n", "\r\n")
    b = parse_bvh(text)
    assert b.names == ["Hips", "Spine"]
    assert_bvh_error(text.replace("4 5 6 40 50 60 4 5 6", "4 5 6 40 50 60 4 5"), 21, "expected 9 values, got 8")


def test_error_deep_in_a_large_bn_file():
    text, _, _ = bn_text(frames=300, crlf=True)
    lines = text.split("\r\n")
    first = lines.index("Frame Time:\t3.33333e-02") + 2  # 1-based line number of frame 0
    for frame, (repl, pattern) in zip(
        [0, 157, 299],
        [("x1.0", "non-numeric value 'x1.0'"), ("nan", "non-finite"), (None, "expected 132 values, got 131")],
        strict=True,
    ):
        broken = list(lines)
        tokens = broken[first - 1 + frame].split()
        broken[first - 1 + frame] = " ".join(tokens[:-1] + ([repl] if repl else []))
        assert_bvh_error("\r\n".join(broken), first + frame, pattern, source="big.bvh")
    # extra blank lines after the last frame are fine, an extra frame is not
    assert parse_bvh(text + "\r\n\r\n  \r\n").num_frames == 300
    assert_bvh_error(text + lines[first - 1] + "\r\n", first + 300, "more frame lines", source="big.bvh")


def test_read_bvh_names_the_file(tmp_path):
    path = tmp_path / "walk1.bvh"
    path.write_text(edit_line(SMALL, 21, "7 8 9 70 80 90 7 8"))
    with pytest.raises(BVHError, match=r"^walk1\.bvh:21: expected 9 values, got 8$"):
        read_bvh(path)


# --------------------------------------------------------------------------------------------
# Real data (optional)
# --------------------------------------------------------------------------------------------
@pytest.mark.skipif(not BN_ZIP.exists(), reason=f"Bandai-Namco dataset not found at {BN_ZIP}")
def test_bandai_namco_zip_first_files():
    for name, data in itertools.islice(iter_bvh_sources(BN_ZIP), 20):
        b = parse_bvh(data, name)
        assert b.num_joints == 22 and b.names[0] == "joint_Root" and b.names[1] == "Hips", name
        assert all(len(ch) == 6 for ch in b.channels)
        assert {b.rotation_order(j) for j in range(22)} == {"zxy"}
        assert b.num_frames > 0 and b.motion.shape == (b.num_frames, 132)
        assert b.frame_time == pytest.approx(1 / 30, rel=1e-4)
