"""Masks pinned by hand-written expectations: which values are known, and how the unknown ones are filled."""
import numpy as np
import pytest
import torch

from inbetweening.geometry.quaternion import qnormalize, slerp_np
from inbetweening.predictor.masks import (
    MASK_NAMES,
    MASKS,
    JointGaps,
    apply_mask,
    joints_known,
    lerp_fill,
    transition_known,
    zero_fill,
)
from inbetweening.representation import GlobalPosLocalQuat
from inbetweening.representation.base import Representation

LAYOUT = GlobalPosLocalQuat  # the default representation's channels: position 0:3, rotation 3:7


def about_y(rad):
    return [np.cos(rad / 2), 0.0, np.sin(rad / 2), 0.0]


def test_transition_known_exact_frames():
    k = transition_known(2, 9, 3, 3, 4)
    want = torch.tensor([1, 1, 1, 0, 0, 0, 0, 1, 1], dtype=torch.bool)
    assert k.shape == (2, 9, 3) and k.dtype == torch.bool
    assert torch.equal(k, want[None, :, None].expand(2, 9, 3))
    per = transition_known(3, 9, 2, 2, torch.tensor([1, 3, 6]))
    for b, n in enumerate((1, 3, 6)):
        frames = torch.tensor([f < 2 or f >= 2 + n for f in range(9)])
        assert torch.equal(per[b, :, 0], frames) and torch.equal(per[b, :, 1], frames)
    per[0, 0, 0] = False  # a real tensor, not a view sharing memory across joints
    assert per[0, 0, 1]


def test_joints_known_gap_fraction_and_clipping():
    g = torch.Generator().manual_seed(0)
    k = joints_known(32, 12, 10, 20, 50, 0.3, 0.3, generator=g)  # gaps longer than the window are clipped
    assert k.shape == (32, 12, 10) and k.dtype == torch.bool
    assert k[:, 0].all() and k[:, -1].all()  # first and last frames stay known
    for b in range(32):
        missing = ~k[b]
        joints = missing.any(0)
        assert int(joints.sum()) == 3  # round(0.3 * 10)
        frames = missing.any(1).nonzero().flatten()
        assert len(frames) == 10  # gap clipped to frames - 2
        assert torch.equal(missing[:, joints], missing[:, joints][:, :1].expand(-1, 3))  # same gap for each
    g2 = torch.Generator().manual_seed(1)
    k2 = joints_known(400, 40, 10, 4, 6, 0.0, 0.05, generator=g2)
    for b in range(400):
        missing = ~k2[b]
        assert int(missing.any(0).sum()) == 1  # at least one joint
        frames = missing.any(1).nonzero().flatten()
        assert 4 <= len(frames) <= 6 and int(frames[-1] - frames[0]) + 1 == len(frames)  # one contiguous gap
    lens = {int((~k2[b]).any(1).sum()) for b in range(400)}
    assert lens == {4, 5, 6}  # both ends of the range are drawn
    starts = {int((~k2[b]).any(1).nonzero()[0]) for b in range(400)}
    assert min(starts) == 1  # the first possible start
    # seeded: the same generator seed gives the same mask
    again = joints_known(400, 40, 10, 4, 6, 0.0, 0.05, generator=torch.Generator().manual_seed(1))
    assert torch.equal(again, k2)
    # every draw comes from the generator, none from the global RNG
    torch.manual_seed(123)
    a = joints_known(8, 40, 10, 4, 20, 0.1, 0.9, generator=torch.Generator().manual_seed(5))
    torch.manual_seed(456)
    b = joints_known(8, 40, 10, 4, 20, 0.1, 0.9, generator=torch.Generator().manual_seed(5))
    assert torch.equal(a, b)


def test_zero_fill():
    x = torch.arange(2 * 4 * 2 * 7, dtype=torch.float64).reshape(2, 4, 2, 7) + 1
    known = torch.ones(2, 4, 2, dtype=torch.bool)
    known[1, 2, 0] = False
    out = zero_fill(x, known)
    assert (out[1, 2, 0] == 0).all()
    out[1, 2, 0] = x[1, 2, 0]
    assert torch.equal(out, x)


def test_lerp_fill_hand_values_with_leading_trailing_and_extra_features():
    # one joint, 8 frames, features [pos xyz, quat wxyz, extra]; known frames 2 and 6 only
    t = 8
    x = torch.full((1, t, 1, 8), float("nan"), dtype=torch.float64)
    x[0, 2, 0] = torch.tensor([0.0, 10.0, -4.0, *about_y(0.0), 5.0], dtype=torch.float64)
    x[0, 6, 0] = torch.tensor([8.0, 2.0, 4.0, *about_y(1.2), 9.0], dtype=torch.float64)
    known = torch.zeros(1, t, 1, dtype=torch.bool)
    known[0, [2, 6], 0] = True
    out = lerp_fill(x, known, LAYOUT)[0, :, 0].numpy()
    want_pos = {0: [0, 10, -4], 1: [0, 10, -4], 3: [2, 8, -2], 4: [4, 6, 0], 5: [6, 4, 2], 7: [8, 2, 4]}
    want_ang = {0: 0.0, 1: 0.0, 3: 0.3, 4: 0.6, 5: 0.9, 7: 1.2}
    want_extra = {0: 5.0, 1: 5.0, 3: 5.0, 4: 5.0, 5: 5.0, 7: 9.0}  # extra features hold the previous known value
    for f in want_pos:
        np.testing.assert_allclose(out[f, :3], want_pos[f], atol=1e-12)
        np.testing.assert_allclose(out[f, 3:7], about_y(want_ang[f]), atol=1e-12)
        assert out[f, 7] == want_extra[f]
    np.testing.assert_array_equal(out[[2, 6]], x[0, [2, 6], 0].numpy())  # known rows copied exactly


