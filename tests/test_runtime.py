"""The fill runtime's own stages (:mod:`inbetweening.runtime`), each with a test that fails when that stage is wrong:
the gap plan, the canonical frame (decided by the known frames only), the blend's weights, foot locking's key
contacts, the file's frame, and the keys copied back exactly.  A recording numpy backend stands in for the network
where the stage is the runtime's; the torch backend where the network matters."""
from __future__ import annotations

import json

import numpy as np
import pytest

from inbetweening.data.contacts import FootContact
from inbetweening.data.convention import FileConvention
from inbetweening.geometry import canonical
from inbetweening.geometry.interp import interpolate_keyframes
from inbetweening.geometry.quaternion import qmul, qrot, slerp_np
from inbetweening.geometry.skeleton import Skeleton
from inbetweening.predictor.predictor import Predictor
from inbetweening.runtime import FillRuntime, InbetweenError, ModelError, ModelInfo
from inbetweening.runtime.foot_lock import key_contacts
from inbetweening.runtime.model import WINDOW_FORMAT
from inbetweening.runtime.plan import check_keys, plan_gaps
from inbetweening.runtime.torch_backend import TorchBackend, window_metadata

SK = Skeleton(("hips", "spine", "head", "thigh", "shin", "foot"), (-1, 0, 1, 0, 3, 4),
              np.array([[0, 0, 0], [0, 20, 0], [0, 25, 0], [10, -5, 0], [0, -40, 0], [0, -40, 0]], dtype=float))


def info(**kw) -> ModelInfo:
    base = {"skeleton": SK, "n_past": 4, "forward_axis": (0.0, 0.0, 1.0), "centre": "known", "trained_gap": 8,
            "hard_max_gap": 20, "fps": 30.0}
    return ModelInfo(**{**base, **kw})


class Recorder:
    """A backend that records what it is given and predicts, in the canonical frame, a fixed pose: root at
    ``(5, 90, 0)`` facing +X, every joint's rotation the identity; weights scale the distance to frame ``n_past - 1``."""

    def __init__(self, model_info: ModelInfo, contact: float | None = None):
        self.info, self.contact, self.seen = model_info, contact, []

    def predict(self, root, local_q, known, weight, contacts=True):
        self.seen.append((root.copy(), local_q.copy(), known.copy(), None if weight is None else weight.copy()))
        r = np.broadcast_to(np.array([5.0, 90.0, 0.0]), root.shape).copy()
        q = np.zeros(local_q.shape)
        q[..., 0] = 1.0
        if weight is not None:  # the blend: the interpolation (here: the last context frame) + w (prediction - it)
            last = root[:, self.info.n_past - 1 : self.info.n_past]
            r = last + weight[..., :1] * (r - last)
        c = None if self.contact is None else np.full(known.shape, self.contact)
        return r, q, c


def motion(frames=60, seed=0, yaw_rate=0.02):
    rng = np.random.default_rng(seed)
    t = np.arange(frames)
    root = np.stack([80 * np.sin(t / 25), 90 + 3 * np.sin(t / 5), 3.0 * t], -1) + rng.normal(0, 30, (1, 3))
    ang = 0.3 * np.sin(t[:, None, None] / rng.uniform(6, 15, (1, SK.num_joints, 3)))
    q = np.concatenate([np.ones((frames, SK.num_joints, 1)), ang], -1)
    q[:, 0] = np.stack([np.cos(yaw_rate * t), 0 * t, np.sin(yaw_rate * t), 0 * t], -1)
    return root, q / np.linalg.norm(q, axis=-1, keepdims=True)


# ------------------------------------------------------------------------------------------------ plan and keys
def test_plan_splits_long_gaps_into_equal_segments():
    plan = plan_gaps([0, 5, 6, 40], limit=10)
    # 6 -> 40: m = ceil(34 / 11) = 4 equal parts; no window between the neighbouring keys 5 and 6
    assert plan.segments == [(0, 5), (6, 14), (14, 23), (23, 32), (32, 40)]
    assert plan.pseudo == [(6, 40, [14, 23, 32])] and plan.pseudo_keyframes == [14, 23, 32]
    assert all(b - a - 1 <= 10 for a, b in plan.segments)
    with pytest.raises(InbetweenError, match=r"gap between keyframes 6 and 40 is 33 frames, longer than max_gap=10 "
                                             r"\(the model was trained on gaps up to 10\)"):
        plan_gaps([0, 5, 6, 40], limit=10, segment=False, trained_gap=10)


