"""Forward/inverse kinematics and the benchmark's window normalisation for large float64 numpy batches.

The same arithmetic as :func:`inbetweening.geometry.skeleton.fk` / :func:`~inbetweening.geometry.skeleton.ik` and
:func:`inbetweening.data.windows.canonicalise_windows`, operation for operation (every product, sum and
difference in the same order), so the results are bit-identical; only the memory layout differs.  The batch is
cut into chunks of a few thousand frames that fit in the CPU cache, and inside a chunk every quaternion / vector
component of every joint is its own contiguous array (component-major), so each numpy call streams over
contiguous memory instead of the strided ``[..., c]`` views and ``np.stack`` copies of the generic functions.

Tested bit for bit against the generic functions (``tests/test_kinematics_np.py``).  Used by dataset preparation
(:func:`inbetweening.data.windows.prepare_windows`, :func:`~inbetweening.data.windows.training_stats`).
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from inbetweening.geometry.canonical import facing_rotation, masked_mean

CHUNK_FRAMES = 16384  # frames per chunk (~2.9 MB per component array for a 22-joint skeleton): measured fastest with 2 threads

__all__ = ["CHUNK_FRAMES", "canonical_positions_np", "canonicalise_windows_np", "column_mean_std", "fk_np"]


def _cross(a, b):
    ax, ay, az = a
    bx, by, bz = b
    return (ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx)


def _qmul(a, b):
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


def _qrot(q, v):
    u = q[1:]
    t = tuple(2.0 * c for c in _cross(u, v))
    c2 = _cross(u, t)
    return tuple(v[i] + q[0] * t[i] + c2[i] for i in range(3))


def _qinv(q):
    return (q[0], -q[1], -q[2], -q[3])


def _components(a: np.ndarray) -> np.ndarray:
    """``(..., J, C)`` -> contiguous ``(J, C, ...)``."""
    return np.ascontiguousarray(np.moveaxis(a, (-2, -1), (0, 1)))


def _fk_chunk(q: np.ndarray, p: np.ndarray, parents: Sequence[int]):
    """Component-major FK: ``q (J, 4, ...), p (J, 3, ...) -> lists of per-joint component tuples``."""
    gq = [tuple(q[0])]
    gp = [tuple(p[0])]
    for j in range(1, len(parents)):
        par = parents[j]
        r = _qrot(gq[par], tuple(p[j]))
        gp.append(tuple(r[i] + gp[par][i] for i in range(3)))
        gq.append(_qmul(gq[par], tuple(q[j])))
    return gq, gp


def _ik_chunk(gq, gp, parents: Sequence[int]):
    lq, lp = [gq[0]], [gp[0]]
    for j in range(1, len(parents)):
        par = parents[j]
        inv = _qinv(gq[par])
        lq.append(_qmul(inv, gq[j]))
        lp.append(_qrot(inv, tuple(gp[j][i] - gp[par][i] for i in range(3))))
    return lq, lp


def _store(out: np.ndarray, joints) -> None:
    """Write per-joint component tuples into ``out`` (``(..., J, C)`` view of the chunk): contiguous writes into a
    component-major buffer, then one transposing copy."""
    buf = np.empty((len(joints), len(joints[0])) + out.shape[:-2], dtype=out.dtype)
    for j, comps in enumerate(joints):
        for c, v in enumerate(comps):
            buf[j, c] = v
    out[...] = np.moveaxis(buf, (0, 1), (-2, -1))


def _chunks(n: int, frames_per_item: int):
    step = max(1, CHUNK_FRAMES // max(1, frames_per_item))
    return [(s, min(s + step, n)) for s in range(0, n, step)]


def fk_np(local_q: np.ndarray, local_p: np.ndarray, parents: Sequence[int], positions_only: bool = False):
    """:func:`inbetweening.geometry.skeleton.fk` of numpy arrays, bit-identical.  ``(..., J, 4), (..., J, 3)`` ->
    global ``(..., J, 4), (..., J, 3)`` float64 (``positions_only``: only the positions)."""
    local_q = np.asarray(local_q)
    local_p = np.asarray(local_p)
    shape = np.broadcast_shapes(local_q.shape[:-1], local_p.shape[:-1])
    lq = np.broadcast_to(local_q, shape + (4,)).reshape(-1, shape[-1], 4)
    lp = np.broadcast_to(local_p, shape + (3,)).reshape(-1, shape[-1], 3)
    dtype = np.result_type(local_q, local_p)
    gq_out = None if positions_only else np.empty(lq.shape, dtype=dtype)
    gp_out = np.empty(lp.shape, dtype=dtype)
    for s, e in _chunks(len(lq), 1):
        gq, gp = _fk_chunk(_components(lq[s:e]), _components(lp[s:e]), parents)
        _store(gp_out[s:e], gp)
        if gq_out is not None:
            _store(gq_out[s:e], gq)
    gp_out = gp_out.reshape(shape + (3,))
    return gp_out if positions_only else (gq_out.reshape(shape + (4,)), gp_out)


def _canonical_chunk(x: np.ndarray, q: np.ndarray, xz: np.ndarray, parents: Sequence[int],
                     forward_axis: Sequence[float], frame: int):
    """One chunk of :func:`canonicalise_windows_np`: ``x (b, T, J, 3)`` (modified: root XZ centred on ``xz``),
    ``q (b, T, J, 4)`` -> local ``(rotations, positions)`` as per-joint component tuples of ``(b, T)`` arrays."""
    x[:, :, 0, 0] = x[:, :, 0, 0] - xz[..., 0]
    x[:, :, 0, 2] = x[:, :, 0, 2] - xz[..., 1]
    gq, gp = _fk_chunk(_components(q), _components(x), parents)  # components (b, T)
    root = np.stack([c[:, frame : frame + 1] for c in gq[0]], axis=-1)[:, :, None, :]  # (b, 1, 1, 4)
    inv = _qinv(tuple(np.ascontiguousarray(facing_rotation(root, forward_axis)[:, :, 0, c]) for c in range(4)))
    return _ik_chunk([_qmul(inv, g) for g in gq], [_qrot(inv, g) for g in gp], parents)


def canonicalise_windows_np(X: np.ndarray, Q: np.ndarray, parents: Sequence[int], forward_axis: Sequence[float],
                            frame: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`inbetweening.data.windows.canonicalise_windows` of numpy windows ``(B, T, J, 3), (B, T, J, 4)``,
    bit-identical, chunk by chunk of windows."""
    X = np.asarray(X)
    Q = np.asarray(Q)
    xz = masked_mean(X[:, :, 0, 0::2])  # (B, 1, 2): over the whole array, as the generic function reduces it
    out_x = np.empty(np.broadcast_shapes(X.shape[:-1], Q.shape[:-1]) + (3,), dtype=np.result_type(X, Q))
    out_q = np.empty(out_x.shape[:-1] + (4,), dtype=out_x.dtype)
    for s, e in _chunks(len(X), X.shape[1]):
        lq, lp = _canonical_chunk(np.array(X[s:e], copy=True), Q[s:e], xz[s:e], parents, forward_axis, frame)
        _store(out_q[s:e], lq)
        _store(out_x[s:e], lp)
    return out_x, out_q


