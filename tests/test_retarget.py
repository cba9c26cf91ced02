"""Retargeting (:mod:`inbetweening.runtime.retarget`) and the runtime's rig fill (:meth:`FillRuntime.fill_rig`) on
characters generated from the model's own motion (tests/characters.py): other names, proportions, A-pose rests,
extra bones, metres and Z up.  The generated rig moves exactly as the model does, so carrying it onto the model's
skeleton must give the model's motion back."""
from __future__ import annotations

import types
from pathlib import Path

import numpy as np
import pytest

from characters import character, model_walk
from inbetweening.geometry.interp import interpolate_keyframes
from inbetweening.geometry.quaternion import qrot
from inbetweening.runtime import FillRuntime, InbetweenError
from inbetweening.runtime.retarget import Retarget
from inbetweening.runtime.torch_backend import TorchBackend

MODEL = Path(__file__).resolve().parents[1] / "models" / "bn2_reference" / "model.ckpt"
VARIANTS = {
    "renamed": dict(extras=False, z_up=False, unit=1.0),
    "metres_z_up": dict(extras=False),
    "extra_bones": dict(),
    "a_pose": dict(a_pose=40.0),
    "proportions": dict(a_pose=30.0, scale={"legs": 1.15, "Spine": 0.85, "Chest": 1.1, "UpperArm_L": 1.15,
                                            "UpperArm_R": 1.15, "LowerArm_L": 0.9, "LowerArm_R": 0.9, "Neck": 1.15}),
}


@pytest.fixture(scope="module")
def backend():
    return TorchBackend.from_checkpoint(MODEL)


@pytest.fixture(scope="module")
def motion(backend):
    """A walk of the model's skeleton: the root turning, the legs and arms swinging."""
    return model_walk(backend.info.skeleton)


def _local(g, parents, j):
    from inbetweening.geometry.quaternion import qinv, qmul

    return qmul(qinv(g[parents[j]]), g[j])


def _carried(sk, motion, name):
    """The motion played by the character ``name``: ``(rig, its local_q, local_p, the Retarget (its natural pose the
    mean of every 15th frame), the motion carried back onto the model's skeleton (root, local_q))``."""
    rig, slots = character(sk, *motion, **VARIANTS[name])
    lq, lp = rig.local_rotations(), rig.channel_positions()
    rt = Retarget(rig.skeleton(), sk, types.SimpleNamespace(slots=slots), reference=lq[0], poses=lq[::15])
    return rig, lq, lp, rt, rt.to_model(lq, lp)


def _heading_free(a: np.ndarray, b: np.ndarray) -> float:
    """The largest distance between positions ``a`` and ``b`` (``(..., 3)``, Y up) once ``a`` is turned about the up
    axis onto ``b`` (least squares): two worlds whose characters face other ways fill alike (the window is turned to
    its own heading)."""
    xa, xb = a[..., [0, 2]].reshape(-1, 2), b[..., [0, 2]].reshape(-1, 2)
    u, _, vt = np.linalg.svd(xa.T @ xb)
    turned = a.copy()
    turned[..., [0, 2]] = (xa @ (u @ vt)).reshape(a[..., [0, 2]].shape)
    return float(np.abs(turned - b).max())


@pytest.mark.parametrize("name", list(VARIANTS))
def test_a_character_carries_the_models_motion_exactly(backend, motion, name):
    """model skeleton -> character -> model skeleton: the joints' positions within 1e-4 of the body's height."""
    sk = backend.info.skeleton
    root, q = motion
    _, _, _, rt, (r2, q2) = _carried(sk, motion, name)
    gp, gp2 = sk.pose(root, q)[1], sk.pose(r2, q2)[1]
    height = np.ptp(gp[..., 1], axis=-1).max()
    assert _heading_free(gp2, gp) <= 1e-4 * height, _heading_free(gp2, gp)
    unit = VARIANTS[name].get("unit", 0.01)
    legs = VARIANTS[name].get("scale", {}).get("legs", 1.0)
    assert rt.scale == pytest.approx(1.0 / (unit * legs), rel=1e-4)  # the hips' height sets the root's scale


