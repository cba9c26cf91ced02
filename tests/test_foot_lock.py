"""Foot locking (runtime/foot_lock.py) and the two-bone IK behind it (geometry/ik.py)."""
from __future__ import annotations

import numpy as np
import pytest

from inbetweening.data.contacts import FootContact, foot_contacts
from inbetweening.data.synthetic import NAMES, OFFSETS, PARENTS, generate_clip
from inbetweening.geometry.ik import two_bone_ik
from inbetweening.geometry.quaternion import qmul, qnormalize, qrot
from inbetweening.geometry.skeleton import Skeleton
from inbetweening.runtime.foot_lock import (
    clip_feet,
    gap_contacts,
    legs,
    lock_feet,
    plausible_contacts,
)
from inbetweening.runtime.settings import DEFAULT_SETTINGS

PLANTED_REACH, TRUSTED_SHARE = DEFAULT_SETTINGS.planted_reach, DEFAULT_SETTINGS.trusted_share

SK = Skeleton(NAMES, PARENTS, OFFSETS)
FEET = [NAMES.index(n) for n in ("LeftFoot", "LeftToe", "RightFoot", "RightToe")]


def test_legs_of_the_feet():
    assert [tuple(NAMES[j] for j in leg) for leg in legs(SK, FEET)] == [
        ("LeftUpLeg", "LeftLeg", "LeftFoot"), ("RightUpLeg", "RightLeg", "RightFoot")]
    assert legs(SK, [NAMES.index("LeftUpLeg")]) == []  # its chain would turn the root


def test_two_bone_ik_reaches_the_target_and_keeps_hip_and_foot():
    rng = np.random.default_rng(0)
    f = 300

    def rq(n):
        return qnormalize(rng.normal(size=(n, 4)))

    par, hl, kl, al = rq(f), rq(f), rq(f), rq(f)
    hip = rng.normal(size=(f, 3))
    knee_off, ankle_off = np.array([0, -43.0, 0]), np.array([0, -42.0, 0])

    def chain(hl, kl, al):
        hg = qmul(par, hl)
        kg = qmul(hg, kl)
        knee = hip + qrot(hg, np.broadcast_to(knee_off, (f, 3)))
        return hg, kg, qmul(kg, al), knee, knee + qrot(kg, np.broadcast_to(ankle_off, (f, 3)))

    hg, kg, ag, knee, ankle = chain(hl, kl, al)
    d = rng.normal(size=(f, 3))
    reach = rng.uniform(5, 84, (f, 1))
    target = hip + d / np.linalg.norm(d, axis=1, keepdims=True) * reach
    h2, k2, a2 = two_bone_ik(hip, knee, ankle, target, hg, kg, ag, par)
    _, _, ag2, knee2, ankle2 = chain(h2, k2, a2)
    assert np.abs(ankle2 - target).max() < 1e-3  # cm
    assert np.abs(np.abs((ag2 * ag).sum(-1)) - 1).max() < 1e-6  # the foot keeps its global rotation
    assert np.allclose(np.linalg.norm(knee2 - hip, axis=1), 43.0)  # bones keep their lengths
    far = hip + (target - hip) / reach * 200  # out of reach: the leg straight towards it
    _, _, _, _, ankle3 = chain(*two_bone_ik(hip, knee, ankle, far, hg, kg, ag, par))
    along = ((ankle3 - hip) * (far - hip)).sum(-1) / np.linalg.norm(far - hip, axis=-1)
    assert np.allclose(along, 85.0, atol=1e-3)


def _clip(n=60, seed=1):
    """A synthetic clip walking on the spot (root XZ held: every locked position stays within the legs' reach)."""
    q, root = generate_clip(np.random.default_rng(seed), n)
    root[:, [0, 2]] = root[:1, [0, 2]]
    return root, q