@pytest.mark.parametrize("keys, match", [([0], "at least 2"), ([0, 0, 5], "listed twice"), ([5, 2], "sorted"),
                                         ([0, 99], "out of range"), ([0, 2.5], "not an integer"), ("0,5", "list")])
def test_bad_keys_are_one_clear_error(keys, match):
    with pytest.raises(InbetweenError, match=match):
        check_keys(keys, 50)


def test_pseudo_keyframes_are_interpolated_and_generated_around():
    root, q = motion(60)
    rt = FillRuntime(Recorder(info(trained_gap=9)), foot_lock=False)  # 30 frames: 3 segments of 9 generated frames
    out = rt.fill(root, q, [0, 30])
    assert out.pseudo_keyframes == [10, 20]
    ir, iq = interpolate_keyframes(root, q, [0, 30])
    assert np.allclose(out.root[[10, 20]], ir[[10, 20]]) and np.allclose(out.local_q[[10, 20]], iq[[10, 20]])
    assert [(a, b) for a, b, _ in out.segments] == [(0, 10), (10, 20), (20, 30)]


# ------------------------------------------------------------------------------------------------ canonical frame
def test_windows_reach_the_backend_in_the_canonical_frame_of_their_known_frames():
    root, q = motion(40, seed=1)
    rec = Recorder(info())
    FillRuntime(rec, foot_lock=False).fill(root, q, [0, 10, 25, 39])
    p = rec.info.n_past
    for croot, cq, known, _ in rec.seen:
        k = known[0, :, 0]
        assert k[:p].all() and k[-1] and not k[p:-1].any()
        # the root faces +X at the last context frame (its forward axis turned about +Y), ...
        fwd = qrot(cq[0, p - 1, 0], np.array(rec.info.forward_axis))
        assert fwd[0] > 0 and abs(fwd[2]) < 1e-6  # (the facing's normalisation epsilon)
        # ... the known frames' mean root XZ is the origin, heights unchanged
        assert np.allclose(croot[0, k][:, [0, 2]].mean(0), 0.0, atol=1e-9)


def test_unknown_frames_are_never_read_and_the_fill_is_equivariant():
    root, q = motion(40, seed=2)
    keys = [0, 12, 39]
    a = FillRuntime(Recorder(info()), foot_lock=False).fill(root, q, keys)
    junk_r, junk_q = root.copy(), q.copy()
    gaps = np.setdiff1d(np.arange(40), keys)
    junk_r[gaps], junk_q[gaps] = np.nan, np.nan
    b = FillRuntime(Recorder(info()), foot_lock=False).fill(junk_r, junk_q, keys)
    assert np.array_equal(a.root, b.root) and np.array_equal(a.local_q, b.local_q)
    # a yaw and a shift of the world move the fill alike (the canonical frame takes them out)
    y = np.array([np.cos(0.4), 0.0, np.sin(0.4), 0.0])
    moved_q = q.copy()
    moved_q[:, 0] = qmul(y[None], q[:, 0])
    c = FillRuntime(Recorder(info()), foot_lock=False).fill(qrot(y[None], root) + [40.0, 0.0, -7.0], moved_q, keys)
    assert np.allclose(c.root, qrot(y[None], a.root) + [40.0, 0.0, -7.0], atol=1e-9)


def test_centre_last_puts_the_last_context_frame_at_the_origin():
    root, q = motion(30, seed=3)
    rec = Recorder(info(centre="last"))
    FillRuntime(rec, foot_lock=False).fill(root, q, [0, 12, 29])
    for croot, *_ in rec.seen:
        assert np.allclose(croot[0, rec.info.n_past - 1, [0, 2]], 0.0, atol=1e-9)


def test_context_before_the_first_key_is_read_and_frames_after_the_last_are_kept():
    root, q = motion(50, seed=4)
    rec = Recorder(info(trained_gap=12))
    out = FillRuntime(rec, foot_lock=False).fill(root, q, [10, 20, 30])
    croot, cq, _, _ = rec.seen[0]
    centre, rot = canonical.canonical_frame(root[7:22][None], q[7:22][None], rec.info.forward_axis, 3,
                                            np.isin(np.arange(7, 22), [7, 8, 9, 10, 20])[None])
    assert np.allclose(canonical.uncanonicalise(croot, cq, centre, rot)[0][0, :4], root[7:11])  # frames 7..10
    assert np.array_equal(out.root[:11], root[:11]) and np.array_equal(out.root[30:], root[30:])
    nan_r = root.copy()
    nan_r[:10] = np.nan  # no usable context: the first key's pose is repeated
    rec2 = Recorder(info(trained_gap=12))
    FillRuntime(rec2, foot_lock=False).fill(nan_r, q, [10, 20, 30])
    assert np.isfinite(rec2.seen[0][0]).all()


