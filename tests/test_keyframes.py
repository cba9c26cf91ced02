"""The keyframes-only protocol (``eval.py protocol=keyframes``): scoring functions pinned by hand-derived values,
the whole protocol on clips whose answers are known, and eval.py / benchmark.json / collect end to end."""
from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import TINY, compose_cfg
from inbetweening.data.clips import Clip
from inbetweening.data.contacts import FootContact
from inbetweening.data.datasets import spec_contact
from inbetweening.data.errors import DatasetError
from inbetweening.data.specs import DATASETS, DatasetSpec, lafan_split
from inbetweening.evaluation import keyframes as KF
from inbetweening.evaluation import schedules as SCH
from inbetweening.evaluation.collect import collect, to_markdown
from inbetweening.geometry.interp import interpolate_keyframes
from inbetweening.geometry.skeleton import Skeleton
from inbetweening.training.callbacks import NonFiniteError
from inbetweening.training.config import ConfigError, validate
from inbetweening.training.evaluate import evaluate
from inbetweening.training.job import write_benchmark

FPS = 30.0
H, S = 5.0, 60.0  # contact height (cm) and speed (cm/s) of the hand-made cases
DATA = [o for o in TINY if o.startswith("data.")]
FIGURES = ("model_cm", "interp_cm", "ratio", "skate_model", "skate_interp", "skate_gt", "n_clips", "n_frames", "mean_gap",
           "worse_share", "worst", "clip_ratios")


def _yaw(deg) -> np.ndarray:
    a = np.radians(np.asarray(deg, np.float64)) / 2
    return np.stack([np.cos(a), 0 * a, np.sin(a), 0 * a], -1)


# ------------------------------------------------------------------ pure functions
def test_keyframe_indices_truncate_to_the_last_key():
    assert SCH.keyframe_indices(10, 3) == [0, 3, 6, 9]
    assert SCH.keyframe_indices(12, 3) == [0, 3, 6, 9]  # frames 10, 11 are cut: the last frame is a key
    assert SCH.keyframe_indices(46, 45) == [0, 45]
    assert SCH.keyframe_indices(45, 45) == []  # too short for two keys
    np.testing.assert_array_equal(KF.generated_frames(7, [0, 3, 6]), [0, 1, 1, 0, 1, 1, 0])
    np.testing.assert_array_equal(KF.scored_pairs(np.array([0, 1, 0, 0, 1, 0], bool)), [1, 1, 0, 1, 1])


def test_keyed_clip_hides_every_frame_but_the_keys_and_ends_at_the_last_key():
    rng = np.random.default_rng(3)
    root, q = rng.normal(size=(20, 3)), rng.normal(size=(20, 4, 4))
    keys = [0, 4, 5, 13]
    (tr, tq), (gr, gq), gen = KF.keyed_clip(root, q, keys)
    assert tr.shape == (14, 3) and tq.shape == (14, 4, 4) and gr.shape == (14, 3)
    assert list(np.flatnonzero(gen)) == [t for t in range(14) if t not in keys]
    assert np.array_equal(gr[keys], root[keys]) and np.array_equal(gq[keys], q[keys])  # keys bit-exact
    assert np.isnan(gr[gen]).all() and np.isnan(gq[gen]).all() and np.array_equal(tr, root[:14])
    gr[1] = 0.0
    assert root[1, 0] != 0.0 or root[1, 1] != 0.0  # a copy: the caller's clip is untouched


def test_position_error_is_the_mean_distance_on_the_selected_frames():
    gt = np.zeros((4, 2, 3))
    pred = gt.copy()
    pred[1] += [3.0, 4.0, 0.0]  # 5 cm on both joints
    pred[2, 0] += [0.0, 0.0, 2.0]  # 2 cm on one joint
    pred[3] += 100.0  # a keyframe: not selected
    s, n = KF.position_error(pred, gt, np.array([False, True, True, False]))
    assert n == 4 and s == pytest.approx(12.0)