def test_locked_feet_stand_still_and_keys_stay_exact():
    root, q = _clip()
    known = [0, 30, 59]
    contact = np.zeros((60, len(NAMES)))
    left = NAMES.index("LeftFoot")
    contact[8:20, left] = 1.0  # a planted left foot the model slid through, no key inside
    contact[25:36, left] = 1.0  # a run holding the key at frame 30
    assert np.array_equal(lock_feet(SK, root, q, known, contact, FEET)[0], root)  # by default the root stays
    new_root, out = lock_feet(SK, root, q, known, contact, FEET, move_root=True)
    assert np.array_equal(out[known], q[known]) and np.array_equal(new_root[known], root[known])
    _, gp0 = SK.pose(root, q)
    _, gp = SK.pose(new_root, out)
    a = gp[:, left]
    assert np.abs(a[8:20] - a[8:20].mean(axis=0)).max() < 1e-3  # held still over the run
    assert np.allclose(a[8:20].mean(axis=0), gp0[8:20, left].mean(axis=0), atol=1e-3)  # at the run's mean position
    # held where the key puts it (where the hip was too far for the leg, the root moved towards it)
    at_key = np.linalg.norm(a[25:36] - gp0[30, left], axis=1) < 1e-2
    assert at_key.all()
    moved = np.flatnonzero(np.abs(new_root - root).max(axis=1) > 0)
    assert len(moved) and moved.min() >= 8 - 8 and moved.max() <= 35 + 8  # only around the runs (out of reach)
    right = NAMES.index("RightFoot")
    rel = gp[:, right] - new_root[:, None][:, 0]
    assert np.allclose(rel, gp0[:, right] - root)  # no contact on the right: its pose untouched (carried by the root)
    changed = np.flatnonzero(np.abs(out - q).max(axis=(1, 2)) > 0)
    assert changed.min() >= 8 - 4 and changed.max() <= 35 + 4  # the run and its blend frames only
    untouched = [j for j in range(len(NAMES)) if j not in (1, 2, 3)]  # only the left hip, knee and ankle turn
    assert np.array_equal(out[:, untouched], q[:, untouched])
    blend = np.linalg.norm(a[4:8] - gp0[4:8, left], axis=1)
    assert (np.diff(blend) > 0).all()  # blended in over the 4 frames before the run


def test_a_run_between_two_keys_moves_from_one_key_to_the_other():
    root, q = _clip(seed=2)
    known = [0, 10, 20, 59]
    contact = np.zeros((60, len(NAMES)))
    left = NAMES.index("LeftFoot")
    contact[5:25, left] = 1.0
    new_root, out = lock_feet(SK, root, q, known, contact, FEET, move_root=True)
    _, gp0 = SK.pose(root, q)
    a = SK.pose(new_root, out)[1][:, left]
    w = (np.arange(5, 25) - 10).clip(0, 10) / 10
    want = gp0[10, left] + w[:, None] * (gp0[20, left] - gp0[10, left])
    reached = np.linalg.norm(a[5:25] - want, axis=1) < 1e-2  # (the root moved where the leg could not reach)
    assert reached.all() and np.array_equal(out[known], q[known])


