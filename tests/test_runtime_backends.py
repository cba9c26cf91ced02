"""The runtime's two backends agree: the exported window graph on ONNX Runtime (what Blender fills with) against the
trained module in PyTorch (what the CLI, the API and ``eval.py`` fill with), window by window and on whole fills of
the models (``bn2_reference`` exported here; the shipped ensemble's committed graphs ``models/<name>/model.onnx``
against their checkpoints, so a checkpoint and its graph cannot drift apart; ``bn2_v2``: contact channels, feet
locked); the ONNX backend's errors; the runtime fills without PyTorch, from the very wheel the Blender extension
bundles."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch

from characters import wiggle
from conftest import BLOCK_TORCH
from inbetweening.api.export import export_onnx, export_window_onnx, window_example
from inbetweening.api.shipped import SHIPPED, SHIPPED_CKPTS, SHIPPED_ONNX
from inbetweening.runtime import FillRuntime, ModelError
from inbetweening.runtime.onnx_backend import OnnxBackend
from inbetweening.runtime.torch_backend import TorchBackend, WindowPath

REPO = Path(__file__).resolve().parents[1]
MODELS = {"bn2_reference": REPO / "models" / "bn2_reference" / "model.ckpt",
          **{name: REPO / ckpt for name, ckpt in zip(SHIPPED, SHIPPED_CKPTS)}}
GRAPHS = {name: REPO / graph for name, graph in zip(SHIPPED, SHIPPED_ONNX)}  # committed: predict's default


@pytest.fixture(scope="module", params=list(MODELS))
def backends(request, tmp_path_factory):
    torch_backend = TorchBackend.from_checkpoint(MODELS[request.param])
    path = GRAPHS.get(request.param)
    if path is None:
        path = tmp_path_factory.mktemp("onnx") / "model.onnx"
        info = export_window_onnx(torch_backend.predictor, path, trained_gap=torch_backend.info.trained_gap)
        assert info["max_abs_diff"] < 1e-4
    return torch_backend, OnnxBackend(str(path))


clip = wiggle  # a smooth random motion of the model's 21 joints (tests/characters.py)


def test_both_backends_describe_the_model_alike(backends):
    tb, ob = backends
    assert tb.info == ob.info
    assert ob.info.has_contacts == ("contact" in tb.predictor.representation.channels())


def test_the_window_graph_is_the_window_path(backends):
    tb, ob = backends
    for gap in (1, 15, 40):
        root, q, known, weight = window_example(tb.predictor, 2, gap, seed=gap)
        got = ob.predict(root.numpy(), q.numpy(), known.numpy(), weight.numpy())
        with torch.no_grad():
            ref = WindowPath(tb.predictor)(root, q, known, weight)
        sl = slice(tb.info.n_past, tb.info.n_past + gap)
        for a, b in zip(got, ref):
            assert np.abs(a[:, sl] - b[:, sl].numpy()).max() <= 1e-4
        assert (got[2] is None) == (len(ref) == 2)


@pytest.mark.parametrize("keys", [[0, 15, 30, 45, 60, 90, 120, 150, 199], [0, 1, 2, 70, 199], [0, 199]])
def test_torch_and_onnx_fills_agree(backends, keys):
    """The whole fill (gap plan with pseudo-keyframes, context, canonical frame, blend, foot locking, keys exact):
    the same poses from either backend within 1e-3 cm after FK.  Measured (largest joint distance over the clip):
    0.9e-4 to 1.1e-4 cm for bn2_reference, 1.9e-4 to 4.6e-4 cm for bn2_v2, locked or not: float32 rounding of the
    network's kernels (ONNX Runtime's against PyTorch's), carried through chained windows."""
    tb, ob = backends
    root, q = clip()
    a = FillRuntime(tb).fill(root, q, keys)
    b = FillRuntime(ob).fill(root, q, keys)
    sk = tb.info.skeleton
    err = np.abs(sk.pose(a.root, a.local_q)[1] - sk.pose(b.root, b.local_q)[1]).max()
    assert err <= 1e-3, err
    assert a.locked and b.locked  # every model locks its feet (a model without contact channels: detected on the fill)
    assert np.array_equal(b.root[keys], root[keys]) and np.array_equal(b.local_q[keys], q[keys])


def test_onnx_backend_errors(tmp_path):
    with pytest.raises(ModelError, match="not found"):
        OnnxBackend(str(tmp_path / "none.onnx"))
    (tmp_path / "junk.onnx").write_bytes(b"\x00junk")
    with pytest.raises(ModelError, match="not a readable ONNX model"):
        OnnxBackend(str(tmp_path / "junk.onnx"))
    export_onnx(TorchBackend.from_checkpoint(MODELS["bn2_reference"]).predictor, tmp_path / "net.onnx", check=False)
    with pytest.raises(ModelError, match="net.onnx is not an in-betweening window model"):  # the bare network
        OnnxBackend(str(tmp_path / "net.onnx"))


NO_TORCH = BLOCK_TORCH + """
import json
import numpy as np
import inbetweening
from inbetweening.runtime import FillRuntime
from inbetweening.runtime.onnx_backend import OnnxBackend
cfg = json.load(open(sys.argv[1]))
d = np.load(cfg["clip"])
out = FillRuntime(OnnxBackend(cfg["model"])).fill(d["root"], d["q"], cfg["keys"])
np.savez(cfg["out"], root=out.root, q=out.local_q)
print(inbetweening.__file__, "torch" in sys.modules)
"""


def test_the_bundled_runtime_fills_without_torch(backends, tmp_path):
    """Unpack the runtime wheel the extension build makes, block PyTorch, fill with the ONNX backend: the result is the
    in-tree runtime's, and the modules came from the wheel."""
    from inbetweening.blender.build import runtime_wheel

    _, ob = backends
    site = tmp_path / "site"
    with zipfile.ZipFile(runtime_wheel(tmp_path, "0.0.1")) as z:
        z.extractall(site)
    root, q = clip(120)
    keys = [0, 10, 50, 119]
    np.savez(tmp_path / "clip.npz", root=root, q=q)
    cfg = {"clip": str(tmp_path / "clip.npz"), "model": ob.path, "keys": keys, "out": str(tmp_path / "out.npz")}
    (tmp_path / "cfg.json").write_text(json.dumps(cfg))
    (tmp_path / "run.py").write_text(NO_TORCH)
    proc = subprocess.run([sys.executable, str(tmp_path / "run.py"), str(tmp_path / "cfg.json")], capture_output=True,
                          text=True, env={**os.environ, "PYTHONPATH": str(site)}, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    where, imported = proc.stdout.split()
    assert where.startswith(str(site)) and imported == "False"
    got = np.load(tmp_path / "out.npz")
    ref = FillRuntime(ob).fill(root, q, keys)
    assert np.array_equal(got["root"], ref.root) and np.array_equal(got["q"], ref.local_q)
