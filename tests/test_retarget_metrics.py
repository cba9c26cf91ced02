"""Retargeting scores (src/inbetweening/retarget/metrics.py) on motions whose figures are known."""
from __future__ import annotations

import numpy as np
import pytest

from inbetweening.data.contacts import FootContact
from inbetweening.retarget.metrics import RetargetScore, jerk

FPS = 30.0


def _score(height=100.0):
    # 3 joints: 0 the root, 1 above it (a bone of length 50), 2 a foot on the ground (scored for skating)
    return RetargetScore(bones=[1], bone_parents=[0], bone_lengths=np.array([50.0]), slots=[(1, 1)],
                         hips=(0, 0), feet=([2], [2]), heights=(height, height), contact=FootContact(("f",), 5.0, 20.0),
                         fps=FPS)


def _pose(frames, foot_speed=0.0):
    t = np.arange(frames)[:, None]
    root = np.concatenate([t * 2.0, np.full_like(t, 50.0, dtype=float), 0 * t], 1)
    gp = np.stack([root, root + [0, 50, 0], np.concatenate([t * foot_speed / FPS, 0 * t + 1.0, 0 * t + 10.0], 1)], 1)
    return gp


def test_constant_velocity_has_no_jerk_and_a_cubic_has_the_known_one():
    t = np.arange(20, dtype=float)[:, None, None]
    assert jerk(np.concatenate([t, 2 * t, 0 * t], -1), FPS)[0] == pytest.approx(0.0, abs=1e-6)
    total, n = jerk(np.concatenate([t**3, 0 * t, 0 * t], -1), FPS)
    assert total / n == pytest.approx(6.0 * FPS**3)


def test_exact_motion_scores_zero_and_errors_scale_with_height():
    src = _pose(30)
    s = _score()
    s.add(src, src, src)
    r = s.result()
    assert r["pos_err"] == 0 and r["pose_err"] == 0 and r["bone_err"] == pytest.approx(0.0, abs=1e-9)
    off = src.copy()
    off[:, 1] += [0, 10, 0]  # 10 units higher: bone 50 -> 60, 10 % of a 100 body
    s = _score()
    s.add(off, src, src)
    r = s.result()
    assert r["pos_err"] == pytest.approx(100 * 10 / 3 / 100) and r["bone_err"] == pytest.approx(10.0)
    assert r["pose_err"] == pytest.approx(10.0)


def test_skating_is_the_foot_speed_while_the_source_foot_is_planted():
    src = _pose(30, foot_speed=0.0)
    sliding = _pose(30, foot_speed=15.0)  # 15 units/s, under the 20 units/s planted speed of the source's rule
    s = _score()
    s.add(sliding, None, src)
    assert s.result()["skate"] == pytest.approx(15.0)  # % of a 100-unit body per second
    s = _score()
    s.add(src, None, src)
    assert s.result()["skate"] == pytest.approx(0.0)


def test_the_source_scores():
    from inbetweening.retarget.metrics import source_scores

    still = _pose(30, foot_speed=0.0)
    sliding = _pose(30, foot_speed=15.0)
    r = source_scores([still, sliding], [2], 100.0, FootContact(("f",), 5.0, 20.0), FPS)
    assert r["jerk"] == pytest.approx(0.0, abs=1e-6) and r["skate"] == pytest.approx(7.5)