def test_a_held_toe_stays_still_with_or_without_its_ankle():
    """A planted toe is held as an ankle is: with its heel up (the toe alone planted) the leg carries the foot, as
    generated, so the toe sits at its hold; with the ankle planted too the foot turns about the held ankle to point
    the toe at its hold.  Keys stay exact; the other leg is untouched.  A toe run the body walks away from (the foot,
    carried to the toe's hold, out of the leg's reach) is not held."""
    root, q = _clip(seed=3)
    known = [0, 30, 59]
    left, ltoe = NAMES.index("LeftFoot"), NAMES.index("LeftToe")
    _, gp0 = SK.pose(root, q)
    for ankle_too in (False, True):
        contact = np.zeros((60, len(NAMES)))
        contact[8:20, ltoe] = 1.0
        if ankle_too:
            contact[8:20, left] = 1.0
        new_root, out = lock_feet(SK, root, q, known, contact, FEET)
        gp = SK.pose(new_root, out)[1]
        toe = gp[8:20, ltoe]
        assert np.abs(toe - toe.mean(axis=0)).max() < 1e-3  # the toe held still over its run
        hold = gp0[8:20, ltoe].mean(axis=0)  # the run's mean, or the direction towards it from the held ankle
        if ankle_too:
            ankle = gp[8:20, left]
            assert np.abs(ankle - ankle.mean(axis=0)).max() < 1e-3
            aim, want = toe[0] - ankle[0], hold - ankle[0]
            assert np.allclose(aim / np.linalg.norm(aim), want / np.linalg.norm(want), atol=1e-6)
        else:
            assert np.allclose(toe[0], hold, atol=1e-3)
        assert np.array_equal(out[known], q[known])
        right_leg = [NAMES.index(n) for n in ("RightUpLeg", "RightLeg", "RightFoot")]
        assert np.array_equal(out[:, right_leg], q[:, right_leg])
    contact = np.zeros((60, len(NAMES)))
    contact[8:20, ltoe] = 1.0
    leg = np.linalg.norm(OFFSETS[NAMES.index("LeftLeg")]) + np.linalg.norm(OFFSETS[left])
    walked = root.copy()
    walked[8:20, 0] += np.linspace(0, 3 * leg, 12)  # the body walks away from the toe: out of the leg's reach
    assert np.array_equal(lock_feet(SK, walked, q, known, contact, FEET)[1], q)  # not held: the fill as it was
    walked[8:20, 0] = root[8:20, 0] + np.linspace(0, 0.2 * PLANTED_REACH * leg, 12)  # a short step: held
    toe = SK.pose(*lock_feet(SK, walked, q, known, contact, FEET))[1][8:20, ltoe]
    assert np.abs(toe - toe.mean(axis=0)).max() < 1e-3
    assert np.array_equal(lock_feet(SK, walked, q, known, contact, FEET, toes=False)[1], q)  # the ankles alone
    free = np.zeros((60, len(NAMES)))
    free[8:20, left] = 1.0  # the ankle alone: the foot keeps its global rotation (the toe follows it)
    gq0 = SK.pose(root, q)[0]
    gq = SK.pose(*lock_feet(SK, root, q, known, free, FEET))[0]
    assert np.allclose(np.abs((gq[8:20, left] * gq0[8:20, left]).sum(-1)), 1.0, atol=1e-9)


def test_a_foot_planted_only_at_the_end_key_blends_in_where_it_goes_on():
    """One gap, its end key the only planted frame: the lock leaves the gap alone unless ``ends`` says the foot stays
    planted beyond that key (the keys of the next gap hold it down); then the frames before it are pulled towards it."""
    root, q = _clip(seed=2)
    root, q = root[:11], q[:11]
    contact = np.zeros((11, len(NAMES)))
    left = NAMES.index("LeftFoot")
    contact[10, left] = 1.0
    alone = lock_feet(SK, root, q, [0, 10], contact, FEET)
    assert np.array_equal(alone[1], q)
    ends = np.zeros((2, len(NAMES)), dtype=bool)
    ends[1, left] = True
    _, out = lock_feet(SK, root, q, [0, 10], contact, FEET, ends=ends)
    gp0, gp1 = SK.pose(root, q)[1][:, left], SK.pose(root, out)[1][:, left]
    d0, d1 = (np.linalg.norm(g[6:10] - gp0[10], axis=1) for g in (gp0, gp1))
    assert (d1 < d0).all() and np.array_equal(out[[0, 10]], q[[0, 10]])