@pytest.mark.parametrize("name", ["renamed", "extra_bones", "proportions"])
def test_back_onto_the_character_and_again_is_the_same_motion(backend, motion, name):
    """to_rig then to_model: the model's motion again (the rig's mapped bones carry all of it)."""
    sk = backend.info.skeleton
    rig, lq, lp, rt, (r2, q2) = _carried(sk, motion, name)
    lq3, lp3 = rt.to_rig(r2, q2, lq, lp, movers=list(range(rig.num_joints)))
    r4, q4 = rt.to_model(lq3, lp3)
    assert np.abs(sk.pose(r4, q4)[1] - sk.pose(r2, q2)[1]).max() < 1e-4  # cm
    free = [i for i, b in enumerate(rig.names) if "finger" in b or "twist" in b]
    assert np.allclose(np.abs((lq3[:, free] * lq[:, free]).sum(-1)), 1.0)  # bones without a slot keep their values


def _ratio(sk, filled, truth, keys) -> float:
    """The fill's mean joint error over the generated frames of ``truth`` (root, local_q), over interpolation's."""
    n = keys[-1] + 1
    gen = np.setdiff1d(np.arange(n), keys)
    ir, iq = interpolate_keyframes(truth[0][:n], truth[1][:n], keys)
    t, p, i = (sk.pose(r[:n], q[:n])[1][gen] for r, q in (truth, filled, (ir, iq)))
    return float(np.linalg.norm(p - t, axis=-1).mean() / np.linalg.norm(i - t, axis=-1).mean())


def test_the_fill_on_a_character_is_as_good_as_on_the_models_skeleton(backend, motion):
    """Keys every 15 frames of a character: the rig's keys exactly as given, the fill (carried back onto the model's
    skeleton) as good as the native fill of the same keys (ratio to interpolation within 0.02), bones without a slot
    interpolated.  (Not the same numbers: the character faces another way in its world, and the network reads its
    windows' quaternions as numbers.)"""
    sk = backend.info.skeleton
    root, q = motion
    keys = list(range(0, 121, 15))
    runtime = FillRuntime(backend)
    native = runtime.fill(root, q, keys)
    rig, slots = character(sk, root, q, **VARIANTS["proportions"])
    lq, lp = rig.local_rotations(), rig.channel_positions()
    hidden_q, hidden_p = lq.copy(), lp.copy()
    gen = np.setdiff1d(np.arange(121), keys)
    hidden_q[gen], hidden_p[gen] = np.nan, np.nan  # nothing between the keys is read
    rt = Retarget(rig.skeleton(), sk, types.SimpleNamespace(slots=slots), reference=lq[0], poses=lq[keys])
    out = runtime.fill_rig(rt, hidden_q, hidden_p, keys, movers=list(range(rig.num_joints)))
    assert np.array_equal(out.local_q[keys], lq[keys]) and np.array_equal(out.local_p[keys], lp[keys])
    assert np.isfinite(out.local_q).all() and np.isfinite(out.local_p).all()
    filled = rt.to_model(out.local_q, out.local_p)
    truth = rt.to_model(lq, lp)
    assert _ratio(sk, filled, truth, keys) <= _ratio(sk, (native.root, native.local_q), (root, q), keys) + 0.02
    finger = rig.names.index("hand_l_finger0_02")
    _, iq = interpolate_keyframes(np.zeros((121, 3)), lq, keys)
    assert np.allclose(np.abs((out.local_q[:, finger] * iq[:, finger]).sum(-1)), 1.0)


def test_a_refill_of_a_character_keeps_its_other_gaps_exactly(backend, motion):
    """A re-fill in the rig's frames (``only``/``previous`` of :meth:`FillRuntime.fill`): the gaps before the named
    ones are the input bit for bit, the named ones and those after them (their context) are the fill of every gap."""
    sk = backend.info.skeleton
    root, q = motion
    keys = list(range(0, 121, 15))
    rig, slots = character(sk, root, q, **VARIANTS["renamed"])
    lq, lp = rig.local_rotations(), rig.channel_positions()
    rt = Retarget(rig.skeleton(), sk, types.SimpleNamespace(slots=slots), reference=lq[0])
    runtime = FillRuntime(backend, foot_lock=False)
    full = runtime.fill_rig(rt, lq, lp, keys, movers=[0])
    assert full.generated == list(zip(keys, keys[1:])) and set(full.shares) == set(full.generated)
    out = runtime.fill_rig(rt, full.local_q, full.local_p, keys, movers=[0], only={(75, 90)}, previous=full.shares)
    assert out.generated == [(75, 90), (90, 105), (105, 120)] and out.shares == full.shares
    assert np.array_equal(out.local_q[:76], full.local_q[:76]) and np.array_equal(out.local_p[:76], full.local_p[:76])
    assert np.abs(out.local_q - full.local_q).max() < 1e-5 and np.abs(out.local_p - full.local_p).max() < 1e-5


