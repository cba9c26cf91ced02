"""The fast numpy kinematics and dataset preparation are the generic definitions, bit for bit.

``geometry/kinematics_np.py`` re-orders memory (cache-sized chunks, one contiguous array per joint component) but must
perform the same floating-point operations in the same order as ``skeleton.fk``/``ik`` and
``canonical.canonicalise_windows``: these tests compare with ``np.array_equal`` (no tolerance), on chunk sizes that
split the batch unevenly, and compare the parallel BVH reader with the sequential one.
"""
from __future__ import annotations

import numpy as np
import pytest

from inbetweening.data import windows as W
from inbetweening.data.clips import Clip
from inbetweening.geometry import kinematics_np as FK
from inbetweening.geometry.skeleton import Skeleton, fk, ik

PARENTS = (-1, 0, 1, 2, 1, 4, 0, 6, 7)


def _quats(rng, shape):
    q = rng.normal(size=shape + (4,))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


@pytest.fixture(params=[7, 64, 100000], ids=["chunk7", "chunk64", "one-chunk"])
def chunk(request, monkeypatch):
    monkeypatch.setattr(FK, "CHUNK_FRAMES", request.param)
    return request.param


def test_fk_np_is_skeleton_fk_bit_for_bit(chunk):
    rng = np.random.default_rng(0)
    q = _quats(rng, (5, 13, len(PARENTS)))
    p = rng.normal(size=(5, 13, len(PARENTS), 3)) * 20
    gq, gp = fk(q, p, PARENTS)
    fq, fp = FK.fk_np(q, p, PARENTS)
    assert np.array_equal(gq, fq) and np.array_equal(gp, fp)
    assert np.array_equal(FK.fk_np(q, p, PARENTS, positions_only=True), gp)
    assert not np.array_equal(fk(q, p, (-1, 0, 0, 2, 1, 4, 0, 6, 7))[1], fp)  # the parents matter


def test_canonicalise_windows_np_is_the_generic_definition_bit_for_bit(chunk):
    rng = np.random.default_rng(1)
    X = rng.normal(size=(6, 12, len(PARENTS), 3)) * 50
    Q = _quats(rng, (6, 12, len(PARENTS)))
    want = W._canonicalise_windows_generic(X, Q, PARENTS, (0.0, 0.0, 1.0), 4)
    got = FK.canonicalise_windows_np(X, Q, PARENTS, (0.0, 0.0, 1.0), 4)
    assert np.array_equal(want[0], got[0]) and np.array_equal(want[1], got[1])
    assert W.canonicalise_windows(X, Q, PARENTS, (0.0, 0.0, 1.0), 4)[1] is not None  # numpy dispatch works
    # and the round trip is the windows' own FK turned about Y (not a no-op)
    assert not np.allclose(got[0][:, :, 0], X[:, :, 0])
    gq, _ = fk(*ik(*fk(Q, X, PARENTS), PARENTS), PARENTS)
    assert np.allclose(gq, fk(Q, X, PARENTS)[0])