def test_lerp_fill_several_gaps_per_joint_and_per_joint_masks():
    x = torch.zeros(1, 10, 2, 7, dtype=torch.float64)
    x[..., 3] = 1.0
    x[0, :, 0, 0] = torch.tensor([0, 99, 99, 3, 99, 99, 99, 7, 99, 9], dtype=torch.float64)
    x[0, :, 1, 0] = torch.tensor([0, 10, 20, 30, 40, 50, 60, 70, 80, 90], dtype=torch.float64)
    known = torch.ones(1, 10, 2, dtype=torch.bool)
    known[0, [1, 2, 4, 5, 6, 8], 0] = False
    out = lerp_fill(x, known, LAYOUT)
    np.testing.assert_allclose(out[0, :, 0, 0], np.arange(10.0), atol=1e-12)  # each gap between its own neighbours
    assert torch.equal(out[0, :, 1], x[0, :, 1])  # the fully known joint is untouched


def test_lerp_fill_no_known_frame_for_a_joint_keeps_finite_zeros():
    x = torch.randn(1, 5, 2, 7, dtype=torch.float64)
    known = torch.ones(1, 5, 2, dtype=torch.bool)
    known[0, :, 1] = False
    out = lerp_fill(x, known, LAYOUT)
    assert torch.isfinite(out).all() and torch.equal(out[0, :, 0], x[0, :, 0])
    np.testing.assert_array_equal(out[0, :, 1, :3], 0.0)


@pytest.mark.parametrize("name", MASK_NAMES)
def test_apply_mask_shown_and_interpolation(name):
    x = torch.zeros(1, 6, 1, 7, dtype=torch.float64)
    x[0, :, 0, 0] = torch.arange(6, dtype=torch.float64) * 2
    x[..., 3] = 1.0
    known = transition_known(1, 6, 1, 2, 3)  # frames 2, 3, 4 unknown
    xn = x.clone()
    xn[~known] = float("nan")
    shown, interp = apply_mask(name, xn, known, LAYOUT)
    np.testing.assert_allclose(interp[0, :, 0, 0], [0, 2, 4, 6, 8, 10], atol=1e-12)
    if name == "zero":
        np.testing.assert_array_equal(shown[0, 2:5, 0], 0.0)
    else:
        assert torch.equal(shown, interp)
    assert torch.equal(shown[known], x[known])
    assert set(MASKS) == set(MASK_NAMES)


def test_apply_mask_unknown_name():
    with pytest.raises(ValueError, match=r"unknown mask 'blur'; choose one of \['joints', 'lerp', 'zero'\]"):
        apply_mask("blur", torch.zeros(1, 2, 1, 7), torch.ones(1, 2, 1, dtype=torch.bool), LAYOUT)


def test_transition_known_per_batch_and_per_sample():
    k = transition_known(2, 20, 3, 10, 5)
    assert k[:, :10].all() and not k[:, 10:15].any() and k[:, 15:].all()
    k2 = transition_known(2, 20, 3, 10, torch.tensor([3, 6]))
    assert not k2[0, 10:13].any() and k2[0, 13].all() and not k2[1, 10:16].any() and k2[1, 16].all()


def test_joints_known_fraction_and_gap_ranges():
    g = torch.Generator().manual_seed(0)
    k = joints_known(16, 60, 20, 10, 30, 0.1, 0.3, generator=g)
    assert k[:, 0].all() and k[:, -1].all()
    missing_joints = (~k).any(1).sum(-1)
    assert (missing_joints >= 2).all() and (missing_joints <= 6).all()
    gap = (~k).any(2).sum(1)
    assert (gap >= 10).all() and (gap <= 30).all()