def _skate(feet, pairs=None):
    """Skating of a motion on its own contacts (what the protocol does for the ground truth)."""
    contact = KF.foot_contacts(feet, FPS, H, S)
    return KF.foot_skate(feet, contact if pairs is None else contact & pairs[:, None], FPS)


def test_a_foot_sliding_on_the_ground_skates_at_its_speed():
    t = np.arange(20)
    vx, vz = 12.0, 16.0  # cm/s -> horizontal speed 20 cm/s
    foot = np.stack([vx * t / FPS, np.full(20, 1.0), vz * t / FPS], -1)[:, None]  # (F, 1, 3), 1 cm high
    s, n = _skate(foot)
    assert n == 19 and s / n == pytest.approx(20.0)
    assert KF.foot_contacts(foot, FPS, H, S).all()


def test_a_foot_in_the_air_or_moving_fast_contributes_nothing():
    t = np.arange(20)
    air = np.stack([12.0 * t / FPS, np.full(20, 30.0), 0 * t], -1)[:, None]  # 30 cm high
    assert _skate(air) == (0.0, 0)
    fast = np.stack([200.0 * t / FPS, np.zeros(20), 0 * t], -1)[:, None]  # on the ground, 200 cm/s > S
    assert _skate(fast) == (0.0, 0)
    # half the clip on the ground at 6 cm/s, then lifted: only the ground pairs count, at 6 cm/s
    mixed = np.stack([6.0 * t / FPS, np.where(t < 10, 0.0, 40.0), 0 * t], -1)[:, None]
    s, n = _skate(mixed)
    assert n == 9 and s / n == pytest.approx(6.0)  # pairs (0,1) .. (8,9); (9,10) has mean height 20
    # vertical speed does not skate: a foot pressing down (on the ground, slowly) has horizontal speed 0
    press = np.stack([0 * t, 2.0 - 0.1 * t / FPS, 0 * t], -1)[:, None]
    assert _skate(press) == (0.0, 19)
    # only the scored pairs count
    s, n = _skate(mixed, np.arange(19) < 4)
    assert n == 4 and s / n == pytest.approx(6.0)


def test_skating_is_measured_where_the_ground_truth_is_in_contact():
    """A generated foot sliding at 90 cm/s where the real foot is planted skates 90 cm/s (on its own contacts it
    would have none: faster than contact_speed); where the real foot is in the air nothing counts."""
    t = np.arange(20)
    gt = np.stack([0 * t, np.where(t < 10, 1.0, 40.0), 0 * t], -1)[:, None].astype(float)  # planted, then lifted
    gen = gt.copy()
    gen[:, 0, 0] = 90.0 * t / FPS
    contact = KF.foot_contacts(gt, FPS, H, S)
    s, n = KF.foot_skate(gen, contact, FPS)
    assert n == 9 and s / n == pytest.approx(90.0)
    assert KF.foot_skate(gt, contact, FPS) == (0.0, 9)
    assert _skate(gen) == (0.0, 0)


def test_hold_keyframes_repeats_the_previous_key():
    root = np.arange(7.0)[:, None] * [1.0, 0.0, 0.0]
    q = np.broadcast_to(_yaw(np.arange(7.0) * 10)[:, None], (7, 2, 4))
    r, qq = KF.hold_keyframes(root, q, [0, 3, 6])
    np.testing.assert_array_equal(r[:, 0], [0, 0, 0, 3, 3, 3, 6])
    np.testing.assert_array_equal(qq[:, 1], q[[0, 0, 0, 3, 3, 3, 6], 1])


# ------------------------------------------------------------------ the protocol on clips with known answers
# root -> foot 90 cm below: a 2-joint skeleton whose foot moves with the root
SKEL = Skeleton(("Hips", "LeftFoot"), (-1, 0), np.array([[0.0, 0.0, 0.0], [0.0, -90.0, 0.0]]))
FEET = KF.FootSpec((1,), H, S)


