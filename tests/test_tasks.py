"""The training task (training/tasks.py): transition/context/keyframe draws and the windows cut to them."""
from __future__ import annotations

import pytest
import torch

from inbetweening.data import windows as W
from inbetweening.training.tasks import draw_task, task_window


def _old_task(x, n, per_sample):
    """The training task as it was cut before context/keyframe options existed (kept here as the reference);
    ``x (B, W, ...)``: frames first after the batch."""
    t = W.N_PAST + int(n.max()) + 1
    x = x[:, :t].clone()
    if per_sample:
        tt = torch.arange(t)[None, :]
        src = torch.minimum(tt, (W.N_PAST + n)[:, None])
        src = src.reshape(*src.shape, *([1] * (x.dim() - 2)))
        x = torch.gather(x, 1, src.expand_as(x))
    return x


@pytest.mark.parametrize("per_sample", [False, True])
def test_default_task_draws_and_cuts_what_it_did_before(per_sample):
    root, q = torch.randn(6, 50, 3, dtype=torch.float64), torch.randn(6, 50, 5, 4, dtype=torch.float64)
    g1, g2 = torch.Generator().manual_seed(3), torch.Generator().manual_seed(3)
    c, n, keys = draw_task(g1, 6, (5, 30), per_sample, (10, 10), 0, 0.0)
    old_n = torch.randint(5, 31, (6,) if per_sample else (1,), generator=g2).expand(6)
    assert torch.equal(n, old_n) and keys is None and (c == 10).all()
    out_root, out_q, known = task_window(root, q, c, n)
    assert torch.equal(out_root, _old_task(root, n, per_sample))
    assert torch.equal(out_q, _old_task(q, n, per_sample))
    assert known.shape == out_q.shape[:3] and known.dtype == torch.bool
    assert known[:, :10].all() and not known[0, 10 : 10 + int(n[0])].any() and known[0, 10 + int(n[0])].all()


def test_variable_context_keeps_the_last_context_frame_and_the_target():
    root = torch.arange(50.0, dtype=torch.float64)[None, :, None].expand(8, 50, 3).clone()
    q = torch.arange(50.0, dtype=torch.float64)[None, :, None, None].expand(8, 50, 3, 4).clone()
    c, n, _ = draw_task(torch.Generator().manual_seed(0), 8, (5, 20), True, (1, 10), 0, 0.0)
    assert c.min() >= 1 and c.max() <= 10 and len(set(c.tolist())) > 1
    out_root, out_q, known = task_window(root, q, c, n)
    assert out_q.shape[1] == out_root.shape[1] == int((c + n).max()) + 1
    for out in (out_root[..., None, :], out_q):  # root and rotations are cut alike
        for b in range(8):
            cb, nb = int(c[b]), int(n[b])
            assert out[b, cb - 1, 0, 0] == W.N_PAST - 1  # the last context frame is the window's frame 9
            assert out[b, 0, 0, 0] == W.N_PAST - cb  # no frame before the context
            assert out[b, cb + nb, 0, 0] == W.N_PAST + nb  # the target keyframe
            assert (out[b, cb + nb :, 0, 0] == W.N_PAST + nb).all()  # padding repeats the target
            assert known[b, :cb].all() and not known[b, cb : cb + nb].any() and known[b, cb + nb :].all()


def test_intermediate_keyframes_lie_inside_the_transition_and_leave_frames_to_predict():
    c, n, keys = draw_task(torch.Generator().manual_seed(1), 64, (2, 30), True, (1, 10), 4, 0.5)
    root, q = torch.zeros(64, 50, 3), torch.zeros(64, 50, 3, 4)
    _, _, known = task_window(root, q, c, n, keys)
    counts = keys.sum(1)
    assert 0 < (counts > 0).float().mean() < 1  # about half the samples get keyframes
    assert counts.max() <= 4
    for b in range(64):
        cb, nb = int(c[b]), int(n[b])
        inside = keys[b].nonzero().flatten()
        assert ((inside >= cb) & (inside < cb + nb)).all()
        assert (~known[b, cb : cb + nb, 0]).sum() >= 1  # something is left to predict
        assert known[b, inside].all()


def test_subtrees_mark_each_joint_and_everything_below_it():
    from inbetweening.training.tasks import subtrees
    below = subtrees([-1, 0, 1, 1, 0, 4])  # root, spine, arm.L, arm.R, leg, foot
    assert below[0].all()
    assert below[1].tolist() == [False, True, True, True, False, False]
    assert below[4].tolist() == [False, False, False, False, True, True]
    assert below[5].tolist() == [False] * 5 + [True]


