"""``inbetweening.training.figures``: what the TensorBoard skeleton figure shows."""
from __future__ import annotations

import numpy as np
from matplotlib.colors import to_rgb

from inbetweening.data.synthetic import PARENTS, generate_clip, make_bvh
from inbetweening.tools.render import figure_to_array
from inbetweening.training.figures import INTERP_COLOR, MODEL_COLOR, frames_to_draw, transition_figure


def _pixels(img: np.ndarray, color: str) -> int:
    return int((np.abs(img.astype(float) / 255 - np.asarray(to_rgb(color))).max(axis=-1) < 0.08).sum())


def test_the_interpolation_stays_visible_where_the_prediction_equals_it():
    q, root = generate_clip(np.random.default_rng(0), 41)
    bvh = make_bvh(q, root)
    gt = bvh.skeleton().pose(root, q)[1]
    interp = gt + np.array([0.0, 0.0, 3.0])  # off the ground truth, and the prediction exactly on it
    fig = transition_figure(gt, interp.copy(), interp, PARENTS, 10, 30, frames_to_draw(10, 30, 6))
    img = figure_to_array(fig)
    side_views = img[: int(img.shape[0] * 0.55)]  # the top row of the figure: the skeleton panels
    assert _pixels(side_views, INTERP_COLOR) > 200  # dashed on top
    assert _pixels(side_views, MODEL_COLOR) > 200  # and the prediction through the gaps of the dashes
