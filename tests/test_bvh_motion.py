"""The vectorised MOTION-block conversion: exact values, and None (never a wrong array) for malformed blocks."""
from __future__ import annotations

import numpy as np
import pytest

from inbetweening.data.bvh_motion import _char_class, _fast_decimals, motion_values


def test_values_are_float_of_each_token():
    block = b"1.5 -2.25 +3\n\n0.000001 -0 12345678.1234567\n"
    out = motion_values(block, 2, 3)
    expected = [[1.5, -2.25, 3.0], [1e-6, -0.0, 12345678.1234567]]
    assert out.shape == (2, 3) and out.tolist() == expected
    assert np.signbit(out[1, 1])
    assert motion_values(b"1e-3 2.5E+2 3.14159265358979323846\n", 1, 3).tolist() == [[1e-3, 250.0, 3.14159265358979323846]]
    assert motion_values(b"\n \n", 4, 0).shape == (4, 0)


@pytest.mark.parametrize(
    "block, frames, width",
    [
        (b"1 2\n3\n", 2, 2),  # short line
        (b"1 2\n3 4\n5 6\n", 2, 2),  # more lines than frames
        (b"1 2\n", 2, 2),  # truncated
        (b"1 x\n", 1, 2),  # non-numeric
        (b"1 nan\n", 1, 2),  # non-finite
        (b"1 1e999\n", 1, 2),  # overflows to inf
        (b"1 2\x01\n", 1, 2),  # control character
        (b"1-2 3\n", 1, 2),  # sign inside a token
        (b"1.2.3 4\n", 1, 2),  # two points in a token
        (b"1\n", 1, 0),  # values where the hierarchy has no channel
    ],
)
def test_malformed_blocks_give_none(block, frames, width):
    assert motion_values(block, frames, width) is None


def test_char_class():
    assert _char_class(np.frombuffer(b" -1.5\n+2\t", np.uint8)) == ("decimal", 2, 1)
    assert _char_class(np.frombuffer(b"1e5 2E-3", np.uint8))[0] == "float"
    assert _char_class(np.frombuffer(b"1 abc", np.uint8))[0] == "bad"


def test_fast_path_declines_long_mantissas():
    pad = b" " * 24
    for token, fast in ((b"-12345678.1234567", True), (b"123456789.5", False), (b"0.1234567890123456", False)):
        buf = pad + token + pad
        a = np.frombuffer(buf, np.uint8)
        _, nsigns, ndots = _char_class(a)
        got = _fast_decimals(buf, a, np.array([24]), np.array([24 + len(token)]), nsigns, ndots)
        assert (got is not None) == fast
        if fast:
            assert got.tolist() == [float(token)]