# ------------------------------------------------------------------------------------------------ the blend
def test_blend_weights_per_gap_length_scale_the_network_in_the_runtime():
    """Without the self-check each window keeps the calibrated weight of its gap's length; the runtime blends (the
    backend is asked for the network alone) and reports the weights."""
    root, q = motion(40, seed=5)
    rec = Recorder(info(blend=(0.0, 0.2, 0.6), trained_gap=12))
    out = FillRuntime(rec, foot_lock=False, self_check=False).fill(root, q, [0, 2, 5, 15, 39])
    gaps = [int((~known[0, :, 0]).sum()) for _, _, known, _ in rec.seen]
    assert gaps == [1, 2, 9, 11, 11]  # the last gap (23 frames) is split in two
    assert all(w is None for *_, w in rec.seen)
    assert [w for _, _, w in out.segments] == [0.0, 0.2, 0.6, 0.6, 0.6] and out.checks == []
    interp = interpolate_keyframes(root, q, [0, 2, 5, 15, 39])
    np.testing.assert_array_equal(out.root[1], interp[0][1])  # weight 0: the interpolation, exactly
    half = FillRuntime(Recorder(info(blend=(0.6,), trained_gap=12)), foot_lock=False, self_check=False)
    plain = FillRuntime(Recorder(info(trained_gap=12)), foot_lock=False, self_check=False)
    a, b, i = half.fill(root, q, [0, 9]), plain.fill(root, q, [0, 9]), interpolate_keyframes(root, q, [0, 9])
    np.testing.assert_allclose(a.root[1:9], i[0][1:9] + 0.6 * (b.root[1:9] - i[0][1:9]), atol=1e-9)


def test_the_self_check_hides_each_interior_key_and_scales_the_gaps_near_it():
    """A network that misses the hidden keys (the recording backend's fixed pose) is not trusted where it was checked:
    those gaps come back as the interpolation; a check window longer than the trained gap is not run."""
    root, q = motion(90, seed=3)
    keys = [0, 6, 12, 18, 60, 71, 82]
    rec = Recorder(info(trained_gap=12))
    out = FillRuntime(rec, foot_lock=False).fill(root, q, keys)
    assert [(c.a, c.key, c.b) for c in out.checks] == [(0, 6, 12), (6, 12, 18)]  # the others: windows too long
    assert all(c.net > 1.05 * c.interp for c in out.checks)
    known = rec.seen[0][2]  # the two checks, one backend call
    assert known.shape[0] == 2 and (~known[:, :, 0]).sum(1).tolist() == [11, 11]  # the key between is hidden
    weights = {(a, b): w for a, b, w in out.segments}
    assert weights[(0, 6)] == weights[(6, 12)] == weights[(12, 18)] == 0.0
    interp = interpolate_keyframes(root, q, keys)
    np.testing.assert_allclose(out.root[:19], interp[0][:19], atol=1e-9)
    assert weights[(71, 82)] == 1.0  # no check within reach: the calibrated weight (1 without a blend)


def test_trust_of_the_self_checks():
    from inbetweening.runtime.settings import DEFAULT_SETTINGS as S
    from inbetweening.runtime.trust import Check, checks_of, gap_weights, trust_of

    DENSE_GAP, DENSE_X_NONE, X_FULL, X_NONE = S.dense_gap, S.dense_x_none, S.x_full, S.x_none

    assert trust_of(X_FULL) == 1.0 and trust_of(X_NONE) == 0.0 and 0.0 < trust_of((X_FULL + X_NONE) / 2) < 1.0
    x = (DENSE_X_NONE + X_NONE) / 2  # short gaps are judged more strictly: no trust where a long gap keeps some
    assert trust_of(x, DENSE_GAP - 1) == 0.0 < trust_of(x, DENSE_GAP) == trust_of(x)
    short = gap_weights([(0, 4), (4, 8)], [0, 4, 8], [Check(0, 4, 8, x, 1.0)], lambda n: None)
    assert short[(0, 4)] == (0.0, x)
    assert [c.key for c in checks_of([0, 5, 10, 40, 45, 50], trained_gap=30)] == [5, 45]
    checks = [Check(0, 5, 10, 1.0, 2.0), Check(40, 45, 50, 3.0, 2.0)]
    w = gap_weights([(0, 5), (5, 10), (10, 40), (40, 45), (45, 50)], [0, 5, 10, 40, 45, 50], checks,
                    lambda n: 0.8 if n < 10 else None)
    assert w[(0, 5)] == w[(5, 10)] == (0.8, 0.5)  # the network beat interpolation well at key 5: the prior kept
    assert w[(40, 45)] == w[(45, 50)] == (0.0, 1.5)  # worse at key 45: interpolation
    assert w[(10, 40)] == (trust_of(4.0 / 4.0), 1.0)  # a long gap pools every check within reach of it


