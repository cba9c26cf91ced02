"""``python -m inbetweening.export``: ONNX export of a trained network, checked against ONNX Runtime."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from inbetweening.api import export
from inbetweening.cli.export import run as export_cli
from inbetweening.training.module import load_module

ort = pytest.importorskip("onnxruntime")
onnx = pytest.importorskip("onnx")


@pytest.fixture(scope="module")
def exported(tiny_checkpoint, tmp_path_factory):
    path = tmp_path_factory.mktemp("onnx") / "model.onnx"
    assert export_cli([f"ckpt_path={tiny_checkpoint}", "format=onnx", f"output={path}", "opset=17"]) == 0
    return path, load_module(str(tiny_checkpoint))


@pytest.mark.parametrize(("batch", "gap"), [(1, 30), (5, 4)])
def test_onnxruntime_matches_pytorch(exported, batch, gap):
    path, module = exported
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    x, known, interp = export.random_window(module, batch, gap, seed=batch)
    got = export._run_ort(session, x, known, interp)
    with torch.no_grad():
        ref = module.net.eval()(x, known, interp).numpy()
    assert got.shape == ref.shape == (batch, module.n_past + gap + 1, module.skeleton.num_joints, 7)
    assert np.abs(got - ref).max() <= 1e-4


def test_metadata_describes_the_inputs(exported):
    path, module = exported
    meta = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"]).get_modelmeta().custom_metadata_map
    props = {k: json.loads(v) for k, v in meta.items()}
    assert props["skeleton_names"] == list(module.skeleton.names)
    assert props["skeleton_parents"] == list(module.skeleton.parents)
    assert np.allclose(props["skeleton_offsets"], module.skeleton.offsets)
    assert np.allclose(props["pos_mean"], module.mean) and np.allclose(props["pos_std"], module.std)
    assert props["mask"] == "lerp" and props["n_past"] == 10 and props["forward_axis"] == [0.0, 0.0, 1.0]
    graph_inputs = [i.name for i in onnx.load(str(path)).graph.input]
    assert props["inputs"] == graph_inputs and graph_inputs[:2] == ["x", "known"]


def _ort_vs_torch(path, module, batch: int, gap: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Run the .onnx file with ONNX Runtime on inputs built here (not by the exporter's helpers) and the torch
    network on the same inputs.  Returns ``(onnx output, torch output)``."""
    from inbetweening.predictor.masks import apply_mask
    from inbetweening.representation import GlobalPosLocalQuat

    g = torch.Generator().manual_seed(seed)
    j, n_past = module.skeleton.num_joints, module.n_past
    t = n_past + gap + 1
    quat = torch.randn(batch, t, j, 4, generator=g)
    feats = torch.cat([torch.randn(batch, t, j, 3, generator=g), quat / quat.norm(dim=-1, keepdim=True)], -1)
    known = torch.zeros(batch, t, j, dtype=torch.bool)
    known[:, :n_past] = True
    known[:, n_past + gap] = True
    x, interp = apply_mask(module.mask_name, feats, known, GlobalPosLocalQuat)  # [pos 0:3, quat 3:7]
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    names = [i.name for i in session.get_inputs()]
    assert names[:2] == ["x", "known"] and set(names) <= {"x", "known", "interp"}
    feeds = {"x": x.numpy(), "known": known.numpy(), "interp": interp.numpy()}
    (got,) = session.run(None, {k: feeds[k] for k in names})
    with torch.no_grad():
        ref = module.net.eval()(x, known, interp).numpy()
    return got, ref


def test_export_prints_check(tiny_checkpoint, tmp_path, capsys):
    assert export_cli(["--ckpt_path", str(tiny_checkpoint), "--output", str(tmp_path / "m.onnx")]) == 0
    out = capsys.readouterr().out
    diff = float(out.rsplit("max abs diff", 1)[1])
    assert diff <= 1e-4
    # the printed number is the exporter's own claim: check the written file independently of check_onnx
    module = load_module(str(tiny_checkpoint))
    for batch, gap in ((2, 6), (1, 25)):
        got, ref = _ort_vs_torch(tmp_path / "m.onnx", module, batch, gap, seed=10 + gap)
        assert got.shape == ref.shape == (batch, module.n_past + gap + 1, module.skeleton.num_joints, 7)
        np.testing.assert_allclose(got, ref, atol=1e-4, rtol=0)


