"""``inbetweening.training.figures``: what the TensorBoard skeleton figure shows."""
from __future__ import annotations

import numpy as np
import torch
from matplotlib.colors import to_rgb

from inbetweening.data.synthetic import NAMES, PARENTS, generate_clip, make_bvh
from inbetweening.rendering.render import figure_to_array
from inbetweening.rendering.skeleton_plot import CONTACT_COLOR
from inbetweening.training.figures import (
    INTERP_COLOR,
    MODEL_COLOR,
    SkeletonFigure,
    frames_to_draw,
    transition_figure,
)


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


def _standing_then_gliding(frames: int = 41, start: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """``(local_q, root)``: a synthetic pose held still with its lowest foot joint 3 cm above the floor (the feet
    low enough planted by the data's rule), gliding forward at 1 m/s after frame ``start - 1`` (no foot planted)."""
    q, root = generate_clip(np.random.default_rng(3), frames)
    q[:] = q[:1]
    root[:] = root[:1]
    feet = [i for i, name in enumerate(NAMES) if "Foot" in name or "Toe" in name]
    root[:, 1] += 3.0 - make_bvh(q, root).skeleton().pose(root, q)[1][0, feet, 1].min()
    root[start:, 0] += 100.0 / 30.0 * np.arange(1, frames - start + 1)
    return q, root


def test_the_skeleton_figure_marks_planted_feet_of_a_contact_model(tiny_contact_checkpoint):
    """A model with contact channels (a real trained predictor): the callback's window carries the predicted and the
    true planted feet, the truth being the data's contact rule on the ground-truth motion; the figure marks each
    side view's planted feet where they stand (prediction: dots in the contact colour, truth: rings), keeps the
    interpolation visible, adds a row per foot under the error curve, and stays thumbnail-sized."""
    from inbetweening.data.contacts import planted_frames
    from inbetweening.training.module import load_module

    module = load_module(tiny_contact_checkpoint)
    pr = module.predictor
    q, root = _standing_then_gliding()
    s, contacts = SkeletonFigure(n=30).window_motion(module, torch.tensor(root), torch.tensor(q), 30)
    names, rule = pr.skeleton.names, pr.contact
    feet = list(rule.indices(names))
    assert set(contacts) == {"prediction", "ground truth"}
    assert all(c.shape == (41, len(names)) and c.dtype == bool for c in contacts.values())
    others = [j for j in range(len(names)) if j not in feet]
    assert not contacts["ground truth"][:, others].any()
    truth = planted_frames(s["ground truth"][:, feet], pr.fps, rule.height, rule.speed)
    assert np.array_equal(contacts["ground truth"][:, feet], truth)
    assert truth[0].sum() >= 2 and (truth[:19] == truth[0]).all() and not truth[19:].any()  # standing, then gliding

    frames = frames_to_draw(10, 30, 6)
    every = {"prediction": np.zeros_like(contacts["prediction"]), "ground truth": contacts["ground truth"]}
    every["prediction"][:, feet] = True  # every foot planted: a dot on each in every side view
    for marks in (contacts, every):
        fig = transition_figure(s["ground truth"], s["prediction"], s["interpolation"], PARENTS, 10, 30, frames,
                                feet=feet, contacts=marks, foot_names=[names[j] for j in feet])
        for ax, t in zip(fig.axes, frames):
            dots = [ln for ln in ax.get_lines() if ln.get_marker() == "o" and ln.get_markerfacecolor() != "none"]
            rings = [ln for ln in ax.get_lines() if ln.get_marker() == "o" and ln.get_markerfacecolor() == "none"]
            on = [j for j in feet if marks["prediction"][t, j]]
            assert np.allclose(dots[0].get_xdata(), s["prediction"][t, on, 0])
            assert np.allclose(dots[0].get_ydata(), s["prediction"][t, on, 1])
            assert len(rings[0].get_xdata()) == marks["ground truth"][t, feet].sum()
        assert fig.axes[len(frames) + 1].get_yticklabels()[0].get_text() == names[feet[0]]  # the rows per foot
        w, h = fig.get_size_inches() * fig.dpi
        assert w <= 1000 and h <= 450
    img = figure_to_array(fig)
    side_views = img[: int(img.shape[0] * 0.45)]
    assert _pixels(side_views, CONTACT_COLOR) > 100  # the dots are seen, not hidden under the bones
    assert _pixels(side_views, INTERP_COLOR) > 200