def test_checks_near_the_trained_gap_take_the_long_thresholds():
    """``long_check``: checks whose windows average over that share of the trained gap are judged by the long pair;
    shorter ones, and every check when it is 1 (the default), by the regular pair."""
    from inbetweening.runtime.settings import FillSettings
    from inbetweening.runtime.trust import Check, gap_weights, is_long, trust_of

    s = FillSettings(long_check=0.8, long_x_full=0.9, long_x_none=1.3)
    x = 1.1  # past the regular x_none (no trust), half-way in the long pair
    near = [Check(0, 30, 60, x, 1.0)]  # a 59-frame window
    assert is_long(near, 59, s) and not is_long(near, 80, s) and not is_long(near, None, s)
    assert not is_long(near, 59, FillSettings())  # off by default
    assert trust_of(x, 29, s) == 0.0 and abs(trust_of(x, 29, s, long=True) - 0.5) < 1e-12
    keys = [0, 30, 60]
    long_w = gap_weights([(0, 30), (30, 60)], keys, near, lambda n: None, s, trained_gap=59)
    short_w = gap_weights([(0, 30), (30, 60)], keys, near, lambda n: None, s, trained_gap=100)
    assert abs(long_w[(0, 30)][0] - 0.5) < 1e-12 and short_w[(0, 30)] == (0.0, x)
    with pytest.raises(InbetweenError, match="fill.long_x_full"):
        FillSettings(long_x_full=1.2, long_x_none=1.1)


class Lift:
    """A backend that predicts the interpolation with the root lifted by up to ``lift`` cm mid-gap: better than the
    interpolation at keys above it, worse below (the self-check's trust between none and full)."""

    def __init__(self, model_info: ModelInfo, lift: float = 1.0):
        self.info, self.lift = model_info, lift

    def predict(self, root, local_q, known, weight, contacts=True):
        p, t = self.info.n_past, root.shape[1]
        s = np.clip((np.arange(t) - (p - 1)) / (t - p), 0, 1)
        r = root[:, p - 1 : p] + s[None, :, None] * (root[:, -1:] - root[:, p - 1 : p])
        r[..., 1] += self.lift * 4 * s * (1 - s)
        w = np.broadcast_to(s[None, :, None], local_q.shape[:3])
        return r, slerp_np(np.broadcast_to(local_q[:, p - 1 : p], local_q.shape),
                           np.broadcast_to(local_q[:, -1:], local_q.shape), w), \
            np.ones(known.shape) if self.info.has_contacts else None


def lifted(frames=91):
    root, q = motion(frames, seed=11)
    root[:, 1] = 90 + 12 * np.sin(np.arange(frames) / 9)
    q[:, 1:] = q[0, 1:]
    return root, q