def test_a_predicted_contact_the_leg_cannot_hold_takes_the_fallback():
    """A predicted contact run is kept where its held foot stays within the leg's reach of the hip; a run held while
    the body walks away (here the root travels 3 leg lengths over it) takes the fall-back contact, on the ankle and the
    toe of that leg only."""
    root, q = _clip(n=40)
    left, ltoe, right = (NAMES.index(n) for n in ("LeftFoot", "LeftToe", "RightFoot"))
    predicted = np.zeros((40, len(NAMES)))
    predicted[5:15, [left, ltoe]] = 1.0  # on the spot: plausible
    predicted[20:35, [right]] = 1.0
    fallback = np.full_like(predicted, 0.25)
    gp = SK.pose(root, q)[1]
    kept = plausible_contacts(SK, FEET, gp, predicted, fallback)
    assert np.array_equal(kept, predicted)  # walking on the spot: every run kept
    leg = np.linalg.norm(OFFSETS[NAMES.index("RightLeg")]) + np.linalg.norm(OFFSETS[right])
    walked = root.copy()
    walked[20:35, 0] += np.linspace(0, 3 * leg, 15)  # the body walks away during the right foot's run
    gp = SK.pose(walked, q)[1]
    out = plausible_contacts(SK, FEET, gp, predicted, fallback)
    assert np.array_equal(out[20:35, right], fallback[20:35, right])  # implausible: the fall-back
    assert np.array_equal(out[:, [left, ltoe]], predicted[:, [left, ltoe]])  # the other leg's runs untouched
    walked[20:35, 0] = root[20:35, 0] + np.linspace(0, 0.5 * PLANTED_REACH * leg, 15)  # a short step: still reachable
    out = plausible_contacts(SK, FEET, SK.pose(walked, q)[1], predicted, fallback)
    assert np.array_equal(out, predicted)


def test_a_gap_given_back_to_interpolation_takes_only_the_keys_contact():
    """Under :data:`TRUSTED_SHARE` of the network a gap's feet are what its keys say (here: the left foot held by both
    keys), not the rule on the fill (which finds every foot planted) nor the prediction; at the threshold the rule and
    the prediction decide again."""
    root, q = _clip(n=41)
    rule = FootContact(tuple(NAMES[j] for j in FEET), 1e3, 1e6)  # every foot low and slow: all planted by the rule
    feet = clip_feet(rule, SK, 30.0, root, q, [0, 20, 40])
    left = NAMES.index("LeftFoot")
    feet.held[(0, 20)][:] = False
    feet.held[(0, 20)][left] = True
    trusted = gap_contacts(SK, feet, 30.0, root, q, 0, 20)
    assert (trusted[:, FEET] == 1).all()
    back = gap_contacts(SK, feet, 30.0, root, q, 0, 20, share=0.5 * TRUSTED_SHARE)
    assert (back[:, left] == 1).all() and (np.delete(back, left, axis=1) == 0).all()
    predicted = np.ones((19, len(NAMES)))
    assert np.array_equal(gap_contacts(SK, feet, 30.0, root, q, 0, 20, predicted, share=0.0), back)
    assert np.array_equal(gap_contacts(SK, feet, 30.0, root, q, 0, 20, share=TRUSTED_SHARE), trusted)

@pytest.mark.parametrize("lock", [True, False])
def test_inbetweener_locks_feet_with_a_contact_model(tiny_contact_checkpoint, lock):
    """A model with contact channels: the Inbetweener locks by default (keys exact either way); foot_lock=False is
    the network's output.  Locking moves no root: the first gap's is the network's (later gaps take the locked gaps
    before them as their context, so theirs follow it)."""
    from inbetweening.api.inbetweener import Inbetweener

    ib = Inbetweener.from_checkpoint(tiny_contact_checkpoint)
    assert ib.foot_lock
    root, q = _clip(80, seed=4)
    keys = [0, 25, 50, 79]
    nan_r, nan_q = np.full_like(root, np.nan), np.full_like(q, np.nan)
    nan_r[keys], nan_q[keys] = root[keys], q[keys]
    r_out, q_out = ib.fill_arrays(nan_r, nan_q, keys, foot_lock=lock)
    assert np.array_equal(q_out[keys], q[keys]) and np.array_equal(r_out[keys], root[keys])
    r_free, q_free = ib.fill_arrays(nan_r, nan_q, keys, foot_lock=False)
    assert np.array_equal(r_out[:26], r_free[:26])  # the root is never changed by locking
    if not lock:
        assert np.array_equal(q_out, q_free)