def test_zero_and_lerp_fill_against_numpy_slerp():
    x = torch.randn(2, 12, 3, 7, dtype=torch.float64)
    x[..., 3:] = qnormalize(x[..., 3:])
    known = transition_known(2, 12, 3, 4, 6)  # frames 4..9 unknown, 3 and 10 known
    z = zero_fill(x, known, LAYOUT)
    assert (z[:, 4:10] == 0).all() and torch.equal(z[known], x[known])
    lf = lerp_fill(x, known, LAYOUT)
    w = (7 - 3) / (10 - 3)
    np.testing.assert_allclose(lf[:, 7, :, :3], x[:, 3, :, :3] + w * (x[:, 10, :, :3] - x[:, 3, :, :3]), atol=1e-12)
    ref = slerp_np(x[:, 3, :, 3:].numpy(), x[:, 10, :, 3:].numpy(), w)
    np.testing.assert_allclose(lf[:, 7, :, 3:].numpy(), ref, atol=1e-9)
    # unknown values are never read, even when they are NaN
    xn = x.clone()
    xn[~known] = float("nan")
    assert torch.isfinite(lerp_fill(xn, known, LAYOUT)).all() and torch.isfinite(zero_fill(xn, known)).all()
    with pytest.raises(ValueError, match="unknown mask"):
        apply_mask("blur", x, known, LAYOUT)


def test_lerp_fill_per_joint_gaps_hold_at_edges():
    x = torch.arange(10, dtype=torch.float64)[None, :, None, None].expand(1, 10, 2, 7).clone()
    known = torch.ones(1, 10, 2, dtype=torch.bool)
    known[0, 2:5, 0] = False  # interior gap on joint 0
    known[0, 7:, 1] = False  # trailing gap on joint 1: hold the last known value
    out = lerp_fill(x, known, LAYOUT)
    np.testing.assert_allclose(out[0, 2:5, 0, 0], [2, 3, 4])
    np.testing.assert_allclose(out[0, 7:, 1, 0], [6, 6, 6])

class _RotationFirst(Representation):
    """A layout with the rotation before the position and one extra channel: lerp_fill follows the layout."""

    features, quat, pos = 8, slice(0, 4), slice(4, 7)


def test_lerp_fill_reads_the_channels_from_the_layout():
    x = torch.zeros(1, 5, 1, 8, dtype=torch.float64)
    x[0, 0, 0] = torch.tensor([*about_y(0.0), 0.0, 4.0, -8.0, 1.0], dtype=torch.float64)
    x[0, 4, 0] = torch.tensor([*about_y(0.8), 8.0, 0.0, 8.0, 3.0], dtype=torch.float64)
    known = transition_known(1, 5, 1, 1, 3)  # frames 1..3 unknown
    out = lerp_fill(x, known, _RotationFirst)[0, :, 0].numpy()
    for f in (1, 2, 3):
        np.testing.assert_allclose(out[f, 4:7], [2.0 * f, 4.0 - f, -8.0 + 4.0 * f], atol=1e-12)
        np.testing.assert_allclose(out[f, 0:4], about_y(0.2 * f), atol=1e-12)
        assert out[f, 7] == 1.0  # the extra channel holds
    # the same values read with the default layout are not interpolated as positions/rotations
    assert not np.allclose(lerp_fill(x, known, LAYOUT)[0, :, 0].numpy(), out)


def test_joint_gaps_defaults_config_and_known():
    g = JointGaps()
    assert (g.gap_min, g.gap_max, g.frac_min, g.frac_max) == (10, 200, 0.1, 0.3)
    assert JointGaps.from_config(None) == g and JointGaps.from_config({"name": "joints"}) == g
    c = JointGaps.from_config({"name": "joints", "gap_min": 3, "gap_max": 7, "frac_max": 0.5})
    assert (c.gap_min, c.gap_max, c.frac_min, c.frac_max) == (3, 7, 0.1, 0.5)
    with pytest.raises(TypeError):
        JointGaps.from_config({"gap": 3})
    k = c.known(8, 40, 20, generator=torch.Generator().manual_seed(4))
    want = joints_known(8, 40, 20, 3, 7, 0.1, 0.5, generator=torch.Generator().manual_seed(4))
    assert torch.equal(k, want)
    gap = (~k).any(2).sum(1)
    assert (gap >= 3).all() and (gap <= 7).all()


def test_gap_lengths_against_a_loop_per_joint():
    """Each unknown value gets the length of its own joint's run of unknown frames (open at the edges too); known
    values 0; the same numbers as a plain loop on random per-joint masks."""
    from inbetweening.predictor.masks import gap_lengths

    k = torch.tensor([1, 1, 0, 0, 0, 1, 0, 1, 0, 0], dtype=torch.bool)
    assert gap_lengths(k[None, :, None])[0, :, 0].tolist() == [0, 0, 3, 3, 3, 0, 1, 0, 2, 2]
    g = torch.Generator().manual_seed(0)
    known = torch.rand(4, 23, 5, generator=g) < 0.3
    want = torch.zeros(4, 23, 5, dtype=torch.long)
    for b in range(4):
        for j in range(5):
            t = 0
            while t < 23:
                if known[b, t, j]:
                    t += 1
                    continue
                end = t
                while end < 23 and not known[b, end, j]:
                    end += 1
                want[b, t:end, j] = end - t
                t = end
    assert torch.equal(gap_lengths(known), want)
    assert torch.equal(gap_lengths(torch.zeros(1, 6, 2, dtype=torch.bool)), torch.full((1, 6, 2), 6))