def _sliding_clip(frames: int, speed: float, turn: float = 0.0, name: str = "slide") -> Clip:
    """The root glides along +X at ``speed`` cm/s, 91 cm high (foot 1 cm above the ground); the root turns about Y
    at ``turn`` degrees per frame (the foot is below the root: it does not move with the turn)."""
    t = np.arange(frames)
    root = np.stack([speed * t / FPS, np.full(frames, 91.0), np.zeros(frames)], -1)
    q = np.stack([_yaw(turn * t), _yaw(0.0 * t)], 1)
    return Clip(name, q, root)


def test_interpolation_is_exact_on_a_clip_linear_in_time():
    clip = _sliding_clip(61, 12.0, turn=2.0)
    res = KF.evaluate_clips([clip], SKEL, None, [5, 15, 30], FPS, FEET)
    assert set(res) == {"5", "15", "30"}
    for k, r in res.items():
        assert r["interp_cm"] == pytest.approx(0.0, abs=1e-9) and r["model_cm"] == r["interp_cm"]
        assert r["skate_gt"] == pytest.approx(12.0) and r["skate_interp"] == pytest.approx(12.0)
        assert r["n_clips"] == 1 and r["n_frames"] == 60 - 60 // int(k)


def test_a_model_returning_the_ground_truth_has_error_0_and_the_ground_truths_skate():
    """On a clip interpolation cannot reproduce: the oracle has error 0, interpolation not; skating as the gt's."""
    t = np.arange(46)
    clip = _sliding_clip(46, 12.0)
    clip.root_pos[:, 1] += 3.0 * np.sin(2 * np.pi * t / 15)  # foot 1 +- 3 cm high, < 40 cm/s: in contact
    seen = []

    def oracle(root, q, keys):
        gen = KF.generated_frames(len(root), keys)
        assert np.isnan(root[gen]).all() and np.isnan(q[gen]).all()  # the fill never sees the ground truth
        assert np.array_equal(root[~gen], clip.root_pos[: len(root)][~gen])
        seen.append(list(keys))
        return clip.root_pos[: len(root)], clip.local_q[: len(root)]

    res = KF.evaluate_clips([clip], SKEL, oracle, [5, 15, 45], FPS, FEET)
    assert seen == [list(range(0, 46, 5)), [0, 15, 30, 45], [0, 45]]
    for r in res.values():
        assert r["model_cm"] == 0.0 and r["ratio"] == 0.0 and r["interp_cm"] > 0.1
        assert r["skate_model"] == r["skate_gt"] == pytest.approx(12.0)
    assert res["45"]["skate_interp"] == pytest.approx(12.0)  # interpolation: 1 cm high all along, in contact
    assert res["45"]["interp_cm"] > res["5"]["interp_cm"]


def test_hold_baseline_stands_still_then_jumps_on_the_ground_truths_contacts():
    """Holding a key: the foot stands still for 14 pairs, then jumps 15 frames' distance in one (12 cm/s * 15 =
    180 cm/s); the ground truth slides at 12 cm/s, in contact all along, so the hold's skate is 2 * 180 / 30 pairs
    = 12 cm/s; its error at frame a + i is 12 cm/s * i / 30."""
    clip = _sliding_clip(31, 12.0)
    res = KF.evaluate_clips([clip], SKEL, KF.hold_keyframes, [15], FPS, FEET)["15"]
    assert res["skate_model"] == pytest.approx(12.0) and res["skate_gt"] == pytest.approx(12.0)
    assert res["model_cm"] == pytest.approx(12.0 / FPS * np.mean(np.arange(1, 15)))
    assert res["interp_cm"] == pytest.approx(0.0, abs=1e-9) and res["n_frames"] == 28
    clip.root_pos[:, 0] = 0.0  # the ground truth stands: the hold and interpolation stand too
    res = KF.evaluate_clips([clip], SKEL, KF.hold_keyframes, [15], FPS, FEET)["15"]
    assert res["skate_model"] == res["skate_interp"] == res["skate_gt"] == 0.0 and res["model_cm"] == 0.0