def test_a_faster_rig_is_filled_at_the_models_rate(backend, motion):
    """A 120 fps rig (every frame of the motion 4 times, interpolated): keys 60 frames apart are 15 of the model's;
    the fill, taken at the model's frames, is as good as the native fill of those keys (ratio within 0.02)."""
    sk = backend.info.skeleton
    root, q = motion
    keys = list(range(0, 121, 15))
    native = FillRuntime(backend).fill(root, q, keys)
    rig, slots = character(sk, root, q, extras=False, z_up=False, unit=1.0)
    lq, lp = rig.local_rotations(), rig.channel_positions()
    fast = np.repeat(np.arange(121), 4)[:481]  # frame k of the fast rig is frame k/4 of the motion (keys exact)
    rt = Retarget(rig.skeleton(), sk, types.SimpleNamespace(slots=slots), reference=lq[0], poses=lq[keys])
    out = FillRuntime(backend).fill_rig(rt, lq[fast], lp[fast], [4 * k for k in keys], movers=[0], fps=120.0)
    filled = rt.to_model(out.local_q[::4], out.local_p[::4])
    truth = rt.to_model(lq, lp)
    assert _ratio(sk, filled, truth, keys) <= _ratio(sk, (native.root, native.local_q), (root, q), keys) + 0.02


def test_rig_fill_errors(backend, motion):
    sk = backend.info.skeleton
    root, q = motion
    rig, slots = character(sk, root, q, **VARIANTS["renamed"])
    lq, lp = rig.local_rotations(), rig.channel_positions()
    rt = Retarget(rig.skeleton(), sk, types.SimpleNamespace(slots=slots))
    runtime = FillRuntime(backend)
    with pytest.raises(InbetweenError, match=r"expected local_q \(F, 21, 4\)"):
        runtime.fill_rig(rt, lq[:, :5], lp, [0, 30])
    bad = lq.copy()
    bad[30] = np.nan
    with pytest.raises(InbetweenError, match="NaN"):
        runtime.fill_rig(rt, bad, lp, [0, 30])


def test_a_static_top_bone_that_turns_the_character_is_part_of_its_world(backend, motion):
    """extra_bones: a motionless ``root`` bone above the hips carries the Z-up turn (the rest pose itself is Y up);
    with the key's pose as the reference, the character still stands upright on the model's side."""
    sk = backend.info.skeleton
    root, q = motion
    rig, slots = character(sk, root, q, **VARIANTS["extra_bones"])
    lq, lp = rig.local_rotations(), rig.channel_positions()
    upright = Retarget(rig.skeleton(), sk, types.SimpleNamespace(slots=slots), reference=lq[0]).to_model(lq, lp)
    assert _heading_free(sk.pose(*upright)[1], sk.pose(root, q)[1]) < 1e-3
    rest = Retarget(rig.skeleton(), sk, types.SimpleNamespace(slots=slots)).to_model(lq, lp)  # the rest pose alone
    head = sk.names.index("Head")
    up = sk.pose(*rest)[1][:, head] - sk.pose(*rest)[1][:, 0]
    assert np.abs(up[:, 1]).mean() < 0.5 * np.linalg.norm(up, axis=-1).mean()  # lying down: why the key is used


def test_a_rig_whose_scale_cannot_be_found_is_refused(backend, motion):
    """A rig whose legs have no length (the ankles at the hips' height): one line naming it, before anything."""
    sk = backend.info.skeleton
    rig, slots = character(sk, *motion, **VARIANTS["renamed"])
    flat = rig.skeleton()
    offsets = flat.offsets.copy()
    for s in ("LowerLeg_L", "Foot_L", "LowerLeg_R", "Foot_R"):
        offsets[flat.names.index(slots[s])] = 0.0
    for s, side in (("UpperLeg_L", 1.0), ("UpperLeg_R", -1.0)):
        offsets[flat.names.index(slots[s])] = [10.0 * side, 0.0, 0.0]
    from inbetweening.geometry.skeleton import Skeleton

    broken = Skeleton(flat.names, flat.parents, offsets)
    with pytest.raises(InbetweenError, match=r"rig 'x.bvh': its scale cannot be found: in its T-pose the hips are not"):
        Retarget(broken, sk, types.SimpleNamespace(slots=slots), where="rig 'x.bvh'")