def test_fill_arrays_returns_the_contacts_it_locks_on(tiny_contact_checkpoint, tiny_checkpoint):
    """``with_contacts``: the same motion plus the contact the lock read, the prediction on generated frames and the
    keys' own (an isolated key: its height under the contact height) on the keys; for a model without contact
    channels, the contact rule on its own fill (0 or 1 on the feet, 0 elsewhere)."""
    from inbetweening.api.inbetweener import Inbetweener

    ib = Inbetweener.from_checkpoint(tiny_contact_checkpoint)
    root, q = _clip(80, seed=4)
    keys = [0, 25, 50, 79]
    nan_r, nan_q = np.full_like(root, np.nan), np.full_like(q, np.nan)
    nan_r[keys], nan_q[keys] = root[keys], q[keys]
    r, lq, contact = ib.fill_arrays(nan_r, nan_q, keys, with_contacts=True)
    r0, q0 = ib.fill_arrays(nan_r, nan_q, keys)
    assert np.array_equal(r, r0) and np.array_equal(lq, q0)
    assert contact.shape == (80, len(NAMES)) and np.isfinite(contact).all()
    assert ((contact >= 0) & (contact <= 1)).all()
    feet = list(ib.predictor.contact.indices(NAMES))
    low = SK.pose(root, q)[1][keys][:, feet, 1] < ib.predictor.contact.height
    assert np.array_equal(contact[keys][:, feet], low.astype(float))
    assert ib.fill_detailed(_bvh(root, q), keyframes=keys).contact.shape == (80, len(NAMES))
    plain = Inbetweener.from_checkpoint(tiny_checkpoint)
    detected = plain.fill_arrays(nan_r, nan_q, keys, with_contacts=True)[2]
    others = [j for j in range(len(NAMES)) if j not in feet]
    assert set(np.unique(detected[:, feet])) <= {0.0, 1.0} and not detected[:, others].any()
    assert np.array_equal(detected[keys][:, feet], low.astype(float))


def _bvh(root, q):
    from inbetweening.data.synthetic import make_bvh

    return make_bvh(q, root)


def test_foot_lock_strip_draws_locked_unlocked_and_truth(tiny_contact_checkpoint, tiny_checkpoint, tmp_path):
    """benchmarks/foot_lock_strip.py's picture on a synthetic clip: three panels in its order, each titled with its foot
    skating, the ground truth's by the evaluation's own numbers; a model without contact channels locks on the
    contacts detected on its fill."""
    from conftest import benchmark_script
    from inbetweening.api.inbetweener import Inbetweener
    from inbetweening.evaluation import keyframes as KF

    strip = benchmark_script("foot_lock_strip")
    ib = Inbetweener.from_checkpoint(tiny_contact_checkpoint)
    root, q = _clip(61, seed=2)
    fig, skate = strip.draw(ib, root, q, 30, "synthetic")
    assert list(skate) == list(strip.LABELS)
    titles = [ax.get_title() for ax in fig.axes]
    assert [t.split(":")[0] for t in titles] == list(strip.LABELS)
    assert all(f"skate {skate[label]:.1f} cm/s" in t for label, t in zip(strip.LABELS, titles))
    feet = list(ib.predictor.contact.indices(NAMES))
    gp = SK.pose(root, q)[1]
    contact = foot_contacts(gp[:, feet], ib.fps, ib.predictor.contact.height, ib.predictor.contact.speed)
    contact &= KF.scored_pairs(KF.generated_frames(61, [0, 30, 60]))[:, None]
    total, count = KF.foot_skate(gp[:, feet], contact, ib.fps)
    assert skate["ground truth"] == pytest.approx(total / count if count else 0.0)
    fig.savefig(tmp_path / "strip.png")
    assert (tmp_path / "strip.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    _, plain = strip.draw(Inbetweener.from_checkpoint(tiny_checkpoint), root, q, 30, "x")
    assert plain["ground truth"] == skate["ground truth"]