def test_short_clips_are_left_out_and_no_feet_means_no_skating():
    res = KF.evaluate_clips([_sliding_clip(20, 6.0), _sliding_clip(40, 6.0)], SKEL, None, [15, 45], FPS, None)
    assert res["15"]["n_clips"] == 2 and "45" not in res  # no clip has 46 frames
    assert "skate_gt" not in res["15"] and set(res["15"]) == {"model_cm", "interp_cm", "ratio", "n_clips", "n_frames",
                                                              "mean_gap", "worse_share", "worst", "clip_ratios"}


def test_foot_spec_from_a_dataset_spec():
    spec = DatasetSpec("kf_test", lafan_split, (0, 0, 1), feet=("LeftFoot",), contact_height=5, contact_speed=60)
    assert KF.foot_spec(SKEL, spec_contact(spec)) == KF.FootSpec((1,), 5.0, 60.0)
    assert KF.foot_spec(SKEL, FootContact()) is None
    with pytest.raises(DatasetError, match=r"foot joint\(s\) \['RightToe'\] are not in the skeleton"):
        KF.foot_spec(SKEL, FootContact(("LeftFoot", "RightToe"), 5, 60))
    with pytest.raises(ValueError, match="feet need contact_height > 0"):
        DatasetSpec("kf_test", lafan_split, (0, 0, 1), feet=("LeftFoot",))
    for name in ("lafan1", "bandai_namco", "synthetic"):  # every built-in dataset is scored for skating
        assert len(DATASETS[name].feet) == 4 and DATASETS[name].contact_height > 0


# ------------------------------------------------------------------ benchmark.json, config, collect
def test_benchmark_json_keeps_its_lafan_form_and_is_strict_for_keyframes(tmp_path):
    path = tmp_path / "benchmark.json"
    write_benchmark(path, "d", "m", 3, {"l2p@5": 1.5})  # the LAFAN protocol's bytes, unchanged
    assert path.read_text() == json.dumps({"dataset": "d", "model": "m", "n_windows": 3, "metrics": {"l2p@5": 1.5}},
                                          indent=2)
    row = {"model_cm": 2.0, "interp_cm": 4.0, "ratio": 0.5, "n_clips": 3, "n_frames": 40}
    write_benchmark(path, "d", "m", 3, {}, keyframes={5: row})
    assert json.loads(path.read_text())["keyframes"] == {"5": row}
    with pytest.raises(NonFiniteError, match=r"benchmark: keyframes.15.ratio not finite \(nan\)"):
        write_benchmark(tmp_path / "b2.json", "d", "m", 3, {}, keyframes={5: row, 15: {**row, "ratio": float("nan")}})
    assert not (tmp_path / "b2.json").exists()


@pytest.mark.parametrize("overrides, match", [
    (["protocol=windows"], r"^protocol: must be one of \['lafan', 'keyframes'\], got 'windows'$"),
    (["keyframe_intervals=[5,1]"], r"^keyframe_intervals: intervals must be integers >= 2"),
    (["keyframe_intervals=[5,x]"], r"^keyframe_intervals: intervals must be integers >= 2 .*got 'x'"),
    (["keyframe_intervals=[]"], r"^keyframe_intervals: must be a non-empty list"),
    (["keyframe_intervals=15"], r"^keyframe_intervals: must be a non-empty list"),
    (["keyframe_intervals=[5,5]"], r"^keyframe_intervals: an interval is listed twice"),
])
def test_bad_protocol_settings_are_one_line_naming_the_key(overrides, match, tmp_path):
    with pytest.raises(ConfigError, match=match) as e:
        validate(compose_cfg("eval", overrides, tmp_path, tmp_path))
    assert "\n" not in str(e.value)