def test_a_refill_generates_the_changed_gaps_and_those_whose_weight_changed():
    """Keys every 6 frames filled; key 54 changed and its two gaps re-filled from the earlier output: the self-check
    at 48, 54 and 60 changed, so the weights of the gaps within reach of them did, left of the key too; those are
    generated, and every gap whose context was generated now.  The result is a fresh fill of the changed keys; the
    gaps before are the input bit for bit."""
    root, q = lifted()
    keys = list(range(0, 91, 6))
    rt = FillRuntime(Lift(info(trained_gap=12)), foot_lock=False)
    before = rt.fill(root, q, keys)
    assert before.generated == list(zip(keys, keys[1:]))
    assert sorted({round(w[0], 2) for w in before.shares.values()})[1:3] == [0.14, 0.16]  # trusted in part
    changed = root.copy()
    changed[54, 1] -= 6.0
    fresh = rt.fill(changed, q, keys)
    given_r, given_q = before.root.copy(), before.local_q.copy()
    given_r[54] = changed[54]
    out = rt.fill(given_r, given_q, keys, only={(48, 54), (54, 60)}, previous=before.shares)
    moved = [g for g in before.shares if abs(before.shares[g][0] - fresh.shares[g][0]) > 1e-6]
    assert moved[:4] == [(24, 30), (30, 36), (36, 42), (42, 48)]  # left of the changed key: their weight changed
    assert out.generated == [(a, a + 6) for a in range(24, 90, 6)] and out.shares == fresh.shares
    np.testing.assert_allclose(out.root, fresh.root, atol=1e-6)
    np.testing.assert_allclose(out.local_q, fresh.local_q, atol=1e-6)
    assert np.array_equal(out.root[:24], given_r[:24]) and np.array_equal(out.local_q[:24], given_q[:24])
    again = rt.fill(out.root, out.local_q, keys, only=set(), previous=out.shares)  # nothing changed: nothing generated
    assert again.generated == [] and np.array_equal(again.root, out.root)
    partial = rt.fill(out.root, out.local_q, keys, only=set(), previous={g: w for g, w in out.shares.items()
                                                                        if g != (6, 12)})
    assert partial.generated[0] == (6, 12)  # no earlier weight: generated (and the gaps it is context for)
    hole = out.root.copy()
    hole[3] = np.nan
    assert rt.fill(hole, out.local_q, keys, only=set(), previous=out.shares).generated[0] == (0, 6)
    with pytest.raises(InbetweenError, match=r"\(6, 18\) is not a gap between two consecutive keys"):
        rt.fill(out.root, out.local_q, keys, only={(6, 18)}, previous=out.shares)


def test_a_refill_locks_the_feet_over_the_span_into_the_generated_gaps_only():
    """Standing on bent legs, the fill lifting the body mid-gap: a re-fill of the last gaps locks the foot at the
    keys' place there (the contact found on the span as given), the kept frames untouched."""
    root, q = motion(49, seed=11)
    q[:] = q[10]
    foot = SK.names.index("foot")
    root[:] = (90.0, 3.0 - SK.pose(np.zeros((1, 3)), q[:1])[1][0, foot, 1], 5.0)  # the foot 3 cm above the floor
    keys = list(range(0, 49, 6))
    model = info(trained_gap=12, contact=FootContact(("foot",), 10.0, 30.0), has_contacts=True)
    rt = FillRuntime(Lift(model), self_check=False)
    before = rt.fill(root, q, keys, foot_lock=False)
    out = rt.fill(before.root, before.local_q, keys, only={(36, 42), (42, 48)}, previous=before.shares)
    assert out.locked and out.generated == [(36, 42), (42, 48)] and not np.isnan(out.contact[1:48]).any()
    assert np.array_equal(out.root[:37], before.root[:37]) and np.array_equal(out.local_q[:37], before.local_q[:37])
    assert np.abs(SK.pose(before.root, before.local_q)[1][37:48, foot, 1] - 3.0).max() > 0.5  # lifted ...
    feet = SK.pose(out.root, out.local_q)[1][:, foot]
    assert (out.contact[37:48, foot] > 0.5).all() and np.abs(feet[37:48] - feet[36]).max() < 1e-6  # ... and held


def walking_on_the_spot(frames=81, lift=0.5):
    """The foot 2 cm above the floor, the body gliding forward at 36 cm/s (faster than the contact speed, 30 cm/s)."""
    root, q = motion(frames, seed=11)
    q[:] = q[10]
    foot = SK.names.index("foot")
    y = 2.0 - SK.pose(np.zeros((1, 3)), q[:1])[1][0, foot, 1]
    root[:] = np.stack([np.full(frames, 90.0), np.full(frames, y), 1.2 * np.arange(frames)], -1)
    model = info(trained_gap=12, contact=FootContact(("foot",), 10.0, 30.0))
    return root, q, foot, FillRuntime(Lift(model, lift=lift), self_check=False)


