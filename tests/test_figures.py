"""``inbetweening.training.figures``: what the TensorBoard skeleton figure shows."""
from __future__ import annotations

import numpy as np
import torch
from matplotlib.colors import to_rgb

from inbetweening.data.synthetic import NAMES, PARENTS, generate_clip, make_bvh
from inbetweening.rendering.render import figure_to_array
from inbetweening.rendering.skeleton_plot import CONTACT_COLOR
from inbetweening.training.figures import (
    CARD_PX,
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
    interpolation visible, adds a row per foot under the error curve, and stays card-sized."""
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
        rows = fig.axes[len(frames) + 1]  # a row per foot, in skeleton order
        assert rows.get_ylim() == (len(feet) - 0.5, -0.5) and len(rows.collections) == 2 * len(feet)
        w, h = fig.get_size_inches() * fig.dpi
        assert w <= 640 and h <= 1000  # card-sized: test_the_figures_text_is_legible_in_a_card
    img = figure_to_array(fig)
    side_views = img[: int(img.shape[0] * 0.45)]
    assert _pixels(side_views, CONTACT_COLOR) > 100  # the dots are seen, not hidden under the bones
    assert _pixels(side_views, INTERP_COLOR) > 200


# ------------------------------------------------------------------ legible in TensorBoard's image card


def _figures():
    """The two figures as a run draws them: the per-joint figure of the synthetic skeleton (4 lengths, with
    interpolation), the skeleton figure without and with contact rows."""
    from inbetweening.training.figures import per_joint_figure

    rng = np.random.default_rng(1)
    q, root = generate_clip(np.random.default_rng(0), 41)
    gt = make_bvh(q, root).skeleton().pose(root, q)[1]
    pred = gt + rng.normal(0, 2, gt.shape)
    interp = gt + np.array([0.0, 0.0, 3.0]) * np.linspace(0, 1, 41)[:, None, None]
    feet = [i for i, name in enumerate(NAMES) if "Foot" in name or "Toe" in name]
    contacts = {k: rng.random((41, len(NAMES))) > 0.5 for k in ("prediction", "ground truth")}
    model = {n: {"pos": rng.random(len(NAMES)) * n, "rot": rng.random(len(NAMES)) * n} for n in (5, 15, 30, 45)}
    title = "epoch 12, step 4800 (best, last): window 0, 30-frame transition"
    slower = {n: {k: v * 1.2 for k, v in e.items()} for n, e in model.items()}
    return {"per_joint": per_joint_figure(NAMES, model, slower, title="validation per-joint position error, epoch 12"),
            "per_joint_rotation": per_joint_figure(NAMES, model, slower, key="rot",
                                                   title="validation per-joint rotation error, epoch 12"),
            "skeleton": transition_figure(gt, pred, interp, PARENTS, 10, 30, frames_to_draw(10, 30, 6), title=title),
            "skeleton_contacts": transition_figure(gt, pred, interp, PARENTS, 10, 30, frames_to_draw(10, 30, 6),
                                                   title=title, feet=feet, contacts=contacts,
                                                   foot_names=[NAMES[j] for j in feet])}


def test_the_figures_text_is_legible_in_a_card():
    """Fitted into TensorBoard's image card at its narrowest (320 x 230 px), every text of both figures is at least
    8 px high (the old 960 x 390 skeleton figure's 7 pt labels were about 3 px), and none is cut at the figure's
    edge."""
    from inbetweening.training.figures import HEIGHT_PX, WIDTH_PX

    for name, fig in _figures().items():
        img = figure_to_array(fig)
        h, w = img.shape[:2]
        assert (w, h) == (WIDTH_PX, HEIGHT_PX) and w > h, name  # landscape, like the card's box
        scale = min(CARD_PX[0] / w, CARD_PX[1] / h)
        renderer = fig.canvas.get_renderer()
        texts = [t for t in fig.findobj(lambda a: hasattr(a, "get_text") and hasattr(a, "get_fontsize"))
                 if t.get_visible() and t.get_text().strip() and t.get_window_extent(renderer).width > 0]
        assert len(texts) > 20, name
        for t in texts:
            card_px = t.get_fontsize() * fig.dpi / 72 * scale
            assert card_px >= 8, (name, t.get_text(), card_px)
        border = np.concatenate([img[:2].reshape(-1, 3), img[-2:].reshape(-1, 3), img[:, :2].reshape(-1, 3),
                                 img[:, -2:].reshape(-1, 3)])
        assert (border > 250).all(), name  # nothing drawn up to the edge: no text cut off


def test_no_legend_covers_the_data():
    """Pixel check on the rendered PNGs: the pixels the legends draw (the figure drawn with and without them) all
    lie outside every data area (axes), e.g. the per-joint legend no longer covers the 30/45-frame curves, nor the
    skeleton figure's legend frames 11-15 of the error curve; and the error curve has no legend box of its own."""
    for name, fig in _figures().items():
        legends = [*fig.legends, *(a.get_legend() for a in fig.axes if a.get_legend() is not None)]
        assert legends, name
        with_legend = figure_to_array(fig).astype(int)
        for lg in legends:
            lg.set_visible(False)
        without = figure_to_array(fig).astype(int)
        for lg in legends:
            lg.set_visible(True)
        changed = np.abs(with_legend - without).max(axis=-1) > 0
        assert changed.sum() > 200, name  # the legend is drawn
        h = changed.shape[0]
        for ax in fig.axes:
            box = ax.get_window_extent(fig.canvas.get_renderer())
            inside = changed[int(h - box.y1) + 1:int(h - box.y0) - 1, int(box.x0) + 1:int(box.x1) - 1]
            assert not inside.any(), (name, ax.get_title(), int(inside.sum()))
    err = _figures()["skeleton"].axes[6]
    assert err.get_legend() is None and "mean" in err.get_title(loc="left")  # the means: in the title
