"""Finding a dataset's files (folders, zips, single files) and hashing exactly those files for the cache."""
from __future__ import annotations

import zipfile

import pytest

from inbetweening.data.cache import hash_source
from inbetweening.data.errors import BVHError
from inbetweening.data.sources import find_files, iter_bvh_sources


def make_tree(root):
    (root / "a" / "deep").mkdir(parents=True)
    (root / "b.bvh").write_bytes(b"b")
    (root / "a" / "C.BVH").write_bytes(b"c")
    (root / "a" / "deep" / "a.bvh").write_bytes(b"a")
    (root / "a" / "notes.txt").write_bytes(b"n")
    (root / "a" / "dir.bvh").mkdir()  # a folder named like a file: not a file
    return root


def test_find_files_recursive_case_insensitive_files_only(tmp_path):
    root = make_tree(tmp_path / "t")
    assert [p.relative_to(root).as_posix() for p in find_files(root)] == ["a/C.BVH", "a/deep/a.bvh", "b.bvh"]
    assert [p.name for p in find_files(root, "*.TXT")] == ["notes.txt"]
    assert find_files(root, "*.npz") == []


def test_iter_sources_sorted_by_file_name_from_folder_zip_and_file(tmp_path):
    root = make_tree(tmp_path / "t")
    got = list(iter_bvh_sources(root))
    assert got == [("C.BVH", b"c"), ("a.bvh", b"a"), ("b.bvh", b"b")]  # by name, not by folder
    z = tmp_path / "t.zip"
    with zipfile.ZipFile(z, "w") as zf:
        for name, data in got:
            zf.writestr(f"x/{name}", data)
        zf.writestr("__MACOSX/x/._a.bvh", b"junk")
        zf.writestr("x/readme.md", b"r")
    assert list(iter_bvh_sources(z)) == got
    assert list(iter_bvh_sources(root / "b.bvh")) == [("b.bvh", b"b")]
    with pytest.raises(BVHError, match="no members matching '\\*.npz' in this zip file"):
        list(iter_bvh_sources(z, "*.npz"))
    with pytest.raises(BVHError, match="not a folder, a zip file or a file matching"):
        list(iter_bvh_sources(root / "a" / "notes.txt"))
    with pytest.raises(FileNotFoundError, match="does not exist"):
        list(iter_bvh_sources(tmp_path / "missing"))


def test_hash_covers_exactly_the_matching_files(tmp_path):
    root = make_tree(tmp_path / "t")
    base = hash_source(root)
    (root / "a" / "notes.txt").write_bytes(b"changed")  # not a dataset file: same hash
    assert hash_source(root) == base
    (root / "a" / "C.BVH").write_bytes(b"C")  # upper-case extension: read by the reader, so hashed
    changed = hash_source(root)
    assert changed != base
    assert hash_source(root, pattern="*.txt") not in (base, changed)
    memo = tmp_path / "memo"
    assert hash_source(root, memo) == changed == hash_source(root, memo)  # memoised value agrees
