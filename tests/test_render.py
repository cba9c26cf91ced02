"""Tests for the headless skeleton renderer (:mod:`inbetweening.rendering.render`)."""
from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest
from matplotlib.colors import to_rgb
from PIL import Image

from inbetweening.rendering.render import draw_sequences, figure_to_array, render_gif, render_png
from inbetweening.rendering.skeleton_plot import CONTACT_COLOR, FLOOR_COLOR, PALETTE

PARENTS = [-1, 0, 1, 2, 0, 4, 0, 6]  # root, a 3-bone chain, two 2-bone limbs
OFFSETS = np.array(
    [[0, 0, 0], [0, 1, 0], [0, 1, 0], [0, 1, 0], [0.5, -1, 0], [0, -1, 0], [-0.5, -1, 0], [0, -1, 0]], dtype=float
)
T = 6


def _rest_pose() -> np.ndarray:
    """``(J, 3)`` global positions of the rest pose (offsets accumulated along the chain)."""
    pos = np.zeros_like(OFFSETS)
    for j, p in enumerate(PARENTS):
        pos[j] = OFFSETS[j] + (pos[p] if p >= 0 else 0.0)
    return pos


def _walk(n_frames: int = T, speed: float = 0.3, swing: float = 0.4) -> np.ndarray:
    """``(T, J, 3)``: rest pose standing on the floor (y = 0) translated along x, the two limbs' ends swinging in z."""
    t = np.arange(n_frames, dtype=float)
    seq = np.repeat(_rest_pose()[None], n_frames, axis=0)
    seq[:, :, 1] += 2.0  # the limbs' ends (the feet) at y = 0
    seq[:, :, 0] += speed * t[:, None]
    seq[:, 5, 2] += swing * np.sin(t)
    seq[:, 7, 2] -= swing * np.sin(t)
    return seq


@pytest.fixture(scope="module")
def seqs() -> dict[str, np.ndarray]:
    gt = _walk()
    pred = gt + 0.05 * np.random.default_rng(0).standard_normal(gt.shape)
    lerp = np.linspace(gt[0], gt[-1], T)
    return {"ground truth": gt, "prediction": pred, "interpolation": lerp}


def test_render_png_valid_not_blank(tmp_path, seqs):
    keys = np.zeros(T, dtype=bool)
    keys[[0, -1]] = True
    out = render_png(seqs, PARENTS, tmp_path / "sub" / "seq.png", highlight=keys, title="walk", dpi=50)
    assert out.exists() and out.stat().st_size > 0
    with Image.open(out) as im:
        assert im.format == "PNG"
        arr = np.asarray(im.convert("RGB"))
    assert arr.shape[0] > 0 and arr.shape[1] > 0
    assert arr.std() > 0  # not a blank image


def test_render_png_grid_layout(tmp_path, seqs):
    out = render_png(seqs, PARENTS, tmp_path / "grid.png", frames=[0, 3], layout="grid", dpi=40)
    with Image.open(out) as im:
        w, h = im.size
    assert h > w / 3  # 2 rows of 3 panels


def test_render_gif_frame_count_and_shorter_sequence(tmp_path, seqs):
    short = dict(seqs, short=_walk(3))
    keys = np.zeros(T, dtype=bool)
    keys[0] = True
    out = render_gif(short, PARENTS, tmp_path / "anim.gif", fps=10, highlight=keys, dpi=30)
    with Image.open(out) as im:
        assert im.format == "GIF"
        assert im.n_frames == T
        assert im.info.get("loop") == 0
        assert im.info.get("duration") == 100


def test_figure_to_array(seqs):
    fig = draw_sequences(seqs, PARENTS, frames=[0, 2, 5])
    arr = figure_to_array(fig)
    assert arr.ndim == 3 and arr.shape[2] == 3 and arr.dtype == np.uint8
    w, h = fig.canvas.get_width_height()
    assert arr.shape[:2] == (h, w)
    assert arr.std() > 0


def test_different_sequences_give_different_images():
    a = figure_to_array(draw_sequences({"a": _walk()}, PARENTS, panel_size=2))
    b = figure_to_array(draw_sequences({"a": _walk(swing=1.5)}, PARENTS, panel_size=2))
    again = figure_to_array(draw_sequences({"a": _walk()}, PARENTS, panel_size=2))
    assert a.shape != b.shape or not np.array_equal(a, b)  # the framing follows the motion: the size may change
    assert np.array_equal(a, again)  # deterministic


def test_up_axis_changes_view():
    a = figure_to_array(draw_sequences({"a": _walk()}, PARENTS, up_axis=1, panel_size=2))
    b = figure_to_array(draw_sequences({"a": _walk()}, PARENTS, up_axis=2, panel_size=2))
    assert not np.array_equal(a, b)


