"""Tests for the headless skeleton renderer (:mod:`inbetweening.tools.render`)."""
from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest
from PIL import Image

from inbetweening.tools.render import draw_sequences, figure_to_array, render_gif, render_png

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
    """``(T, J, 3)``: rest pose translated along x, with the two limbs' ends swinging in z."""
    t = np.arange(n_frames, dtype=float)
    seq = np.repeat(_rest_pose()[None], n_frames, axis=0)
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
    assert a.shape == b.shape
    assert not np.array_equal(a, b)
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
        from inbetweening.tools.render import draw_sequences, figure_to_array, render_gif, render_png
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
