"""Dataset cache integrity: corrupted entries are detected and rebuilt, never served."""
from __future__ import annotations

import os
import stat

import numpy as np
import pytest

from inbetweening.data.cache import CacheCorrupt, checksum, load_entry, save_entry
from inbetweening.data.datasets import load_dataset

SYNTH = {"num_clips": 8, "min_frames": 120, "max_frames": 140}


def test_checksum_changes_with_any_byte_shape_or_dtype():
    a = np.arange(1001, dtype=np.float64)
    base = checksum(a)
    assert checksum(a.copy()) == base
    for i in (0, 500, 1000):
        b = a.copy()
        b.view(np.uint8)[i * 8 + 3] ^= 0x10
        assert checksum(b) != base
    assert checksum(a.reshape(7, 143)) != base
    assert checksum(a.astype(np.float32)) != checksum(a.astype(np.float32)[:-1])
    odd = np.arange(5, dtype=np.uint8)  # fewer bytes than one word: the tail counts
    flipped = odd.copy()
    flipped[4] = 9
    assert checksum(odd) != checksum(flipped)


def test_save_load_round_trip_and_corruption(tmp_path):
    arrays = {"x": np.random.default_rng(0).normal(size=(64, 33)), "pos_mean": np.ones(6)}
    entry = tmp_path / "entry"
    save_entry(entry, arrays, {"name": "t"})
    got, meta = load_entry(entry)
    assert meta["name"] == "t" and np.array_equal(got["x"], arrays["x"])
    # readable by other users, no temporary folder left behind
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(os.stat(entry).st_mode) == 0o777 & ~umask
    assert stat.S_IMODE(os.stat(entry / "x.npy").st_mode) == 0o666 & ~umask
    assert [p.name for p in tmp_path.iterdir()] == ["entry"]
    # same-size overwrite in the middle of an array file
    f = entry / "x.npy"
    size = f.stat().st_size
    with open(f, "r+b") as fh:
        fh.seek(size // 2)
        fh.write(os.urandom(64))
    assert f.stat().st_size == size
    with pytest.raises(CacheCorrupt, match="x.npy: contents do not match"):
        load_entry(entry)


def test_corrupted_test_windows_are_rebuilt_not_served(tmp_path):
    cache = tmp_path / "cache"
    fresh = load_dataset("synthetic", cache_dir=cache, synthetic=SYNTH)
    want_X = np.array(fresh.test_X)
    (entry,) = (cache / "prepared").iterdir()
    f = entry / "test_X.npy"
    size = f.stat().st_size
    with open(f, "r+b") as fh:  # 4 KiB of random bytes, same file size
        fh.seek(size // 3)
        fh.write(os.urandom(4096))
    with pytest.warns(UserWarning, match="corrupt.*rebuilding"):
        again = load_dataset("synthetic", cache_dir=cache, synthetic=SYNTH)
    np.testing.assert_array_equal(again.test_X, want_X)
    third = load_dataset("synthetic", cache_dir=cache, synthetic=SYNTH)  # the rebuilt entry is valid
    np.testing.assert_array_equal(third.test_X, want_X)


def test_garbled_hash_memo_is_ignored(tmp_path):
    cache = tmp_path / "cache"
    load_dataset("synthetic", cache_dir=cache, synthetic=SYNTH)
    memos = list((cache / "hashes").glob("*.txt"))
    assert memos
    for m in memos:
        m.write_text("half")  # e.g. a torn write by an older version
    data = load_dataset("synthetic", cache_dir=cache, synthetic=SYNTH)
    assert data.test_X.shape[0] > 0
    assert len(list((cache / "prepared").iterdir())) == 1  # same key: the memo was recomputed, not trusted