def test_partial_keys_know_one_body_part_or_the_rest_and_only_on_keyframes():
    from inbetweening.training.tasks import partial_keys, subtrees
    parents = [-1, 0, 1, 1, 0, 4]
    below = subtrees(parents)
    c, n, keys = draw_task(torch.Generator().manual_seed(3), 128, (5, 30), True, (1, 10), 4, 1.0)
    part = partial_keys(torch.Generator().manual_seed(4), keys, parents, 0.5)
    assert part.shape == (*keys.shape, 6)
    assert not part[~keys].any()  # never a value outside the keyframes
    rows = part[keys]
    full = rows.all(-1)
    assert 0.3 < full.float().mean() < 0.7  # about half the keyframes stay whole
    parts = {tuple(r.tolist()) for r in rows[~full]}
    allowed = {tuple(b.tolist()) for b in below[1:]} | {tuple((~b).tolist()) for b in below[1:]}
    assert parts <= allowed and len(parts) > 4
    _, _, known = task_window(torch.zeros(128, 50, 3), torch.zeros(128, 50, 6, 4), c, n, part)
    assert (known.any(-1) & ~known.all(-1)).any()  # frames known on some joints only
    assert torch.equal(partial_keys(torch.Generator().manual_seed(4), keys, parents, 0.0), keys[..., None].expand_as(part))


def test_body_part_mixing_takes_another_windows_upper_body_and_keeps_the_legs():
    from inbetweening.training.tasks import mix_body_parts, upper_body

    # hips 0; legs 1-2 (foot 2) and 3-4 (foot 4); spine 5 with head 6 and arm 7-8
    parents = [-1, 0, 1, 0, 3, 0, 5, 5, 7]
    upper = upper_body(parents, [2, 4])
    assert upper.tolist() == [False, False, False, False, False, True, True, True, True]
    q = torch.randn(6, 4, 9, 4, generator=torch.Generator().manual_seed(1))
    out = mix_body_parts(torch.Generator().manual_seed(0), q, [upper], prob=1.0)
    assert torch.equal(out[:, :, ~upper], q[:, :, ~upper])  # root and legs: each window its own
    for b in range(6):  # the upper body: another window's, whole
        donors = [d for d in range(6) if d != b and torch.equal(out[b][:, upper], q[d][:, upper])]
        assert len(donors) == 1
    assert torch.equal(mix_body_parts(None, q, [upper], prob=0.0), q)
    with pytest.raises(ValueError, match="data.mix_parts: no joint under the root without a foot"):
        upper_body([-1, 0, 1], [2])


def test_limb_mixing_takes_each_arm_and_the_head_from_its_own_donor():
    from inbetweening.training.tasks import mix_body_parts, upper_body, upper_limbs

    # hips 0; legs 1-2 (foot 2), 3-4 (foot 4); spine 5, chest 6 with neck 7 -> head 8, arm 9-10, arm 11-12
    parents = [-1, 0, 1, 0, 3, 0, 5, 6, 7, 6, 9, 6, 11]
    limbs = upper_limbs(parents, upper_body(parents, [2, 4]))
    want = [[7, 8], [9, 10], [11, 12]]  # written out by hand, not derived
    assert [torch.nonzero(m).flatten().tolist() for m in limbs] == want
    assert len(upper_limbs([-1, 0, 1, 0, 3], upper_body([-1, 0, 1, 0, 3], [2]))) == 1  # no branch: one part, whole
    b = 64
    q = torch.randn(b, 3, 13, 4, generator=torch.Generator().manual_seed(2))
    out = mix_body_parts(torch.Generator().manual_seed(5), q, limbs)
    assert torch.equal(out[:, :, :7], q[:, :, :7])  # root, legs, spine, chest: the window's own
    sources = []
    for w in range(b):
        src = []
        for joints in want:  # each limb whole from one window of the batch
            hits = [d for d in range(b) if torch.equal(out[w][:, joints], q[d][:, joints])]
            assert len(hits) == 1
            src.append(hits[0])
        sources.append(src)
    left_right = [(s[1] != w, s[2] != w) for w, s in enumerate(sources)]
    assert (True, False) in left_right and (False, True) in left_right  # the arms are drawn apart
    assert any(s[1] != w and s[2] != w and s[1] != s[2] for w, s in enumerate(sources))  # two donors, one window
