"""The Blender extension without Blender: the build command's argument errors, the models it bundles (by default the
shipped ensemble of bn2_partial, bn2_partial_twin and bn2_v2) and the model the extension fills with
(:func:`load_model`: their ensemble, or a user's model file alone), the runtime wheel it bundles (the project's own
runtime modules, importable and filling without PyTorch), and what the extension's sources import.  The ONNX backend
against the torch one: tests/test_runtime_backends.py."""
from __future__ import annotations

import ast
import importlib.util
import json
import subprocess
import sys
import types
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch

from inbetweening.predictor import masks

REPO = Path(__file__).resolve().parents[1]
CKPTS = [REPO / "models" / name / "model.ckpt" for name in ("bn2_partial", "bn2_partial_twin", "bn2_v2")]  # bundled
CKPT = CKPTS[0]
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
    (("build", "OUT", f"ckpt_path=[{CKPT},/nonexistent/model.ckpt]", "platforms=linux-x64"),
     "ckpt_path: /nonexistent/model.ckpt does not exist"),
    (("build", "OUT", f"ckpt_path=[{CKPT},{CKPT}]", "platforms=linux-x64"), f"ckpt_path: {CKPT} is given twice"),
    (("build", "OUT", "ckpt_path=[]"), "ckpt_path: no path given"),
    (("export", f"ckpt_path=[{CKPT},{CKPTS[1]}]", "output=model.onnx"), "export takes one checkpoint"),
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


def test_the_runtime_wheel_holds_the_runtime_and_what_it_imports(tmp_path):
    from inbetweening.blender.build import runtime_modules, runtime_wheel

    mods = runtime_modules()
    assert "inbetweening.runtime.fill" in mods and "inbetweening.runtime.onnx_backend" in mods
    dcc = REPO / "src" / "inbetweening" / "dcc"  # the DCC core the extension fills through, every module of it
    assert {m for m in mods if m.startswith("inbetweening.dcc")} == {"inbetweening.dcc"} | {
        f"inbetweening.dcc.{f.stem}" for f in dcc.glob("*.py") if f.stem != "__init__"}
    assert "inbetweening.geometry.ik" in mods and "inbetweening.data.contacts" in mods
    assert "inbetweening.runtime.torch_backend" not in mods and not any(m.startswith("inbetweening.tools") for m in mods)
    whl = runtime_wheel(tmp_path, "9.9")
    with zipfile.ZipFile(whl) as z:
        names = set(z.namelist())
        record = z.read("inbetweening_runtime-9.9.dist-info/RECORD").decode()
        src = z.read("inbetweening/runtime/fill.py")
    assert "inbetweening/runtime/fill.py" in names and "inbetweening/__init__.py" in names
    assert "inbetweening/dcc/fill.py" in names and "inbetweening/dcc/host.py" in names
    assert src == (REPO / "src" / "inbetweening" / "runtime" / "fill.py").read_bytes()  # the file itself, no copy
    assert all(n in record for n in names if not n.endswith("RECORD"))


def test_a_runtime_module_that_imports_torch_fails_the_build(monkeypatch):
    from inbetweening.blender import build

    monkeypatch.setattr(build, "RUNTIME_LEFT_OUT", ())  # torch_backend imports torch at the top
    with pytest.raises(build.BuildError, match=r"inbetweening.runtime.torch_backend imports torch"):
        build.runtime_modules()


def test_a_dcc_core_module_that_imports_bpy_or_torch_fails_the_build(monkeypatch, tmp_path):
    """The DCC core is bundled under the runtime's rule: a module of it importing a host's module (``bpy``) or
    PyTorch fails the build, naming it."""
    from inbetweening.blender import build

    real = build._module_file
    bad = tmp_path / "bad.py"
    for module in ("bpy", "torch"):
        bad.write_text(f"import numpy\nimport {module}\n")
        monkeypatch.setattr(build, "_module_file", lambda name: bad if name == "inbetweening.dcc.keys" else real(name))
        with pytest.raises(build.BuildError, match=rf"inbetweening.dcc.keys imports {module}: the bundled runtime"):
            build.runtime_modules()


def test_extension_sources_need_no_torch():
    """Inside Blender only numpy, onnxruntime, bpy/mathutils, the extension's own modules and the bundled runtime's
    modules are imported."""
    from inbetweening.blender.build import runtime_modules

    bundled = set(runtime_modules())
    allowed = {"numpy", "onnxruntime", "bpy", "mathutils", "bpy_extras", "__future__", "os", "json", "math",
               "itertools", "time", "importlib", "hashlib", "re", "inbetweening"}  # inbetweening: the runtime wheel
    for f in EXT.glob("*.py"):
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                names = [node.module]
            else:
                continue
            assert all(n.split(".")[0] in allowed for n in names), (f.name, names)
            assert all(n in bundled for n in names if n.startswith("inbetweening")), (f.name, names)