def test_torch_input(tmp_path):
    torch = pytest.importorskip("torch")
    seq = torch.tensor(_walk(), requires_grad=True)
    arr = figure_to_array(draw_sequences({"t": seq * 1.0}, torch.tensor(PARENTS), panel_size=2))
    ref = figure_to_array(draw_sequences({"t": _walk()}, PARENTS, panel_size=2))
    assert np.array_equal(arr, ref)


def test_does_not_import_pyplot(tmp_path):
    """In a fresh interpreter (in this one, lightning has usually imported pyplot already): importing and using the
    renderer never imports pyplot, so the global matplotlib backend is left alone."""
    code = textwrap.dedent(f"""
        import sys
        import numpy as np
        from inbetweening.rendering.render import draw_sequences, figure_to_array, render_gif, render_png
        assert "matplotlib.pyplot" not in sys.modules, "imported by the module"
        seq = np.cumsum(np.ones((3, 8, 3)), axis=0)
        parents = {PARENTS!r}
        figure_to_array(draw_sequences({{"a": seq}}, parents, panel_size=1))
        render_png({{"a": seq}}, parents, {str(tmp_path / "a.png")!r}, dpi=20)
        render_gif({{"a": seq}}, parents, {str(tmp_path / "a.gif")!r}, dpi=20)
        assert "matplotlib.pyplot" not in sys.modules, "imported while drawing"
        print("no pyplot")
    """)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "no pyplot"


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"sequences": {}}, "empty"),
        ({"sequences": {"x": np.zeros((T, 8))}}, r"shape \(T, J, 3\)"),
        ({"sequences": {"x": np.zeros((T, 8, 4))}}, r"shape \(T, J, 3\)"),
        ({"sequences": {"x": np.zeros((T, 5, 3))}}, "J=5 joints but parents describes 8"),
        ({"sequences": {"x": np.zeros((0, 8, 3))}}, "no frames"),
        ({"sequences": {"x": np.full((T, 8, 3), np.nan)}}, "NaN"),
        ({"parents": [-1, 0, 5]}, "invalid parents"),
        ({"up_axis": 3}, "up_axis"),
        ({"highlight": np.zeros(T + 1, dtype=bool)}, "highlight"),
        ({"frames": [T]}, "out of range"),
        ({"layout": "spiral"}, "layout"),
        ({"columns": 0}, "columns"),
        ({"view": (10.0,)}, "view"),
        ({"feet": [8]}, r"feet \[8\] are not joint indices"),
        ({"feet": [5, 5]}, "twice"),
        ({"contacts": np.ones((T, 1), bool)}, "without feet"),
        ({"feet": [5], "contacts": np.ones((T + 1, 1), bool)}, r"must have shape \(6, 8\) \(every joint\) or \(6, 1\)"),
        ({"feet": [5], "contacts": {"y": np.ones((T, 1), bool)}}, "not labels of sequences"),
        ({"feet": [5], "contacts": np.full((T, 1), 0.7)}, "threshold a predicted contact first"),
    ],
)
def test_bad_input_messages(kwargs, match):
    args = {"sequences": {"x": _walk()}, "parents": PARENTS, **kwargs}
    with pytest.raises(ValueError, match=match):
        draw_sequences(**args)


def test_non_mapping_is_type_error():
    with pytest.raises(TypeError, match="must be a dict"):
        draw_sequences([_walk()], PARENTS)


def test_render_gif_bad_input(tmp_path):
    with pytest.raises(ValueError, match="fps"):
        render_gif({"x": _walk()}, PARENTS, tmp_path / "a.gif", fps=0)
    with pytest.raises(ValueError, match="parents describes"):
        render_gif({"x": _walk()}, PARENTS[:4], tmp_path / "a.gif")
    assert not (tmp_path / "a.gif").exists()


# ------------------------------------------------------------------ the picture itself: framing, floor, feet
def _mask(img: np.ndarray, color, tol: float = 0.06) -> np.ndarray:
    """Pixels within ``tol`` (per channel, 0-1) of ``color``."""
    return (np.abs(img.astype(float) / 255 - np.asarray(to_rgb(color))).max(axis=-1) < tol)


def _panel_pixels(fig, img: np.ndarray) -> list[np.ndarray]:
    """Each axes' pixels (top-to-bottom rows), in the order the panels were added."""
    h = img.shape[0]
    out = []
    for ax in fig.axes:
        b = ax.get_window_extent()
        out.append(img[int(round(h - b.y1)) : int(round(h - b.y0)), int(round(b.x0)) : int(round(b.x1))])
    return out


def _span(mask: np.ndarray) -> tuple[float, float]:
    """The fraction of the panel's height and width that the True pixels span."""
    rows, cols = np.nonzero(mask.any(axis=1))[0], np.nonzero(mask.any(axis=0))[0]
    if len(rows) == 0:
        return 0.0, 0.0
    return (rows[-1] - rows[0] + 1) / mask.shape[0], (cols[-1] - cols[0] + 1) / mask.shape[1]


