"""Exact, vectorised conversion of a BVH MOTION block (decimal text) to a float64 array.

:func:`motion_values` finds token boundaries and per-line value counts with numpy operations over the raw
bytes, never a Python loop over frames.  Plain decimals (``-12.345678``, up to 15 significant digits, the
format every common exporter writes) are converted by an exact SWAR digit parser (:func:`_fast_decimals`);
anything else (exponents, longer mantissas) goes through numpy's ``strtod`` path.  Both give the correctly
rounded double, identical to ``float(token)``.  Problems are only *detected* here (``None`` is returned);
the BVH reader then locates and reports them.
"""
from __future__ import annotations

import numpy as np

_PAD = 24  # whitespace around the block so 8-byte loads never leave the buffer
_U64 = np.uint64
_POW10 = 10.0 ** np.arange(16)
# digit nibbles of the k highest bytes of a little-endian uint64 (the last k characters of an 8-byte load)
_DIGITS_HIGH = np.array([0x0F0F0F0F0F0F0F0F & ~((1 << (8 * (8 - k))) - 1) for k in range(9)], dtype=_U64)
_POW10_U64 = np.array([10**k for k in range(16)], dtype=_U64)


def _eight_digits(chunk: np.ndarray, keep: np.ndarray | np.uint64) -> np.ndarray:
    """SWAR: 8 ASCII digits per uint64 (little-endian load, first byte most significant) -> their value.

    ``keep`` selects the digit nibbles to use (from ``_DIGITS_HIGH``); other bytes count as ``0``.
    ``(N,) uint64 -> (N,) uint64``, values < 1e8.
    """
    x = chunk & keep
    x = (x * _U64(2561)) >> _U64(8)  # pairs of digits: 10 * d0 + d1 in every other byte
    lo, hi = x & _U64(0x000000FF000000FF), (x >> _U64(16)) & _U64(0x000000FF000000FF)
    return (lo * _U64(0x000F424000000064) + hi * _U64(0x0000271000000001)) >> _U64(32)


def _fast_decimals(
    buf: bytes, a: np.ndarray, ts: np.ndarray, te: np.ndarray, nsigns: int, ndots: int
) -> np.ndarray | None:
    """Convert plain decimal tokens ``[+-]digits[.digits]`` exactly, vectorised.

    ``buf``/``a``: the padded block (bytes / uint8 view) holding only digits, ``+-.`` and whitespace;
    ``ts``/``te``: ``(M,)`` token start/end offsets; ``nsigns``/``ndots``: counts of ``+-`` and ``.`` in ``a``.
    Returns ``(M,)`` float64 equal to ``float(token)``, or ``None`` when a token is not of that form or has
    more than 15 significant digits (or 8 before the point): the caller then uses the general path.

    Each token's digits before and after the point are read as integers with SWAR arithmetic on 8-byte
    loads; the mantissa (< 1e15, exact in float64) divided by the exact power of ten is correctly rounded.
    """
    m = len(ts)
    if m == 0:
        return np.zeros(0)
    first = a[ts]
    negative = first == 45
    signed = negative | (first == 43)
    if np.count_nonzero(signed) != nsigns:
        return None  # a sign inside a token
    pivot = None  # position of each token's point (its end if it has none)
    tok0 = buf[ts[0] : te[0]]
    if ndots == m and b"." in tok0:  # common case: every token has the same number of decimals
        nfrac = len(tok0) - tok0.index(b".") - 1
        guess = te - (nfrac + 1)
        if (a[guess] == 46).all():
            nint = guess - ts - signed
            if nint.min() >= 0:  # each guessed point lies inside its own token
                pivot, ndig = guess, nint + nfrac
    if pivot is None:
        dots = np.flatnonzero(a == 46)
        owner = np.searchsorted(te, dots, side="right")
        if len(owner) > 1 and not (np.diff(owner) > 0).all():
            return None  # two points in one token
        pivot = te.copy()
        pivot[owner] = dots
        nfrac = np.zeros(m, dtype=np.int64)
        nfrac[owner] = te[owner] - dots - 1
        nint = pivot - ts - signed
        ndig = nint + nfrac
    if nint.max() > 8 or ndig.max() > 15 or ndig.min() < 1:
        return None
    max_frac = int(np.max(nfrac))
    if max_frac <= 7:  # one 16-byte load per token: 8 bytes before the point, the point and 7 after it
        v16 = np.ndarray(shape=(len(buf) - 15,), dtype="V16", buffer=buf, strides=(1,))
        words = v16[pivot - 8].view("<u8").reshape(m, 2)
        mantissa = _eight_digits(words[:, 0], _DIGITS_HIGH[nint])
        if max_frac:  # shift the decimals to the top bytes, dropping the point and what follows them
            frac = _eight_digits(words[:, 1] << (_U64(8) * _U64(7 - nfrac)), _DIGITS_HIGH[nfrac])
            mantissa = mantissa * _POW10_U64[nfrac] + frac
    else:  # up to 15 decimals: the first nfrac - 8 and the last 8 from two more 8-byte loads
        u = np.ndarray(shape=(len(buf) - 7,), dtype="<u8", buffer=buf, strides=(1,))
        lo, hi = np.maximum(nfrac - 8, 0), np.minimum(nfrac, 8)
        mantissa = _eight_digits(u[pivot - 8], _DIGITS_HIGH[nint])
        mantissa = mantissa * _POW10_U64[lo] + _eight_digits(u[te - 16], _DIGITS_HIGH[lo])
        mantissa = mantissa * _POW10_U64[hi] + _eight_digits(u[te - 8], _DIGITS_HIGH[hi])
    scale = _POW10[nfrac]
    return mantissa.astype(np.float64) / np.where(negative, -scale, scale)  # one correctly rounded division