def test_training_stats_and_windows_equal_the_loop_per_window_definition(chunk, monkeypatch):
    rng = np.random.default_rng(2)
    sk = Skeleton(tuple(f"j{i}" for i in range(len(PARENTS))), PARENTS, rng.normal(size=(len(PARENTS), 3)) * 10)
    clips = [Clip(f"c{i}", _quats(rng, (n, len(PARENTS))), rng.normal(size=(n, 3)) * 100)
             for i, n in enumerate([30, 8, 57, 12, 41])]  # the 8-frame clip holds no window
    # the definition: one window at a time, stacked, then the generic normalisation and FK
    xs, qs = [], []
    for c in clips:
        for s in W.window_starts(len(c.root_pos), 12, 5):
            xs.append(sk.local_positions(c.root_pos[s : s + 12]))
            qs.append(c.local_q[s : s + 12])
    X0, Q0 = np.stack(xs), np.stack(qs)
    X, Q = W.extract_windows(clips, sk, 12, 5)
    assert np.array_equal(X, X0) and np.array_equal(Q, Q0)
    Xn, Qn = W._canonicalise_windows_generic(X0, Q0, PARENTS, (0.0, 0.0, 1.0), W.N_PAST - 1)
    Xf, Qf = W.prepare_windows(clips, sk, 12, 5, (0.0, 0.0, 1.0))
    assert np.array_equal(Xn, Xf) and np.array_equal(Qn, Qf)
    gp = fk(Qn, Xn, PARENTS)[1].reshape(-1, len(PARENTS) * 3)
    mean, std = W.training_stats(clips, sk, 12, 5, (0.0, 0.0, 1.0))
    assert np.array_equal(mean, gp.mean(axis=0)) and np.array_equal(std, gp.std(axis=0))
    m2, s2 = W.position_stats(Xf, Qf, PARENTS)
    assert np.array_equal(m2, mean) and np.array_equal(s2, std)
    assert W.training_stats(clips[1:2], sk, 12, 5, (0.0, 0.0, 1.0)) is None
    # the threaded path (many small chunks, blocks of columns) gives the same bits
    monkeypatch.setattr(FK, "CHUNK_FRAMES", 24)
    mt, st = W.training_stats(clips, sk, 12, 5, (0.0, 0.0, 1.0), threads=3)
    assert np.array_equal(mt, mean) and np.array_equal(st, std)


@pytest.mark.parametrize("shape", [(1000, 66), (77, 5), (9, 2), (10, 1)])
@pytest.mark.parametrize("threads", [1, 2, 3, 8])
def test_column_mean_std_is_numpys_bit_for_bit(shape, threads):
    a = np.random.default_rng(3).normal(size=shape) * 50 + 3
    m, s = FK.column_mean_std(a, threads)
    assert np.array_equal(m, a.mean(axis=0)) and np.array_equal(s, a.std(axis=0))


def test_parallel_reader_returns_the_sequential_clips(tmp_path, monkeypatch):
    from inbetweening.data import clips as CL
    from inbetweening.data.specs import get_spec
    from inbetweening.data.synthetic import generate_dataset

    src = generate_dataset(tmp_path / "syn", num_clips=8, min_frames=66, max_frames=70)
    spec = get_spec("synthetic")
    monkeypatch.setenv("INBETWEENING_WORKERS", "1")
    seq = list(CL.read_bvh_clips(spec, src))
    monkeypatch.setenv("INBETWEENING_WORKERS", "2")
    monkeypatch.setattr(CL, "PARALLEL_MIN_FILES", 2)  # 8 files: 2 workers, 4 parts
    par = list(CL.read_bvh_clips(spec, src))
    assert [a[0] for a in seq] == [b[0] for b in par] and len(seq) == 8
    for a, b in zip(seq, par):
        assert np.array_equal(a[1].local_q, b[1].local_q) and np.array_equal(a[1].root_pos, b[1].root_pos)
        assert a[2] == b[2] and a[3] == b[3]


def test_parallel_reader_reports_a_bad_file_as_the_sequential_one_does(tmp_path, monkeypatch):
    from inbetweening.data import clips as CL
    from inbetweening.data.errors import BVHError
    from inbetweening.data.specs import get_spec
    from inbetweening.data.synthetic import generate_dataset

    src = generate_dataset(tmp_path / "syn", num_clips=6, min_frames=66, max_frames=70)
    bad = sorted(src.glob("*.bvh"))[3]
    bad.write_text(bad.read_text().replace("MOTION", "MOTON"))
    monkeypatch.setenv("INBETWEENING_WORKERS", "2")
    monkeypatch.setattr(CL, "PARALLEL_MIN_FILES", 2)
    with pytest.raises(BVHError) as e:
        list(CL.read_bvh_clips(get_spec("synthetic"), src))
    assert bad.name in str(e.value) and not str(e.value).startswith("<memory>")