def test_eval_keyframes_protocol_end_to_end(tiny_checkpoint, tmp_path, cache_dir, capsys):
    """eval.py protocol=keyframes for a checkpoint and for interpolation; collect tabulates both."""
    over = [*DATA, "protocol=keyframes", "keyframe_intervals=[5,30]"]
    base = evaluate(compose_cfg("eval", [*over, "model=interpolation"], tmp_path / "sweep" / "interp", cache_dir))
    # self_check=false: the tiny, barely trained network would be handed back to interpolation at keys every 5
    got = evaluate(compose_cfg("eval", [*over, f"ckpt_path='{tiny_checkpoint}'", "self_check=false"],
                               tmp_path / "sweep" / "model", cache_dir))
    out = capsys.readouterr().out
    assert "Keyframes-only protocol: synthetic" in out and "| keyframe every |" in out
    res = json.loads((tmp_path / "sweep" / "model" / "benchmark.json").read_text())
    assert res["model"] == "graph_transformer" and res["metrics"] == {} and set(res["keyframes"]) == {"5", "30"}
    ref = json.loads((tmp_path / "sweep" / "interp" / "benchmark.json").read_text())["keyframes"]
    for k, row in res["keyframes"].items():
        assert set(row) == set(FIGURES)
        assert row["interp_cm"] == pytest.approx(ref[k]["interp_cm"], rel=1e-12)  # the same clips and keys
        assert row["skate_interp"] == pytest.approx(ref[k]["skate_interp"], rel=1e-12)
        assert row["skate_gt"] == pytest.approx(ref[k]["skate_gt"], rel=1e-12)
        assert row["ratio"] == pytest.approx(row["model_cm"] / row["interp_cm"])
        assert row["model_cm"] != pytest.approx(row["interp_cm"], rel=1e-6)  # the network did generate frames
        assert ref[k]["ratio"] == 1.0 and ref[k]["model_cm"] == ref[k]["interp_cm"] > 0
    assert got["model_cm@5"] == res["keyframes"]["5"]["model_cm"] and base["ratio@30"] == 1.0
    assert res["keyframes"]["5"]["interp_cm"] < res["keyframes"]["30"]["interp_cm"]
    rows = collect(tmp_path / "sweep", sort="kf_model_cm@30")
    assert {r["model"] for r in rows} == {"graph_transformer", "interpolation"}
    assert rows[0]["kf_model_cm@30"] <= rows[1]["kf_model_cm@30"]
    assert {r["model"]: r["kf_skate_model@5"] for r in rows} == {
        "graph_transformer": res["keyframes"]["5"]["skate_model"], "interpolation": ref["5"]["skate_model"]}
    assert "KF_MODEL_CM@5" in to_markdown(rows) and "KF_SKATE_GT@30" in to_markdown(rows)


# ------------------------------------------------------------------ keypose schedules
def test_random_schedule_draws_gaps_in_range_and_is_seeded():
    keys = SCH.random_keyframes(400, np.random.default_rng(1))
    gaps = np.diff(keys)
    assert keys[0] == 0 and keys[-1] <= 399 and 399 - keys[-1] < 45  # cut after the last key that fits
    assert gaps.min() >= 3 and gaps.max() <= 45 and len(set(gaps.tolist())) > 3
    assert keys == SCH.random_keyframes(400, np.random.default_rng(1))
    assert keys != SCH.random_keyframes(400, np.random.default_rng(2))
    assert SCH.random_keyframes(3, np.random.default_rng(0), gaps=(3, 3)) == []  # no second key fits in 3 frames
    assert SCH.random_keyframes(4, np.random.default_rng(0), gaps=(3, 3)) == [0, 3]


