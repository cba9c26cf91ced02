"""Atomic writes: the target is replaced only when the write completed; nothing is left behind otherwise."""
import os
import stat

import pytest

from inbetweening.atomic import atomic_path, same_file, write_text


def test_write_replaces_and_leaves_no_temp(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("old")
    write_text(target, "new")
    assert target.read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.txt"]
    mode = stat.S_IMODE(os.stat(target).st_mode)
    assert mode & 0o044 == 0o044 & ~_umask()  # readable by others like a plain open() would make it


def _umask():
    m = os.umask(0)
    os.umask(m)
    return m


def test_interrupted_write_keeps_the_old_file(tmp_path):
    target = tmp_path / "out.bin"
    target.write_bytes(b"precious")
    with pytest.raises(KeyboardInterrupt), atomic_path(target) as tmp:
        assert tmp.parent == tmp_path  # same directory: os.replace is atomic
        tmp.write_bytes(b"half")
        raise KeyboardInterrupt
    assert target.read_bytes() == b"precious"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bin"]


def test_creates_parent_folders(tmp_path):
    write_text(tmp_path / "a" / "b" / "c.txt", "x")
    assert (tmp_path / "a" / "b" / "c.txt").read_text() == "x"


def test_same_file(tmp_path):
    a = tmp_path / "a.bvh"
    a.write_text("x")
    (tmp_path / "link.bvh").symlink_to(a)
    assert same_file(a, tmp_path / "link.bvh")
    assert same_file(a, tmp_path / "sub" / ".." / "a.bvh")
    assert not same_file(a, tmp_path / "b.bvh")
