"""The Blender extension without Blender: the build command's argument errors, the exported window graph against
the Predictor (ONNX Runtime vs PyTorch), and the extension's numpy engine against the project's own functions."""
from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from inbetweening.blender.extension import engine
from inbetweening.geometry import canonical
from inbetweening.geometry.quaternion import remove_discontinuities, slerp_np
from inbetweening.predictor import masks
from inbetweening.tools.export import WindowPath, export_onnx, export_window_onnx

REPO = Path(__file__).resolve().parents[1]
CKPT = REPO / "models" / "bn2_reference" / "model.ckpt"
EXT = REPO / "src" / "inbetweening" / "blender" / "extension"


def cli(*args, cwd=REPO):
    return subprocess.run([sys.executable, "-m", "inbetweening.blender", *map(str, args)], capture_output=True,
                          text=True, cwd=cwd)


@pytest.mark.parametrize("args, needle", [
    ((), "usage"),
    (("build",), "exactly one OUT_DIR"),
    (("build", "a", "b"), "exactly one OUT_DIR"),
    (("frobnicate",), "unknown command 'frobnicate'"),
    (("build", "OUT", "platforms=amiga-68k"), "unknown amiga-68k"),
    (("build", "OUT", "onnxruntime=latest"), "not a version number"),
    (("build", "OUT", "colour=red"), "unknown option 'colour'"),
    (("build", "OUT", "ckpt_path=/nonexistent/model.ckpt", "platforms=linux-x64"), "does not exist"),
    (("export", "ckpt_path=x.ckpt"), "missing output=..."),
    (("export", f"ckpt_path={CKPT}", "output=model.txt"), "must end in .onnx"),
])
def test_cli_errors_are_one_line_exit_2(args, needle, tmp_path):
    proc = cli(*[a.replace("OUT", str(tmp_path / "out")) for a in args])
    assert proc.returncode == 2, proc
    assert needle in (proc.stderr + proc.stdout)
    assert "Traceback" not in proc.stderr
    if args:
        assert proc.stderr.startswith("error: ") and proc.stderr.count("\n") == 1


