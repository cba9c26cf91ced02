"""One fill path for every character, proven on real Bandai-Namco-2 clips rewritten by a writer that is not the
project's (tests/bvh_variants.py: its own parser, FK and writer, SciPy's rotations): a copy that only renames the
joints, changes the Euler order, the channels, the unit, the up axis or adds bones fills exactly as the original (at
most 0.01 cm on every joint it shares); another rest pose, missing toes or hands, other proportions fill about as well
as the original, each against interpolation on its own joints.  Skipped without the dataset."""
from __future__ import annotations

import tempfile
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation as R

import bvh_variants as V
from inbetweening.api.inbetweener import Inbetweener
from inbetweening.data.bvh_writer import write_bvh

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "datasets" / "bandai-namco-2.zip"
MODEL = ROOT / "models" / "bn2_reference" / "model.ckpt"
CLIP = "Bandai-Namco-Research-Motiondataset-2/data/dataset-2_walk_normal_010.bvh"  # a standard-split test clip
FRAMES = 121
UE = {"joint_Root": "root", "Hips": "pelvis", "Spine": "spine_01", "Chest": "spine_02", "Neck": "neck_01", "Head": "head",
      **{f"{b}_{s}": f"{ue}_{s.lower()}" for s in "LR" for b, ue in (
          ("Shoulder", "clavicle"), ("UpperArm", "upperarm"), ("LowerArm", "lowerarm"), ("Hand", "hand"),
          ("UpperLeg", "thigh"), ("LowerLeg", "calf"), ("Foot", "foot"), ("Toes", "ball"))}}
SCHEDULES = {"every 5": list(range(0, FRAMES, 5)), "every 15": list(range(0, FRAMES, 15)),
             "every 30": list(range(0, FRAMES, 30)),
             "random": sorted({0, FRAMES - 1, *np.random.default_rng(3).choice(np.arange(1, FRAMES - 1), 6, replace=False)})}
TOL = 0.01  # cm

pytestmark = pytest.mark.skipif(not DATA.exists(), reason="Bandai-Namco-2 is not beside the checkout")


@pytest.fixture(scope="module")
def ib():
    return Inbetweener.from_checkpoint(MODEL)


@pytest.fixture(scope="module")
def clip() -> V.Clip:
    with zipfile.ZipFile(DATA) as z, tempfile.TemporaryDirectory() as d:
        path = Path(d) / "walk.bvh"
        path.write_bytes(z.read(CLIP))
        return V.trim(V.read(path), 0, FRAMES)


def filled(ib, c: V.Clip, keys, **write) -> np.ndarray:
    """World positions ``(F, J, 3)`` of the fill of ``c`` (written with ``write``), read back by the test's reader."""
    with tempfile.TemporaryDirectory() as d, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        V.write(c, Path(d) / "in.bvh", **write)
        write_bvh(ib.fill(str(Path(d) / "in.bvh"), keyframes=keys), Path(d) / "out.bvh")
        return V.positions(V.read(Path(d) / "out.bvh"))


def ratio(p: np.ndarray, c: V.Clip, keys) -> float:
    """The fill's mean joint error over the generated frames, over interpolation's (slerp, linear) on ``c``."""
    n = keys[-1] + 1
    gen = np.setdiff1d(np.arange(n), keys)
    truth, lerp = V.positions(c)[:n], V.positions(V.interpolate(c, keys))[:n]
    return float(np.linalg.norm(p[gen] - truth[gen], axis=-1).mean() / np.linalg.norm(lerp[gen] - truth[gen], axis=-1).mean())


@pytest.fixture(scope="module")
def native(ib, clip):
    """The original file's layout (six channels, ZXY) filled, per schedule."""
    return {k: filled(ib, clip, keys, orders="ZXY", six=range(len(clip.names))) for k, keys in SCHEDULES.items()}


def _mapped(p: np.ndarray, names, q: np.ndarray, other) -> float:
    """The largest distance between two fills' joints that are the model's (mapped onto its slots), by name."""
    index = {n: i for i, n in enumerate(other)}
    cols = [(i, index[n]) for i, n in enumerate(names) if n in index and n != UE["joint_Root"]]
    return float(np.abs(p[:, [a for a, _ in cols]] - q[:, [b for _, b in cols]]).max())


@pytest.mark.parametrize("schedule", list(SCHEDULES))
def test_a_renamed_copy_fills_identically(ib, clip, native, schedule):
    """UE-mannequin names, Euler XYZ, translation channels on root and pelvis only: every joint within 0.01 cm."""
    keys = SCHEDULES[schedule]
    p = filled(ib, V.rename(clip, UE), keys, orders="XYZ", movers=["root", "pelvis"])
    assert np.abs(p - native[schedule][: len(p)]).max() <= TOL


def test_any_euler_order_and_channels_fill_identically(ib, clip, native):
    """Property: any Euler order per joint, three or six channels per joint, translation channels on any subset of
    the joints that do not move (the hips always: they carry the walk) - the same fill within 0.01 cm."""
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st

    names = clip.names
    orders = st.sampled_from(["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"])

    @settings(max_examples=6, deadline=None, suppress_health_check=list(HealthCheck), derandomize=True)
    @given(st.lists(orders, min_size=len(names), max_size=len(names)),
           st.lists(st.booleans(), min_size=len(names), max_size=len(names)))
    def check(order_list, six):
        keys = SCHEDULES["every 15"]
        p = filled(ib, V.rename(clip, UE), keys, orders={UE[n]: o for n, o in zip(names, order_list)},
                   six=[UE[n] for n, s in zip(names, six) if s], movers=["pelvis"])
        assert np.abs(p - native["every 15"][: len(p)]).max() <= TOL

    check()