def _char_class(a: np.ndarray) -> tuple[str, int, int]:
    """Classify the bytes of a motion block (uint8 ``(N,)``): ``(kind, number of +/- signs, number of points)``.

    ``kind`` is ``"decimal"`` (only digits, ``+-.`` and whitespace), ``"float"`` (also ``eE``) or ``"bad"``.
    """
    nws = np.count_nonzero(a <= 32)
    if np.count_nonzero(a < 9) or np.count_nonzero((a > 13) & (a < 32)):
        return "bad", 0, 0  # control characters
    nsigns = np.count_nonzero(a == 43) + np.count_nonzero(a == 45)
    ndots = np.count_nonzero(a == 46)
    if np.count_nonzero(a < 48) != nws + nsigns + ndots:
        return "bad", 0, 0
    nhigh = np.count_nonzero(a > 57)
    if nhigh == 0:
        return "decimal", nsigns, ndots
    return ("float" if nhigh == np.count_nonzero(a == 101) + np.count_nonzero(a == 69) else "bad"), nsigns, ndots


def motion_values(block: bytes, frames: int, width: int) -> np.ndarray | None:
    """Vectorised conversion of the MOTION data to ``(frames, width)`` float64.

    Returns ``None`` if anything is wrong (value counts, line counts, non-numeric or non-finite values);
    the caller then locates and reports the problem.
    """
    buf = b" " * _PAD + block + b" " * _PAD
    a = np.frombuffer(buf, dtype=np.uint8)
    kind, nsigns, ndots = _char_class(a)
    if kind == "bad":
        return None
    ws = a <= 32
    edges = np.flatnonzero(ws[1:] != ws[:-1]) + 1
    ts, te = edges[0::2], edges[1::2]
    if width == 0:
        return np.zeros((frames, 0)) if len(ts) == 0 else None
    # values per line, vectorised: tokens before each newline
    before = np.searchsorted(ts, np.flatnonzero(a == 10))
    per_line = np.diff(np.concatenate(([0], before, [len(ts)])))
    nonblank = per_line[per_line != 0]
    if len(nonblank) != frames or (nonblank != width).any():
        return None
    values = _fast_decimals(buf, a, ts, te, nsigns, ndots) if kind == "decimal" else None
    if values is None:
        try:
            values = np.array(block.split(), dtype=np.float64)
        except ValueError:
            return None
        if len(values) != len(ts) or not np.isfinite(values).all():
            return None
    return values.reshape(frames, width)