def test_extremes_are_the_speed_minima_at_least_8_apart_and_long_gaps_split():
    # a joint swinging with period 20 frames: speed minima at the turning points, every 10 frames
    t = np.arange(101)
    x = np.sin(2 * np.pi * t / 20)
    pos = np.stack([x, 0 * x, 0 * x], -1)[:, None, :]
    keys = SCH.extreme_keyframes(pos)
    assert keys[0] == 0 and keys[-1] == 100
    turning = [5 + 10 * i for i in range(10)]
    assert set(keys[1:-1]) <= set(turning) and len(keys) >= 10  # at the turns (>= 8 apart: all of them fit)
    assert np.diff(keys).min() >= 5  # only the end frames may sit closer than 8 to a turn
    # a motion that never slows: no minimum, so only the ends, then the 45-frame split (equal parts)
    still = np.stack([t * 1.0, 0 * t, 0 * t], -1)[:, None, :]
    assert SCH.extreme_keyframes(still) == [0, 33, 67, 100]
    assert SCH.extreme_keyframes(still[:40]) == [0, 39]
    # minima closer than 8 frames: the slower one wins
    speed_dips = np.ones(60)
    speed_dips[[20, 24]] = [0.2, 0.1]
    pos = np.cumsum(speed_dips)[:, None, None] * np.array([1.0, 0, 0])
    assert SCH.extreme_keyframes(pos, max_gap=100) == [0, 24, 59]


def test_schedules_run_through_the_protocol_and_are_named_rows():
    clips = [_sliding_clip(200, 12.0, turn=1.0, name=f"c{i}") for i in range(3)]
    res = KF.evaluate_clips(clips, SKEL, None, [15, "random", "extremes"], FPS, FEET, seed=3)
    assert set(res) == {"15", "random", "extremes"}
    assert res["15"]["mean_gap"] == pytest.approx(15.0)
    assert 3 <= res["random"]["mean_gap"] <= 45 and res["random"]["n_clips"] == 3
    assert res["extremes"]["mean_gap"] <= 45
    for r in res.values():  # interpolation is exact on a motion linear in time, whatever the keys
        assert r["interp_cm"] == pytest.approx(0.0, abs=1e-9)
    again = KF.evaluate_clips(clips, SKEL, None, ["random"], FPS, FEET, seed=3)
    assert again["random"] == res["random"]
    other = KF.evaluate_clips(clips, SKEL, None, ["random"], FPS, FEET, seed=4)
    assert other["random"]["n_frames"] != res["random"]["n_frames"]
    with pytest.raises(ValueError, match="unknown keyframe schedule 'grid'"):
        SCH.schedule_keyframes("grid", 100, np.random.default_rng(0))


@pytest.mark.parametrize("value, ok", [("[5,random,extremes]", True), ("[random]", True), ("[bogus]", False),
                                       ("[random,random]", False), ("[1]", False)])
def test_schedules_in_the_config(value, ok, tmp_path):
    cfg = compose_cfg("eval", ["protocol=keyframes", f"keyframe_intervals={value}"], tmp_path, tmp_path)
    if ok:
        validate(cfg)
    else:
        with pytest.raises(ConfigError, match="^keyframe_intervals: "):
            validate(cfg)


def test_per_clip_ratios_name_the_clips_worse_than_interpolation():
    """Each clip's own ratio, the share above 1.05 and the worst by name: a fill that spoils one clip of three."""
    t = np.arange(40)
    clips = []
    for i in range(3):  # a root on a curve: interpolation is not exact
        c = _sliding_clip(40, 6.0, name=f"clip-{i}")
        clips.append(Clip(c.name, c.local_q, c.root_pos + np.stack([30 * np.sin(t / 4), 0 * t, 0 * t], -1)))

    def fill(root, q, keys):
        r, lq = interpolate_keyframes(root, q, keys)
        if fill.calls == 1:
            r[1:-1] += np.array([0.0, 30.0, 0.0])  # the second clip: 30 cm off on every generated frame
        fill.calls += 1
        return r, lq

    fill.calls = 0
    res = KF.evaluate_clips(clips, SKEL, fill, [15], FPS, None)["15"]
    assert set(res["clip_ratios"]) == {"clip-0", "clip-1", "clip-2"}
    assert res["clip_ratios"]["clip-0"] == 1.0 and res["clip_ratios"]["clip-1"] > 1.05
    assert res["worse_share"] == pytest.approx(1 / 3) and res["worst"].startswith("clip-1 ")
    assert "33.3 %" in KF.format_table({"15": res})