@pytest.mark.parametrize(("unit", "per_cm"), [("m", 0.01), ("inch", 1 / 2.54), ("cm", 1.0)])
@pytest.mark.parametrize("z_up", [False, True])
def test_units_and_up_axes_fill_identically_up_to_the_unit_and_the_axes(ib, clip, native, unit, per_cm, z_up):
    turn = R.from_euler("X", 90, degrees=True) if z_up else R.identity()
    c = V.scale(V.turn(V.rename(clip, UE), turn), per_cm)
    keys = SCHEDULES["every 30"]
    p = filled(ib, c, keys)
    back = turn.inv().apply(p.reshape(-1, 3) / per_cm).reshape(p.shape)
    assert np.abs(back - native["every 30"][: len(p)]).max() <= TOL


@pytest.mark.parametrize("extra", ["twist and finger bones", "a second spine bone", "a static top bone",
                                   "a moving top bone"])
def test_extra_unmapped_bones_leave_the_mapped_joints_fill_unchanged(ib, clip, native, extra):
    c = V.rename(clip, UE)
    if extra == "twist and finger bones":
        c = V.add_leaf(V.add_leaf(c, "upperarm_l", "upperarm_twist_01_l", [12.0, 0, 0], seed=1), "hand_r",
                       "index_01_r", [-4.0, 1.0, 2.0], seed=2)
    elif extra == "a second spine bone":
        c = V.insert_bone(c, "spine_02", "spine_015", 0.4)
    else:
        c = V.add_top(c, "world", moving=extra == "a moving top bone")
    keys = SCHEDULES["every 15"]
    p = filled(ib, c, keys)
    assert _mapped(p, c.names, native["every 15"], V.rename(clip, UE).names) <= TOL


def _tpose_directions(a_pose: float = 0.0, bend: float = 0.0) -> dict[str, np.ndarray]:
    """Bone directions of a rest pose: the body up, the legs down, the feet forward, the arms out, lowered by
    ``a_pose`` degrees, the forearms and shins bent by ``bend``."""
    up, down, fwd = np.array([0, 1.0, 0]), np.array([0, -1.0, 0]), np.array([0, 0, 1.0])
    out = {n: up for n in ("Hips", "Spine", "Chest", "Neck")}
    for s, sign in (("L", 1.0), ("R", -1.0)):
        a = np.radians(a_pose)
        arm = np.array([sign * np.cos(a), -np.sin(a), 0.0])
        b = np.radians(bend)
        out.update({f"Shoulder_{s}": np.array([sign, 0, 0.0]), f"UpperArm_{s}": arm,
                    f"LowerArm_{s}": arm * np.cos(b) + fwd * np.sin(b), f"UpperLeg_{s}": down,
                    f"LowerLeg_{s}": down * np.cos(b) - fwd * np.sin(b), f"Foot_{s}": fwd, f"Toes_{s}": fwd})
        out[f"Hand_{s}"] = out[f"LowerArm_{s}"]
    return out


@pytest.mark.parametrize("rest", ["T-pose", "A-pose", "limbs bent 60", "bone axes rolled"])
def test_another_rest_pose_fills_as_well_as_the_models(ib, clip, native, rest):
    """The same motion on a rest pose unlike the model's zero pose (its bones' frames turned): the fill's ratio to
    interpolation within 0.02 of the original's, at keys every 15 and 30."""
    rolls = {n: float(a) for n, a in zip(clip.names, np.random.default_rng(5).uniform(-180, 180, len(clip.names)))}
    frames = {"T-pose": V.aim_frames(clip, _tpose_directions()),
              "A-pose": V.aim_frames(clip, _tpose_directions(a_pose=45.0)),
              "limbs bent 60": V.aim_frames(clip, _tpose_directions(a_pose=20.0, bend=60.0)),
              "bone axes rolled": V.aim_frames(clip, _tpose_directions(), roll=rolls)}[rest]
    c = V.rename(V.rest(clip, frames), UE)
    for schedule in ("every 15", "every 30"):
        keys = SCHEDULES[schedule]
        assert ratio(filled(ib, c, keys), c, keys) <= ratio(native[schedule], clip, keys) + 0.02


@pytest.mark.parametrize("fps", [60.0, 120.0])
def test_a_higher_frame_rate_fills_the_models_frames_as_the_original(ib, clip, native, fps):
    """The clip at 60 or 120 fps (slerped), keys at the same times: the frames at the model's rate fill as the
    original's, within 0.01 cm; the frames between are the fill's, resampled."""
    c = V.resample(clip, fps)
    k = int(round(fps / 30.0))
    keys = [t * k for t in SCHEDULES["every 30"]]
    p = filled(ib, c, keys)
    assert np.abs(p[::k] - native["every 30"][: len(p[::k])]).max() <= TOL


def test_the_self_check_is_set_per_call(ib, clip):
    """``self_check=False`` for one call: no key hidden, the calibrated weights alone, as a runtime built without it;
    the next call checks again."""
    with tempfile.TemporaryDirectory() as d, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        V.write(clip, Path(d) / "in.bvh")
        keys = SCHEDULES["every 15"]
        off = ib.fill_detailed(str(Path(d) / "in.bvh"), keyframes=keys, self_check=False)
        on = ib.fill_detailed(str(Path(d) / "in.bvh"), keyframes=keys)
        built = Inbetweener.from_checkpoint(MODEL, self_check=False).fill_detailed(str(Path(d) / "in.bvh"),
                                                                                  keyframes=keys)
    assert off.checks == [] and on.checks and built.checks == []
    assert off.segments == built.segments and np.array_equal(off.bvh.motion, built.bvh.motion)
