"""benchmarks/check_windows.py: the candidate long pairs between the regular pair and the rule's, and the choice
under the no-more-harm rule (its measurements need BN-2 and run in ``python -m benchmarks run check_windows``)."""
from __future__ import annotations

import math

import pytest

from conftest import benchmark_script
from inbetweening.runtime.settings import FillSettings


@pytest.fixture(scope="module")
def check_windows():
    return benchmark_script("check_windows")


def test_candidate_pairs_run_geometrically_from_the_regular_pair_to_the_rule(check_windows):
    rule = {"long_check": 0.7, "long_x_full": 1.3, "long_x_none": 2.1}
    pairs = check_windows.candidate_pairs(rule, 2)
    assert pairs[0] == {}  # step 0: the shipped settings, no long pair
    assert pairs[-1] == rule
    mid = pairs[1]
    assert mid["long_check"] == 0.7
    assert mid["long_x_full"] == pytest.approx(math.sqrt(0.65 * 1.3), abs=1e-3)  # the regular pair is 0.65 / 1.05
    assert mid["long_x_none"] == pytest.approx(math.sqrt(1.05 * 2.1), abs=1e-3)
    for pair in pairs:
        FillSettings.from_mapping(pair)  # every candidate is a valid setting


def _row(ratios, fill_cm, interp_cm=1.0):
    return {"pair": {}, "ratios": ratios, "fill_cm": fill_cm, "interp_cm": interp_cm}


def test_the_choice_is_the_furthest_step_that_harms_no_more_clips_and_is_no_worse_pooled(check_windows):
    base = _row([0.9, 1.06, 0.8], 0.90)
    assert check_windows.chosen([base, _row([0.7, 1.07, 0.6], 0.80), _row([0.6, 1.2, 0.5], 0.70)]) == 2
    # step 2 harms a second clip: step 1 is the furthest that keeps to the rule
    assert check_windows.chosen([base, _row([0.7, 1.07, 0.6], 0.80), _row([1.1, 1.2, 0.5], 0.60)]) == 1
    # a step that gains on clips but loses pooled is not taken; none better: the regular pair
    assert check_windows.chosen([base, _row([0.7, 1.0, 0.6], 0.95)]) == 0