def test_a_foot_as_low_as_at_the_keys_is_planted_in_longer_gaps():
    """Too fast for the contact rule, as low as at the keys: planted in a gap of 9 frames (the planted level), the
    lift mid-gap taken out by the lock (the foot moves straight from one key's place to the next); with keys every 6
    frames (gaps under 8) or every 25 (gaps of 20 or more) the speed rule alone decides and nothing is locked."""
    root, q, foot, rt = walking_on_the_spot()
    keys = list(range(0, 81, 10))
    free = rt.fill(root, q, keys, foot_lock=False)
    out = rt.fill(root, q, keys)
    heights = SK.pose(free.root, free.local_q)[1][:, foot, 1]
    assert heights[5] > 2.4 and (out.contact[1:80, foot] == 1).all()
    assert np.abs(SK.pose(out.root, out.local_q)[1][:81, foot, 1] - 2.0).max() < 1e-6
    short = list(range(0, 79, 6))
    dense = rt.fill(root, q, short)
    assert (dense.contact[np.setdiff1d(np.arange(78), short), foot] == 0).all()
    sparse = rt.fill(root, q, [0, 25, 50, 75])  # gaps of 24 frames: over PLANTED_MAX_GAP, the speed rule alone
    assert (sparse.contact[np.setdiff1d(np.arange(75), [0, 25, 50]), foot] == 0).all()


def test_a_refill_with_the_feet_locked_is_a_fill_of_every_gap():
    """Feet found and locked gap by gap as each gap is generated: key 40 moved and its gaps re-filled from the
    earlier (locked) output give what a fill of every gap gives, the gaps before it kept bit for bit."""
    root, q, foot, rt = walking_on_the_spot()
    keys = list(range(0, 81, 10))
    before = rt.fill(root, q, keys)
    changed = root.copy()
    changed[40, 1] -= 0.3
    fresh = rt.fill(changed, q, keys)
    given_r = before.root.copy()
    given_r[40] = changed[40]
    out = rt.fill(given_r, before.local_q, keys, only={(30, 40), (40, 50)}, previous=before.shares)
    assert out.generated == [(a, a + 10) for a in range(30, 80, 10)] and (out.contact[1:80, foot] == 1).all()
    assert np.array_equal(out.root[:31], before.root[:31]) and np.array_equal(out.local_q[:31], before.local_q[:31])
    np.testing.assert_allclose(out.local_q, fresh.local_q, atol=1e-9)
    np.testing.assert_allclose(out.root, fresh.root, atol=1e-9)
    assert np.abs(out.root[31:40] - before.root[31:40]).max() > 0.1  # the re-filled gap did change


def test_a_refill_finds_the_kept_gaps_contact_as_each_gap_alone_finds_it():
    """The kept gaps' contact of a re-fill (one FK over the span, sliced per gap) is :func:`gap_contacts` of each gap
    on its own frames: the body is 30 cm up at keys 20 and 60, so the foot leaves the floor in the gaps next to them
    and stands in the others."""
    from inbetweening.runtime.foot_lock import clip_feet, gap_contacts

    root, q, foot, rt = walking_on_the_spot(lift=0.0)
    keys = list(range(0, 81, 10))
    root[[20, 60], 1] += 30.0
    before = rt.fill(root, q, keys)
    out = rt.fill(before.root, before.local_q, keys, only={(70, 80)}, previous=before.shares)
    assert out.generated == [(70, 80)]
    feet = clip_feet(rt.info.contact, SK, rt.info.fps, out.root, out.local_q, keys)
    alone = [gap_contacts(SK, feet, rt.info.fps, out.root, out.local_q, a, b)[:, foot] for a, b in zip(keys, keys[1:7])]
    assert {float(g.mean()) for g in alone} == {0.0, 1.0}  # planted in some kept gaps, not in others
    for (a, b), g in zip(zip(keys, keys[1:7]), alone):
        assert np.array_equal(out.contact[a + 1 : b, foot], g), (a, b)