def canonical_positions_np(root: np.ndarray, rows: np.ndarray, local_q: np.ndarray, offsets: np.ndarray,
                           parents: Sequence[int], forward_axis: Sequence[float], frame: int,
                           threads: int = 1) -> np.ndarray:
    """Global joint positions ``(N, T, J, 3)`` of the canonicalised windows ``rows (N, T)`` (frame indices) of the
    frames ``root (F, 3), local_q (F, J, 4)`` with bone ``offsets (J, 3)``: the same numbers as
    ``fk(*canonicalise_windows(X, Q)[::-1])[1]`` of the gathered windows, without materialising them.

    ``threads > 1`` runs the chunks in a thread pool (numpy releases the GIL inside its loops); every chunk is
    computed and stored exactly as with one thread, so the result is bit-identical."""
    r = root[rows]  # (N, T, 3)
    xz = masked_mean(r[:, :, 0::2])
    out = np.empty(rows.shape + offsets.shape, dtype=np.result_type(root, local_q, offsets))

    def one(bounds: tuple[int, int]) -> None:
        s, e = bounds
        x = np.broadcast_to(offsets, (e - s, rows.shape[1]) + offsets.shape).copy()
        x[:, :, 0] = r[s:e]
        lq, lp = _canonical_chunk(x, local_q[rows[s:e]], xz[s:e], parents, forward_axis, frame)
        _store(out[s:e], _fk_chunk_tuples(lq, lp, parents))

    _run(one, _chunks(len(rows), rows.shape[1]), threads)
    return out


def column_mean_std(flat: np.ndarray, threads: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """``flat.mean(axis=0), flat.std(axis=0)`` of a ``(N, C)`` array, bit-identical (each column is reduced over
    the same rows in the same order; blocks keep at least two columns), with blocks of columns in a thread pool
    when ``threads > 1``."""
    mean = np.empty(flat.shape[1], dtype=np.result_type(flat, np.float64))
    std = np.empty_like(mean)

    def one(bounds: tuple[int, int]) -> None:
        s, e = bounds
        block = flat[:, s:e]  # a view: reducing >= 2 columns over axis 0 keeps numpy's row-by-row order
        mean[s:e], std[s:e] = block.mean(axis=0), block.std(axis=0)

    c = flat.shape[1]
    n = max(1, min(int(threads), c // 2))  # >= 2 columns a block: one column alone is summed pairwise, not row by row
    _run(one, [(c * i // n, c * (i + 1) // n) for i in range(n)], n)
    return mean, std


def _run(fn, items: list, threads: int) -> None:
    """``fn(item)`` for every item, in a ``concurrent.futures`` thread pool when ``threads > 1``."""
    if threads <= 1 or len(items) <= 1:
        for item in items:
            fn(item)
        return
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(max_workers=int(threads)) as pool:
        for _ in pool.map(fn, items):  # re-raises a worker's exception here
            pass


def _fk_chunk_tuples(lq, lp, parents: Sequence[int]):
    """:func:`_fk_chunk` positions from per-joint component tuples."""
    gq, gp = [lq[0]], [lp[0]]
    for j in range(1, len(parents)):
        par = parents[j]
        rot = _qrot(gq[par], lp[j])
        gp.append(tuple(rot[i] + gp[par][i] for i in range(3)))
        gq.append(_qmul(gq[par], lq[j]))
    return gp