def test_check_onnx_reports_a_real_difference(exported, tiny_checkpoint):
    """check_onnx must measure: against a network whose weights changed after the export it reports a large
    difference (and the independent comparison above can tell the two graphs apart too)."""
    path, module = exported
    assert export.check_onnx(module, path) <= 1e-4
    changed = load_module(str(tiny_checkpoint))  # a fresh copy: the fixture's module stays untouched
    with torch.no_grad():
        for p in changed.net.parameters():
            p.add_(0.5)
    got, ref = _ort_vs_torch(path, changed, 2, 6, seed=3)
    assert np.abs(got - ref).max() > 1e-2
    assert export.check_onnx(changed, path) > 1e-2


@pytest.mark.parametrize(
    ("argv", "msg"),
    [
        (["ckpt_path=x.ckpt", "format=tflite", "output=m"], "format: unknown export format 'tflite'; supported: onnx"),
        (["ckpt_path=missing.ckpt", "output=m.onnx"], "ckpt_path: missing.ckpt does not exist"),
        (["format=onnx"], "missing ckpt_path=..., output=..."),
        (["ckpt_path=x", "output=m", "opset=new"], "opset:"),
    ],
)
def test_export_errors(argv, msg, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exc:
        export_cli(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and msg in err and len(err.strip().splitlines()) == 1


def test_inference_only_checkpoint_loads_alone(tiny_checkpoint, tmp_path):
    import subprocess
    import sys

    from inbetweening.training.module import InbetweenModule

    out = tmp_path / "model.ckpt"
    r = subprocess.run([sys.executable, "-m", "inbetweening.export", f"ckpt_path={tiny_checkpoint}", "format=ckpt",
                        f"output={out}"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    slim = torch.load(out, weights_only=False)
    assert "optimizer_states" not in slim and all(k.startswith("net.") for k in slim["state_dict"])
    assert out.stat().st_size < Path(tiny_checkpoint).stat().st_size
    a = InbetweenModule.load_from_checkpoint(tiny_checkpoint, map_location="cpu").eval()
    b = InbetweenModule.load_from_checkpoint(out, map_location="cpu").eval()
    for (ka, va), (kb, vb) in zip(a.net.state_dict().items(), b.net.state_dict().items()):
        assert ka == kb and torch.equal(va, vb)


def test_window_graph_of_a_contact_model_with_the_gate(tiny_contact_checkpoint, tmp_path):
    """The Blender extension's window graph exports for a model with foot contact channels and the gate."""
    pytest.importorskip("onnxruntime")
    from inbetweening.api.export import export_window_onnx
    from inbetweening.predictor.checkpoint import load_predictor

    info = export_window_onnx(load_predictor(str(tiny_contact_checkpoint)), tmp_path / "w.onnx")
    assert info["max_abs_diff"] < 1e-4 and info["metadata"]["contact_slice"] == "[7, 8]"


def test_window_graph_carries_the_do_no_harm_blend(tiny_contact_checkpoint, tmp_path):
    """A calibrated predictor's blend is part of the window graph the Blender extension runs, its weights an input
    (the runtime's): ONNX Runtime with weight 1 is the unblended graph, with the blend's weights it differs."""
    ort = pytest.importorskip("onnxruntime")
    from inbetweening.api.export import export_window_onnx, window_example
    from inbetweening.predictor.checkpoint import load_predictor

    plain = load_predictor(str(tiny_contact_checkpoint))
    torch.manual_seed(0)
    with torch.no_grad():  # a network whose correction is visible
        for p in plain.net.parameters():
            p.add_(0.05 * torch.randn_like(p))
    blended = load_predictor(str(tiny_contact_checkpoint))
    blended.load_state_dict(plain.state_dict())
    blended.blend = (0.0, 0.25, 0.5, 0.75, 1.0)
    outs = []
    for name, pred in (("plain", plain), ("blended", blended)):
        info = export_window_onnx(pred, tmp_path / f"{name}.onnx")
        assert info["max_abs_diff"] < 1e-4
        root, q, known, weight = window_example(pred, 2, 3, seed=5)
        sess = ort.InferenceSession(str(tmp_path / f"{name}.onnx"), providers=["CPUExecutionProvider"])
        feeds = {"root": root.numpy(), "local_q": q.numpy(), "known": known.numpy()}
        inputs = {i.name for i in sess.get_inputs()}
        assert ("weight" in inputs) == (name == "blended")  # only a model with a blend reads the weights
        outs.append(sess.run(None, feeds if name == "plain" else {**feeds, "weight": np.full(weight.shape, 0.5, np.float32)}))
        if name == "blended":
            ones = sess.run(None, {**feeds, "weight": np.ones(weight.shape, np.float32)})
    assert json.loads(info["metadata"]["blend"]) == [0.0, 0.25, 0.5, 0.75, 1.0]
    assert np.abs(outs[0][0] - outs[1][0]).max() > 1e-3  # weight 0.5 moved the prediction
    assert np.abs(outs[0][0] - ones[0]).max() < 1e-4  # weight 1: the network as it is


def test_the_window_graph_is_saved_folded_with_the_same_outputs(tiny_contact_checkpoint, tmp_path):
    """The exported window graph carries ONNX Runtime's basic optimisations (constants folded), so a session loads it
    without optimising: fewer nodes than ``torch.onnx.export`` writes (exported here with the test's own call), standard
    operators only, and bit for bit the outputs of that plain export, run as exported or with the same optimisations
    at load."""
    from inbetweening.api.export import export_window_onnx, window_example
    from inbetweening.predictor.checkpoint import load_predictor
    from inbetweening.runtime.torch_backend import WindowPath

    pred = load_predictor(str(tiny_contact_checkpoint)).eval()
    export_window_onnx(pred, tmp_path / "folded.onnx")
    example = window_example(pred, 2, 15)
    names = ["root", "local_q", "known", "weight"]
    with torch.no_grad():
        outputs = [f"out{i}" for i in range(len(WindowPath(pred)(*example)))]
        torch.onnx.export(WindowPath(pred).eval(), example, str(tmp_path / "plain.onnx"), dynamo=False, opset_version=17,
                          input_names=names, output_names=outputs,
                          dynamic_axes={k: {0: "batch", 1: "frames"} for k in names + outputs})
    folded, plain = onnx.load(str(tmp_path / "folded.onnx")), onnx.load(str(tmp_path / "plain.onnx"))
    assert len(folded.graph.node) < 0.8 * len(plain.graph.node)
    assert {n.domain for n in folded.graph.node} <= {"", "ai.onnx"}
    assert {o.domain for o in folded.opset_import} <= {"", "ai.onnx"}
    onnx.checker.check_model(folded)
    off, basic = ort.SessionOptions(), ort.SessionOptions()
    off.graph_optimization_level = ort.GraphOptimizationLevel.ORT_DISABLE_ALL
    basic.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_BASIC
    sessions = [ort.InferenceSession(str(tmp_path / f), o, providers=["CPUExecutionProvider"])
                for f, o in (("folded.onnx", off), ("plain.onnx", off), ("plain.onnx", basic))]
    for gap, seed in ((3, 1), (29, 2)):
        root, q, known, weight = window_example(pred, 3, gap, seed)
        feeds = {"root": root.numpy(), "local_q": q.numpy(), "known": known.numpy(), "weight": weight.numpy()}
        runs = [s.run(None, {k: v for k, v in feeds.items() if k in {i.name for i in s.get_inputs()}}) for s in sessions]
        for other in runs[1:]:
            assert all(np.array_equal(a, b) for a, b in zip(runs[0], other))
