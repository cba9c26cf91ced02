"""The DCC core (:mod:`inbetweening.dcc`) without any host application: the animator's whole loop through a fake host
(tests/dcc_host.py: keys per bone and frame as numpy arrays) and a real model filling through the runtime.

Keys -> fill -> the animator edits a filled frame by hand and moves a key -> re-fill: every key and the hand edit stay
bit for bit, only the gaps the change reaches are re-filled (those before stay bit for bit) and the re-fill is a fill
of every gap up to the float32 rounding of the curves; partial keys (some bones keyed at a frame); Discard Edits; a
rig that cannot be mapped, or cannot be filled, is one clear error and nothing changes.  On a humanoid of other names
and proportions (the bone map and retargeting) and on the model's own skeleton (the fill on its poses directly)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from characters import character, model_walk
from dcc_host import MemoryCurves, MemoryHumanoid, MemoryModelRig, key_motion, location, rotation
from inbetweening.dcc import RigError, fill_action
from inbetweening.dcc.record import decode
from inbetweening.dcc.report import summary_lines
from inbetweening.runtime.bone_map import BoneMapError
from inbetweening.runtime.torch_backend import TorchBackend

MODEL = Path(__file__).resolve().parents[1] / "models" / "bn2_partial" / "model.ckpt"  # trained for partial keys
EDIT = rotation("upperarm_l", 1)  # the channel the animator edits by hand


@pytest.fixture(scope="module")
def backend():
    return TorchBackend.from_checkpoint(MODEL)


@pytest.fixture(scope="module")
def human(backend):
    """A walk of a character (tests/characters.py: UE names, a twist bone, fingers, a second spine bone, a motionless
    ``root`` above the hips, metres, Z up): ``(names, parents, offsets, local_q, locations, hips)``."""
    bvh, slots = character(backend.info.skeleton, *model_walk(backend.info.skeleton, frames=91))
    names, offsets = list(bvh.names), np.asarray(bvh.offsets, float)
    return (names, [int(p) for p in bvh.parents], offsets, bvh.local_rotations(),
            bvh.channel_positions() - offsets[None], names.index(slots["Hips"]))


def humanoid(backend, human, keys, bones=None, curves=None):
    """The character keyed at ``keys`` (on ``bones``, default every bone) in a fresh :class:`MemoryCurves`, and its
    rig."""
    names, parents, offsets, lq, loc, hips = human
    curves = curves or MemoryCurves()
    key_motion(curves, names, lq, keys, movers=[hips], locations=loc, bones=bones)
    return curves, MemoryHumanoid(curves, backend.info, names, parents, offsets)


def animators(curves: dict) -> dict:
    """Every key of the animator: ``{(channel, frame): value}``."""
    return {(ch, float(f)): float(v) for ch, c in curves.items()
            for f, v, g in zip(c["frames"], c["values"], c["generated"]) if not g}


def same_up_to(a: dict, b: dict, frame: float) -> bool:
    """Whether two curve sets agree bit for bit on every key up to ``frame`` (frames, values, tags)."""
    if a.keys() != b.keys():
        return False
    for ch in a:
        ma, mb = a[ch]["frames"] <= frame, b[ch]["frames"] <= frame
        if not all(np.array_equal(a[ch][k][ma], b[ch][k][mb]) for k in ("frames", "values", "generated")):
            return False
    return True


def equal(a: dict, b: dict) -> bool:
    return same_up_to(a, b, np.inf)


def test_the_animators_loop_on_a_humanoid(backend, human):
    keys = list(range(0, 91, 15))
    curves, rig = humanoid(backend, human, keys)
    before = curves.copy()
    first = fill_action(rig, backend, 0, 90, self_check=False)
    assert (first["gaps"], first["kept"], first["keys"], first["partial_keys"]) == (6, 0, 7, 0)
    assert first["humanoid"] and first["movers"] == ["pelvis"] and first["bone_map"]["Chest"] == "spine_03"
    written = {(p, i) for _, p, i in rig.channels()}
    assert {curves.bone(c) for c in written} == set(first["keyed_bones"]) and "spine_02" in first["keyed_bones"]
    assert all(curves.curves[c]["frames"].tolist() == list(range(91)) for c in written)  # every in-between keyed
    assert animators(curves.curves) == animators(before)  # the keys, bit for bit
    untouched = [c for c in before if c not in written]  # fingers, twist bones, the root: their own curves
    assert untouched and all(equal({c: curves.curves[c]}, {c: before[c]}) for c in untouched)
    filled = curves.copy()

    again = fill_action(rig, backend, 0, 90, self_check=False)
    assert (again["gaps"], again["kept"]) == (0, 6) and equal(curves.curves, filled)  # nothing changed: nothing written

    # the animator edits a generated key of the left upper arm by hand and moves the key at 45 to 48
    value, generated = curves.at(EDIT, 80)
    assert generated
    edited = float(np.float32(value + 0.05))
    curves.key(EDIT, 80, edited, generated=True)
    curves.move(45, 48)
    edits = curves.copy()
    refill = fill_action(rig, backend, 0, 90, self_check=False)
    assert refill["refilled"] == [[30, 48], [48, 60], [60, 75], [75, 90]] and refill["kept"] == 2
    assert refill["edits"] == 1 and refill["partial_keys"] == 1  # the edit keys one bone at 80: a partial key
    assert curves.at(EDIT, 80) == (edited, False)  # kept exactly, the animator's now
    mine = animators(edits)
    assert {k: v for k, v in animators(curves.curves).items() if k in mine} == mine  # every key, bit for bit
    assert same_up_to(curves.curves, filled, 30) and not same_up_to(curves.curves, filled, 90)
    lines = [text for text, _ in summary_lines(decode(curves.record)[0])]
    assert lines[:3] == ["Last fill: 4 gap(s) filled, 2 kept", "1 hand edit(s) kept as keys",
                         "1 partial key(s): some bones keyed"]
    assert lines[3].startswith("0–15: network ") and lines[3].endswith("(kept)") and "(kept)" not in lines[-1]
    refilled = curves.copy()
    assert fill_action(rig, backend, 0, 90, self_check=False)["gaps"] == 0 and equal(curves.curves, refilled)

    # the re-fill is a fill of every gap with the same keys (the record dropped), up to the float32 curves read back
    fresh = MemoryCurves()
    fresh.curves = curves.copy()
    full = fill_action(MemoryHumanoid(fresh, backend.info, *human[:3]), backend, 0, 90, self_check=False)
    assert full["gaps"] == 6 and fresh.at(EDIT, 80) == (edited, False)
    diff = max(float(np.abs(fresh.curves[c]["values"] - refilled[c]["values"]).max()) for c in written)
    assert all(np.array_equal(fresh.curves[c]["frames"], refilled[c]["frames"]) for c in written) and diff < 1e-3

    # Discard Edits: every gap re-filled, the edit given back to the fill
    discard = fill_action(rig, backend, 0, 90, self_check=False, discard_edits=True)
    assert (discard["gaps"], discard["kept"], discard["partial_keys"]) == (6, 0, 0)
    value, generated = curves.at(EDIT, 80)
    assert generated and value != edited
    assert {k: v for k, v in animators(curves.curves).items() if k in mine and k != (EDIT, 80.0)} == \
        {k: v for k, v in mine.items() if k != (EDIT, 80.0)}


def test_a_refill_with_nothing_changed_builds_no_retargeting(backend, human, monkeypatch):
    """The bones a fill writes come from the skeletons and the map alone, so "nothing changed" is known without the
    retargeting (its construction is a sixth of a Blender re-fill); a changed key builds it again."""
    import inbetweening.dcc.mapped as mapped

    curves, rig = humanoid(backend, human, list(range(0, 91, 30)))
    fill_action(rig, backend, 0, 90, self_check=False)
    built = []

    class Counted(mapped.Retarget):
        def __init__(self, *a, **kw):
            built.append(1)
            super().__init__(*a, **kw)

    monkeypatch.setattr(mapped, "Retarget", Counted)
    filled = curves.copy()
    again = fill_action(rig, backend, 0, 90, self_check=False)
    assert (again["gaps"], again["kept"], built) == (0, 3, []) and equal(curves.curves, filled)
    hips = rotation(human[0][human[5]], 1)
    curves.key(hips, 30, float(np.float32(curves.at(hips, 30)[0] + 0.02)))  # the animator turns the hips at 30
    changed = fill_action(rig, backend, 0, 90, self_check=False)
    assert changed["refilled"][:2] == [[0, 30], [30, 60]] and built == [1]


def test_partial_keys_on_a_humanoid(backend, human):
    """Keys every 30 frames and the left arm alone keyed at 75: a partial key (no gap boundary), the arm's keys kept,
    the frame's other bones generated; changing the arm's key re-fills its gap only."""
    names, parents, offsets, lq, loc, hips = human
    arm = ("upperarm_l", "lowerarm_l", "hand_l")
    curves, rig = humanoid(backend, human, [0, 30, 60, 90])
    raised = lq.copy()
    raised[75, names.index("upperarm_l"), 1] += 0.3  # the animator raises the arm at 75 and keys the arm alone
    key_motion(curves, names, raised / np.linalg.norm(raised, axis=-1, keepdims=True), [75], bones=arm)
    keyed = curves.copy()
    first = fill_action(rig, backend, 0, 90)
    assert (first["gaps"], first["partial_keys"], first["refilled"]) == (3, 1, [[0, 30], [30, 60], [60, 90]])
    assert animators(curves.curves) == animators(keyed)
    assert curves.at(rotation("spine_01", 2), 75)[1] and curves.at(location("pelvis", 0), 75)[1]  # generated there
    assert all(not curves.at(rotation(b, i), 75)[1] for b in arm for i in range(4))
    filled = curves.copy()
    assert fill_action(rig, backend, 0, 90)["gaps"] == 0 and equal(curves.curves, filled)

    value, _ = curves.at(rotation("lowerarm_l", 2), 75)
    curves.key(rotation("lowerarm_l", 2), 75, value + 0.2)  # the animator changes the partial key
    changed = curves.copy()
    refill = fill_action(rig, backend, 0, 90)
    assert refill["refilled"] == [[60, 90]] and refill["partial_keys"] == 1
    assert animators(curves.curves) == animators(changed) and same_up_to(curves.curves, filled, 60)
    assert not same_up_to(curves.curves, filled, 90)


def test_a_rig_that_cannot_be_mapped_or_filled_is_one_clear_error_and_nothing_changes(backend, human):
    curves = MemoryCurves()
    chain = np.array([[0.0, 0.0, 0.0]] + [[0.0, 10.0, 0.0]] * 4)
    key_motion(curves, list("abcde"), np.tile([1.0, 0.0, 0.0, 0.0], (31, 5, 1)), [0, 30])
    before = curves.copy()
    with pytest.raises(BoneMapError) as e:  # no humanoid: the front end's rig is refused before anything is read
        MemoryHumanoid(curves, backend.info, list("abcde"), [-1, 0, 1, 2, 3], chain)
    assert str(e.value).startswith("the rig 'memory' is not a humanoid the model can fill: no bone found for Hips")
    assert "\n" not in str(e.value) and equal(curves.curves, before) and curves.record is None
    with pytest.raises(BoneMapError, match="no_such_bone"):  # an override naming a bone the rig does not have
        MemoryHumanoid(MemoryCurves(), backend.info, *human[:3], override={"no_such_bone": "Head"})

    curves, rig = humanoid(backend, human, [30])
    before = curves.copy()
    for kw, message in (({}, "nothing to fill: frames 0..90 hold 1 key(s) and no gap between two keys"),
                        ({"only_selected": True},
                         "only selected range: no keys are selected and there is no preview range")):
        with pytest.raises(RigError) as e:
            fill_action(rig, backend, 0, 90, **kw)
        assert str(e.value) == message and equal(curves.curves, before) and curves.record is None


@pytest.fixture(scope="module")
def small_model():
    """A model of the six-joint skeleton of tests/test_runtime.py (not the humanoid slots): a real network, untrained."""
    from inbetweening.predictor.predictor import Predictor
    from test_runtime import hparams

    net = {"name": "frame_transformer", "d_model": 16, "depth": 1, "heads": 2, "ffn_dim": 16, "dropout": 0.0}
    return TorchBackend(Predictor.from_hparams(hparams(model=net)).eval())


def test_the_animators_loop_on_the_models_own_skeleton(small_model):
    """A rig of the model's own joints fills on its poses directly (no bone map): the keys and a hand edit kept, only
    the gaps from the edit on re-filled."""
    from test_runtime import motion

    root, q = motion(61, seed=3)
    curves = MemoryCurves()
    rig = MemoryModelRig(curves, small_model.info)
    key_motion(curves, rig.names, q, range(0, 61, 10), movers=[0], locations=root[:, None].repeat(6, 1))
    keyed = curves.copy()
    first = fill_action(rig, small_model, 0, 60, foot_lock=False, self_check=False)
    assert (first["gaps"], first["humanoid"]) == (6, False) and animators(curves.curves) == animators(keyed)
    assert all(c["frames"].tolist() == list(range(61)) for c in curves.curves.values())
    filled = curves.copy()
    chan = rotation("spine", 2)
    edited = float(np.float32(curves.at(chan, 35)[0] - 0.1))
    curves.key(chan, 35, edited, generated=True)
    refill = fill_action(rig, small_model, 0, 60, foot_lock=False, self_check=False)
    assert refill["edits"] == 1 and refill["refilled"][0] == [30, 40] and curves.at(chan, 35) == (edited, False)
    assert same_up_to(curves.curves, filled, 30) and animators(curves.curves) == {**animators(keyed), (chan, 35.0): edited}