def test_a_gap_given_back_to_interpolation_is_locked_on_the_keys_contact_alone():
    """A network far from every key: the self-check gives each gap back to interpolation, and then neither its predicted
    contact (planted everywhere) nor the rule on the fill decide the feet, only what each gap's keys say; with the
    check off the same prediction plants the foot."""
    from inbetweening.runtime.foot_lock import clip_feet
    from inbetweening.runtime.settings import DEFAULT_SETTINGS

    TRUSTED_SHARE = DEFAULT_SETTINGS.trusted_share

    root, q = motion(61, seed=3)
    keys = list(range(0, 61, 10))
    model = info(trained_gap=20, hard_max_gap=40, contact=FootContact(("foot",), 10.0, 30.0), has_contacts=True)
    foot = SK.names.index("foot")
    feet = clip_feet(model.contact, SK, model.fps, root, q, keys)
    out = FillRuntime(Recorder(model, contact=1.0)).fill(root, q, keys)
    back = [g for g in zip(keys, keys[1:]) if max(out.shares[g]) < TRUSTED_SHARE]
    assert len(back) == len(keys) - 1
    for a, b in back:
        assert np.array_equal(out.contact[a + 1 : b, foot], np.full(b - a - 1, float(feet.held[(a, b)][foot])))
    assert not out.contact[1:60, foot].all()
    trusted = FillRuntime(Recorder(model, contact=1.0), self_check=False).fill(root, q, keys)
    assert min(min(w) for w in trusted.shares.values()) >= TRUSTED_SHARE and trusted.contact[1:10, foot].all()

def hparams(**kw) -> dict:
    rng = np.random.default_rng(0)
    return {"model": {"name": "interpolation"}, "skeleton": SK.to_dict(), "pos_mean": rng.normal(0, 5, 18).tolist(),
            "pos_std": rng.uniform(1, 5, 18).tolist(), "mask": "lerp", "centre": "known", "n_past": 10,
            "forward_axis": [0.0, 0.0, 1.0], "train_window": 50, **kw}


def test_a_zero_blend_gives_the_interpolation_back_through_a_real_network():
    """With the blend's weight 0 the network's correction is dropped: the fill is the keys' interpolation (root
    linearly, joints by slerp), whatever the network; with weight 1 it is the network's own output."""
    root, q = motion(50, seed=6)
    keys = [0, 17, 40, 49]
    net = {"name": "frame_transformer", "d_model": 16, "depth": 1, "heads": 2, "ffn_dim": 16, "dropout": 0.0,
           "residual_to_interpolation": False}  # (a residual network starts at the interpolation)
    state, fills = None, {}
    for name, blend in (("zero", [0.0]), ("one", [1.0]), ("none", None)):
        pr = Predictor.from_hparams(hparams(model=net, blend=blend)).eval()
        state = pr.state_dict() if state is None else state
        pr.load_state_dict(state)
        fills[name] = FillRuntime(TorchBackend(pr), foot_lock=False, self_check=False).fill(root, q, keys)
    ir, iq = interpolate_keyframes(root, q, keys)
    assert np.abs(fills["zero"].root - ir).max() < 1e-4
    assert np.abs(np.abs((fills["zero"].local_q * iq).sum(-1)) - 1).max() < 1e-6
    assert np.abs(fills["one"].root - fills["none"].root).max() < 1e-4
    assert np.abs(fills["none"].root - ir).max() > 1e-2  # the untrained network does move away from it


def test_the_interpolation_network_is_keyframe_interpolation_and_equivariant():
    p = Predictor.from_hparams(hparams()).eval()
    rt = FillRuntime(TorchBackend(p))
    root, q = motion(16, seed=7)
    r, lq, c = rt.predict_windows(root[None], q[None])  # n_past 10, 5 transition frames, target
    assert r.shape == (1, 5, 3) and lq.shape == (1, 5, SK.num_joints, 4) and c is None
    np.testing.assert_allclose(np.linalg.norm(lq, axis=-1), 1.0, atol=1e-12)
    ir, iq = interpolate_keyframes(root, q, [9, 15])
    np.testing.assert_allclose(r[0], ir[10:15], atol=1e-3)
    np.testing.assert_allclose(np.abs((lq[0] * iq[10:15]).sum(-1)), 1.0, atol=1e-5)
    y = np.array([np.cos(0.6), 0.0, np.sin(0.6), 0.0])
    moved_q = q.copy()
    moved_q[:, 0] = qmul(y[None], q[:, 0])
    r2, lq2, _ = rt.predict_windows((qrot(y[None], root) + [40.0, 0.0, -7.0])[None], moved_q[None])
    np.testing.assert_allclose(r2[0], qrot(y[None], r[0]) + [40.0, 0.0, -7.0], atol=1e-3)
    np.testing.assert_allclose(np.abs((lq2[0, :, 1:] * lq[0, :, 1:]).sum(-1)), 1.0, atol=1e-5)