@pytest.mark.parametrize(("axis", "degrees", "given"), [([1.0, 0.0, 0.0], -90.0, False), ([0.0, 1.0, 0.0], 37.0, False),
                                                      ([0.0, 0.0, 1.0], 180.0, False), ([0.3, 0.5, 0.8], 30.0, True),
                                                      ([0.0, 0.6, 0.8], 75.0, True)])
def test_the_rigs_world_orientation_does_not_matter(backend, motion, axis, degrees, given):
    """The model's own skeleton as a rig (its degenerate zero pose as the rest: legs along the spine, which no longer
    decides where up is) turned as a whole (offsets turned, every rotation conjugated, as Blender's Z-up import does):
    carried onto the model, it is the model's motion itself, within 1e-6 cm of the truth (a turn about the up axis
    left: it is turned back on the way out).  A world turned off the axes needs its up given (a host knows it)."""
    from inbetweening.geometry.quaternion import qinv, qmul

    sk = backend.info.skeleton
    root, q = motion
    half = np.radians(degrees) / 2
    w = np.concatenate([[np.cos(half)], np.sin(half) * np.asarray(axis) / np.linalg.norm(axis)])
    slots = types.SimpleNamespace(slots={n: n for n in sk.names})
    turned = type(sk)(sk.names, sk.parents, qrot(np.broadcast_to(w, sk.offsets.shape[:-1] + (4,)), sk.offsets))
    lp = np.repeat(sk.offsets[None], len(root), 0)
    lp[:, 0] = root
    lq_t = qmul(qmul(w, q), qinv(w))
    lp_t = qrot(np.broadcast_to(w, lp.shape[:-1] + (4,)), lp)
    up = qrot(w, np.array([0.0, 1.0, 0.0])) if given else None
    rt = Retarget(turned, sk, slots, reference=lq_t[0], up=up)
    b = rt.to_model(lq_t, lp_t)
    truth = sk.pose(root, q)[1]
    turn = np.broadcast_to(rt.world, truth.shape[:-1] + (4,))  # rig world -> model world: a turn about Y at most
    assert np.abs(qrot(turn, qrot(np.broadcast_to(w, truth.shape[:-1] + (4,)), truth)) - sk.pose(*b)[1]).max() < 1e-6
    assert abs(abs(qmul(rt.world, w)[0]) - 1.0) < 1e-9 or abs(qrot(qmul(rt.world, w), np.array([0.0, 1.0, 0.0]))[1] - 1) < 1e-9


def test_the_models_side_is_built_once_and_never_changed(backend, motion):
    """The model's side of a ``Retarget`` (its T-pose, basis, rest) is built once per model and natural pose: a
    ``Retarget`` built after others, with another model pose between them, carries the motion exactly as one built
    with the cache emptied, and the shared arrays cannot be written to."""
    from inbetweening.runtime.retarget import ModelSide

    sk = backend.info.skeleton
    rig, slots = character(sk, *motion, **VARIANTS["proportions"])
    lq, lp = rig.local_rotations(), rig.channel_positions()

    def build(**kw):
        return Retarget(rig.skeleton(), sk, types.SimpleNamespace(slots=slots), reference=lq[0], poses=lq[::15], **kw)

    ModelSide._cache.clear()
    fresh = build().to_model(lq, lp)
    identity = np.tile([1.0, 0.0, 0.0, 0.0], (sk.num_joints, 1))
    other = build(model_pose=identity).to_model(lq, lp)  # another natural pose: another side, another result
    assert len(ModelSide._cache) == 2 and not np.allclose(other[1], fresh[1])
    assert identity.flags.writeable  # the caller's pose is copied, not frozen
    again = build()
    for a, b in zip(again.to_model(lq, lp), fresh):
        np.testing.assert_array_equal(a, b)
    assert not again.t_model.flags.writeable
    with pytest.raises(ValueError):
        again.t_model[0, 0] = 2.0