def test_cli_out_dir_that_is_a_file(tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    proc = cli("build", f, "platforms=linux-x64")
    assert proc.returncode == 2 and "is not a folder" in proc.stderr and "Traceback" not in proc.stderr


def test_neighbour_known_without_cummax_is_exact():
    g = torch.Generator().manual_seed(0)
    for shape in [(3, 26, 21), (2, 7, 5), (1, 1, 3)]:
        known = torch.rand(*shape, generator=g) < 0.4
        known[0, :, 0] = False  # a joint with no known frame at all
        for a, b in zip(masks._neighbour_known(known), masks._neighbour_known_exportable(known)):
            assert torch.equal(a, b)


@pytest.fixture(scope="module")
def inbetweener():
    from inbetweening.tools.inbetweener import Inbetweener

    return Inbetweener.from_checkpoint(CKPT)


@pytest.fixture(scope="module")
def window_model(inbetweener, tmp_path_factory):
    path = tmp_path_factory.mktemp("onnx") / "model.onnx"
    info = export_window_onnx(inbetweener, path)
    assert info["max_abs_diff"] < 1e-4
    return engine.Model(str(path))


def test_window_graph_matches_the_predictor(inbetweener, window_model):
    """ONNX Runtime on the window graph vs PyTorch: the graph's own module on canonical windows, and
    ``Predictor.fill_windows`` (world space; the extension's numpy canonical frame around the graph)."""
    p = inbetweener.predictor
    rng = np.random.default_rng(3)
    for gap in (1, 15, 40):
        t = p.n_past + gap + 1
        root = np.array([0.0, 90.0, 0.0]) + rng.normal(0, 20, (2, t, 3))
        root[..., [0, 2]] += rng.normal(0, 300, (2, 1, 2))  # anywhere on the floor
        q = rng.normal(size=(2, t, p.skeleton.num_joints, 4))
        q /= np.linalg.norm(q, axis=-1, keepdims=True)
        known = p.transition_known(2, t, gap)
        got_r, got_q = window_model.predict(root, q, known.numpy())
        with torch.no_grad():
            ref_r, ref_q = WindowPath(p)(torch.from_numpy(root), torch.from_numpy(q), known)
        sl = slice(p.n_past, p.n_past + gap)
        assert np.abs(got_r[:, sl] - ref_r[:, sl].numpy()).max() <= 1e-4
        assert np.abs(got_q[:, sl] - ref_q[:, sl].numpy()).max() <= 1e-4
        wr, wq = window_model.fill_windows(root, q)
        pr, pq = p.fill_windows(root, q)
        assert np.abs(wr - pr).max() <= 1e-4 and np.abs(wq - pq).max() <= 1e-4


def test_window_graph_metadata(window_model, inbetweener):
    m = window_model
    assert m.names == list(inbetweener.skeleton.names) and m.n_past == inbetweener.n_past
    assert m.trained_gap == inbetweener.trained_gap
    assert np.allclose(m.offsets, inbetweener.skeleton.offsets)


def clip(frames=200, joints=21, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(frames)
    root = np.stack([60 * np.sin(t / 40), 90 + 3 * np.sin(t / 7), 2.5 * t], -1)
    ang = 0.4 * np.sin(t[:, None, None] / rng.uniform(8, 20, (1, joints, 3)) + rng.uniform(0, 6, (1, joints, 3)))
    q = np.concatenate([np.ones((frames, joints, 1)), ang], -1)
    q[:, 0] = np.stack([np.cos(t / 60), 0 * t, np.sin(t / 60), 0 * t], -1)  # turning about +Y
    return root, q / np.linalg.norm(q, axis=-1, keepdims=True)


@pytest.mark.parametrize("keys", [[0, 15, 30, 45, 60, 90, 120, 150, 199], [0, 1, 2, 70, 199], [0, 199]])
def test_engine_fill_matches_the_inbetweener(inbetweener, window_model, keys):
    """The extension's gap planning (pseudo-keyframes of long gaps included), context and frame change give the
    Inbetweener's poses; the keys and the frames outside the keys come back bit for bit."""
    root, q = clip()
    ref_r, ref_q = inbetweener.fill_arrays(root, q, keys)
    got_r, got_q = engine.fill(window_model, root, q, keys)
    sk = inbetweener.skeleton
    err = np.abs(sk.pose(ref_r, ref_q)[1] - sk.pose(got_r, got_q)[1]).max()
    assert err <= 1e-3, err
    assert np.array_equal(got_r[keys], root[keys]) and np.array_equal(got_q[keys], q[keys])


def test_engine_context_before_the_first_key_and_frames_after(window_model):
    """Frames before the first key are context (read, not written); frames after the last key are untouched."""
    root, q = clip(120)
    keys = [20, 50, 80]
    got_r, got_q = engine.fill(window_model, root, q, keys)
    assert np.array_equal(got_r[:21], root[:21]) and np.array_equal(got_q[80:], q[80:])
    assert not np.allclose(got_r[21:50], root[21:50])
    other = root.copy()
    other[11:20] += 50.0  # different context -> a different first gap
    assert not np.allclose(engine.fill(window_model, other, q, keys)[0][21:50], got_r[21:50])


def test_engine_geometry_matches_the_project():
    rng = np.random.default_rng(1)
    q = rng.normal(size=(50, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    for fwd in ([0.0, 0.0, 1.0], [0.0, 1.0, 0.0]):
        ref = canonical.facing_rotation(q, fwd)
        ref = ref / np.linalg.norm(ref, axis=-1, keepdims=True)
        assert np.abs(engine.facing_rotation(q, fwd) - ref).max() < 1e-12
    q2 = rng.normal(size=(50, 4))
    w = rng.uniform(size=(50, 1))
    assert np.abs(engine.slerp(q, q2, w[:, 0]) - slerp_np(q, q2, w[:, 0])).max() < 1e-12
    assert np.array_equal(engine.continuous(q[:, None]), remove_discontinuities(q[:, None], axis=0))


def test_model_errors(tmp_path, inbetweener):
    with pytest.raises(engine.ModelError, match="not found"):
        engine.Model(str(tmp_path / "none.onnx"))
    (tmp_path / "junk.onnx").write_bytes(b"\x00junk")
    with pytest.raises(engine.ModelError, match="not a readable ONNX model"):
        engine.Model(str(tmp_path / "junk.onnx"))
    export_onnx(inbetweener.predictor, tmp_path / "net.onnx", check=False)  # the bare network: not the window graph
    with pytest.raises(engine.ModelError, match="not an in-betweening window model"):
        engine.Model(str(tmp_path / "net.onnx"))


def test_extension_sources_need_no_torch():
    """Inside Blender only numpy, onnxruntime, bpy/mathutils and the extension's own modules are imported."""
    allowed = {"numpy", "onnxruntime", "bpy", "mathutils", "bpy_extras", "__future__", "os", "json", "math",
               "itertools", "time", "importlib"}
    for f in EXT.glob("*.py"):
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                names = [node.module]
            else:
                continue
            assert all(n.split(".")[0] in allowed for n in names), (f.name, names)