# ------------------------------------------------------------------------------------------------ keys exact, frames
def test_keys_come_back_bit_for_bit_in_the_files_frame():
    root, q = motion(45, seed=8)
    q = q * 1.0000001  # not exactly unit: still copied as given
    conv = FileConvention("z", 100.0)
    file_root, file_q = conv.to_file(root, q)
    keys = [0, 9, 30, 44]
    rec = Recorder(info(convention=conv, has_contacts=True, contact=FootContact(("foot",), 5.0, 30.0)), contact=1.0)
    out = FillRuntime(rec).fill(file_root, file_q, keys, file_frame=True)
    assert np.array_equal(out.root[keys], file_root[keys]) and np.array_equal(out.local_q[keys], file_q[keys])
    assert out.locked and out.contact is not None
    # the backend saw the project's frame (Y up, cm): heights near the root's 90 cm, not the file's metres
    assert np.abs(rec.seen[0][0][..., 1]).max() > 50
    same = FillRuntime(Recorder(info(), contact=None), foot_lock=False).fill(root, q, keys)
    back = FillRuntime(Recorder(info(convention=conv)), foot_lock=False).fill(file_root, file_q, keys, file_frame=True)
    assert np.allclose(conv.to_project(back.root, back.local_q)[0], same.root, atol=1e-9)


def test_key_contacts_are_the_data_rule_on_the_keys_alone():
    root, q = motion(20, seed=9)
    root[:, 1] = 46.0  # the foot 1 cm above the floor ... (hips 46, shin and foot 80 cm below the thigh's -5)
    gp = SK.pose(root, q)[1]
    contact = FootContact(("foot",), 10.0, 30.0)
    labels = key_contacts(SK, contact, 30.0, root, q, [0, 1, 10])
    foot = SK.names.index("foot")
    assert np.isnan(labels[2:10]).all() and np.isnan(labels[11:]).all()
    assert (labels[[0, 1, 10]][:, [0, 1, 2, 3, 4]] == 0).all()
    speed01 = np.linalg.norm(gp[1, foot] - gp[0, foot]) * 30.0  # keys 0 and 1: their speed to each other
    low = gp[[0, 1, 10], foot, 1] < 10.0
    expect = [low[0] and speed01 < 30.0, low[1] and speed01 < 30.0, low[2]]  # key 10: its height alone
    assert list(labels[[0, 1, 10], foot] == expect) == [True] * 3


def test_max_gap_and_batch_size_are_checked():
    rt = FillRuntime(Recorder(info()))
    assert rt.max_gap == 8
    with pytest.raises(InbetweenError, match="max_gap=21 exceeds what the network supports"):
        FillRuntime(Recorder(info()), max_gap=21)
    with pytest.raises(InbetweenError, match="batch_size must be a positive integer"):
        FillRuntime(Recorder(info()), batch_size=0)
    root, q = motion(20)
    with pytest.raises(InbetweenError, match=r"local_q \(F, 6, 4\)"):
        rt.fill(root, q[:, :3], [0, 19])
    bad = root.copy()
    bad[19] = np.nan
    with pytest.raises(InbetweenError, match="NaN"):
        rt.fill(bad, q, [0, 19])


def test_model_info_from_the_torch_backends_metadata():
    p = Predictor.from_hparams(hparams(blend=[0.1, 0.5], contact={"feet": ["foot"], "height": 5.0, "speed": 20.0},
                                       convention={"up_axis": "z", "unit_cm": 2.54}))
    meta = {k: json.loads(v) for k, v in window_metadata(p, trained_gap=30).items()}
    assert meta["format"] == WINDOW_FORMAT and meta["inputs"] == ["root", "local_q", "known", "weight"]
    m = ModelInfo.from_metadata(meta)
    assert (m.n_past, m.trained_gap, m.blend, m.centre) == (10, 30, (0.1, 0.5), "known")
    assert m.contact.feet == ("foot",) and m.convention.unit_cm == 2.54 and not m.has_contacts
    assert m.skeleton == SK and m.blend_weight(1) == 0.1 and m.blend_weight(7) == 0.5
    assert ModelInfo.from_metadata({**meta, "trained_gap": 99}).trained_gap == 39  # at most train_window - n_past - 1
    with pytest.raises(ModelError, match="older in-betweening window model"):
        ModelInfo.from_metadata({**meta, "format": "inbetweening-window-onnx/1"}, "x.onnx")
    with pytest.raises(ModelError, match="not an in-betweening window model"):
        ModelInfo.from_metadata({"format": "inbetweening-onnx/1"}, "x.onnx")