def test_cli_ensemble_of_two_skeletons_is_one_line_exit_2(tiny_checkpoint, tmp_path):
    proc = cli("build", tmp_path / "out", f"ckpt_path=[{CKPT},{tiny_checkpoint}]", "platforms=linux-x64")
    assert proc.returncode == 2 and "Traceback" not in proc.stderr and proc.stderr.count("\n") == 1, proc.stderr
    assert proc.stderr.startswith(f"error: ckpt_path: ensemble: {tiny_checkpoint} has another skeleton than {CKPT}")
    assert not (tmp_path / "out").exists() or not list((tmp_path / "out").iterdir())


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The linux-x64 zip built with the defaults (the bundled ensemble), no wheels downloaded."""
    from inbetweening.blender import build

    out = tmp_path_factory.mktemp("dist")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(build, "download_wheels", lambda *a, **k: [])
        mp.chdir(REPO)  # the default checkpoints are relative to the repository
        (zip_path,) = build.build(out, platforms=["linux-x64"], log=lambda *a: None)
    with zipfile.ZipFile(zip_path) as z:
        z.extractall(out / "ext")
    return zip_path, out / "ext"


def test_the_build_bundles_every_member_and_says_so(built):
    from inbetweening.blender.build import DEFAULT_CKPTS

    zip_path, ext = built
    assert [Path(c) for c in DEFAULT_CKPTS] == [c.relative_to(REPO) for c in CKPTS]
    names = set(zipfile.ZipFile(zip_path).namelist())
    assert {f"model/{f}" for f in ("model.onnx", "model.json", "model_2.onnx", "model_2.json", "model_3.onnx",
                                   "model_3.json", "models.json")} <= names
    index = json.loads((ext / "model" / "models.json").read_text())
    assert index["fill"] == "ensemble"
    members = index["members"]
    assert [m["onnx"] for m in members] == ["model.onnx", "model_2.onnx", "model_3.onnx"]
    assert [m["source_checkpoint"] for m in members] == list(DEFAULT_CKPTS)
    assert [m["predicts_contact"] for m in members] == [False, False, True]
    for m in members:
        meta = json.loads((ext / "model" / m["json"]).read_text())
        assert meta["source_checkpoint"] == m["source_checkpoint"]
        assert m["onnxruntime_vs_pytorch_max_abs_diff"] == meta["onnxruntime_vs_pytorch_max_abs_diff"] < 1e-4
    licence = (ext / "model" / "MODEL_LICENSE.txt").read_text()
    assert licence.startswith("The weights of the 3 bundled models were all trained on Bandai-Namco") and "CC BY-NC" in licence


def extension_model(monkeypatch, model_dir: Path):
    """The extension's model.py, imported outside Blender (``bpy.path.abspath`` the identity), its bundled models in
    ``model_dir``."""
    monkeypatch.setitem(sys.modules, "bpy", types.SimpleNamespace(path=types.SimpleNamespace(abspath=lambda p: p)))
    spec = importlib.util.spec_from_file_location("extension_model_under_test", EXT / "model.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    monkeypatch.setattr(mod, "MODEL_DIR", str(model_dir))
    return mod


def test_the_extension_fills_with_the_ensemble_of_the_bundled_models(built, monkeypatch):
    """The bundled default is the runtime's EnsembleBackend of the three ONNX members, the same model as the command
    line's ensemble of the three checkpoints (``Inbetweener.from_checkpoint([...])``); a model file chosen in the Model
    field is one OnnxBackend."""
    from inbetweening.api.export import window_example
    from inbetweening.api.inbetweener import Inbetweener
    from inbetweening.runtime.ensemble import EnsembleBackend
    from inbetweening.runtime.onnx_backend import OnnxBackend

    _, ext = built
    mod = extension_model(monkeypatch, ext / "model")
    model = mod.load_model("")
    assert isinstance(model, EnsembleBackend) and mod.load_model("") is model  # cached
    assert [Path(m.path).name for m in model.members] == ["model.onnx", "model_2.onnx", "model_3.onnx"]
    assert all(isinstance(m, OnnxBackend) for m in model.members)
    ib = Inbetweener.from_checkpoint(CKPTS)
    assert isinstance(ib.backend, EnsembleBackend) and model.info == ib.backend.info and model.info.has_contacts
    for gap in (5, 30):
        root, q, known, _ = window_example(ib.predictor, 2, gap, seed=gap)
        got = model.predict(root.numpy(), q.numpy(), known.numpy(), None)
        ref = ib.backend.predict(root.numpy(), q.numpy(), known.numpy(), None)
        sl = slice(ib.n_past, ib.n_past + gap)
        for a, b in zip(got, ref):
            assert np.abs(np.asarray(a)[:, sl] - np.asarray(b)[:, sl]).max() < 1e-4, gap
    assert model.calls == 2

    own = mod.load_model(str(ext / "model" / "model_2.onnx"))  # a user's model file: that model alone
    assert isinstance(own, OnnxBackend) and own.info == ib.backend.members[1].info


def test_a_bad_bundled_model_list_is_one_model_error(built, monkeypatch, tmp_path):
    from inbetweening.runtime.model import ModelError

    (tmp_path / "models.json").write_text('{"members": [{"file": "model.onnx"}]}')
    mod = extension_model(monkeypatch, tmp_path)
    with pytest.raises(ModelError, match=r"models.json: not a list of bundled models \(KeyError"):
        mod.load_model("")
    (tmp_path / "models.json").unlink()  # a build without the list: its model.onnx alone
    with pytest.raises(ModelError, match="model file not found"):
        mod.load_model("")