def test_png_is_readme_width_and_the_body_fills_its_panel(tmp_path, seqs):
    """Three labels at the defaults: a 900 px picture, each skeleton spanning most of its panel's height (the old
    cubic 3-D box left it a third), wholly inside the panel."""
    out = render_png(seqs, PARENTS, tmp_path / "strip.png", frames=[0, T - 1])
    with Image.open(out) as im:
        assert im.size[0] == 900
    fig = draw_sequences(seqs, PARENTS, frames=[0, T - 1])
    panels = _panel_pixels(fig, figure_to_array(fig))
    assert len(panels) == 3
    for panel, color in zip(panels, PALETTE):
        body = _mask(panel, color)
        tall, wide = _span(body)
        assert tall > 0.6, (color, tall)
        assert not body[0].any() and not body[-1].any() and not body[:, 0].any() and not body[:, -1].any()


def test_the_floor_is_drawn_under_the_body(seqs):
    fig = draw_sequences({"a": _walk()}, PARENTS)
    (panel,) = _panel_pixels(fig, figure_to_array(fig))
    floor = _mask(panel, FLOOR_COLOR, tol=0.02)
    assert floor.mean() > 0.1  # a real area, not a line
    rows = np.nonzero(floor.any(axis=1))[0]
    body_rows = np.nonzero(_mask(panel, PALETTE[0]).any(axis=1))[0]
    assert rows.mean() > body_rows.mean()  # below the body's middle (image rows grow downwards)
    fig = draw_sequences({"a": _walk()}, PARENTS, floor=None)
    (panel,) = _panel_pixels(fig, figure_to_array(fig))
    assert not _mask(panel, FLOOR_COLOR, tol=0.02).any()


def _planted_walk(n: int = 10, hold: bool = False) -> np.ndarray:
    """A walk whose limb end 5 is on the floor the whole time: dragged along with the body (``hold=False``: a
    sliding foot) or held at its first position (``hold=True``: a locked foot)."""
    seq = _walk(n, speed=0.4, swing=0.0)
    if hold:
        seq[:, 5] = seq[0, 5]
    return seq


def test_a_sliding_planted_foot_draws_a_streak_a_still_one_a_dot():
    seqs = {"sliding": _planted_walk(), "locked": _planted_walk(hold=True), "no contacts": _planted_walk()}
    planted = np.ones((10, 1), dtype=bool)
    fig = draw_sequences(seqs, PARENTS, feet=[5], contacts={"sliding": planted, "locked": planted})
    sliding, locked, none = (_mask(p, CONTACT_COLOR, tol=0.08) for p in _panel_pixels(fig, figure_to_array(fig)))
    assert not none.any()  # the contact colour appears only where a foot is planted
    assert sliding.sum() > 4 * locked.sum() > 0
    assert _span(sliding)[1] > 0.3 and _span(locked)[1] < 0.1  # a streak a third of the panel wide vs a dot
    # the foot's trail (thin, the label's colour) is drawn without contacts too, and a contact marks it over
    again = draw_sequences(seqs, PARENTS, feet=[5], contacts={"sliding": np.ones((10, 8), bool)})
    assert np.array_equal(_mask(_panel_pixels(again, figure_to_array(again))[0], CONTACT_COLOR, tol=0.08), sliding)


def test_a_wide_motion_stacks_its_panels_at_the_same_width():
    far = {label: _walk(20, speed=3.0) for label in ("a", "b", "c")}  # travels 57 units, 5 tall
    fig = draw_sequences(far, PARENTS)
    xs = {round(ax.get_position().x0, 3) for ax in fig.axes}
    assert xs == {0.0} and fig.get_size_inches()[0] == pytest.approx(9.0)  # one column, 900 px at 100 dpi
    near = draw_sequences({label: _walk() for label in ("a", "b", "c")}, PARENTS)
    assert len({round(ax.get_position().x0, 3) for ax in near.axes}) == 3  # compact: side by side


def test_the_gif_follows_the_body(tmp_path):
    """A body that travels twelve times its height stays in the middle of its panel from the first frame to the
    last, as tall as in the first frame; the floor's grid scrolls under it."""
    out = render_gif({"a": _walk(20, speed=3.0)}, PARENTS, tmp_path / "far.gif", dpi=60, feet=[5, 7])
    frames = []
    with Image.open(out) as im:
        assert im.n_frames == 20
        for i in (0, 19):
            im.seek(i)
            frames.append(np.asarray(im.convert("RGB")))
    spans, centres = [], []
    for img in frames:
        body = _mask(img, PALETTE[0], tol=0.1)
        rows, cols = np.nonzero(body)
        spans.append(_span(body)[0])
        centres.append(cols.mean() / img.shape[1])
    assert min(spans) > 0.45 and abs(spans[0] - spans[1]) < 0.1
    assert abs(centres[0] - centres[1]) < 0.1 and 0.3 < centres[0] < 0.7
    assert _mask(frames[0], FLOOR_COLOR, tol=0.03).mean() > 0.05
