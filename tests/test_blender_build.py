"""The Blender extension without Blender: the build command's argument errors, the runtime wheel it bundles (the
project's own runtime modules, importable and filling without PyTorch), and what the extension's sources import.
The ONNX backend against the torch one: tests/test_runtime_backends.py."""
from __future__ import annotations

import ast
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
import torch

from inbetweening.predictor import masks

REPO = Path(__file__).resolve().parents[1]
CKPT = REPO / "models" / "bn2_partial" / "model.ckpt"  # the bundled model (blender/build.py)
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


def test_the_runtime_wheel_holds_the_runtime_and_what_it_imports(tmp_path):
    from inbetweening.blender.build import runtime_modules, runtime_wheel

    mods = runtime_modules()
    assert "inbetweening.runtime.fill" in mods and "inbetweening.runtime.onnx_backend" in mods
    assert "inbetweening.geometry.ik" in mods and "inbetweening.data.contacts" in mods
    assert "inbetweening.runtime.torch_backend" not in mods and not any(m.startswith("inbetweening.tools") for m in mods)
    whl = runtime_wheel(tmp_path, "9.9")
    with zipfile.ZipFile(whl) as z:
        names = set(z.namelist())
        record = z.read("inbetweening_runtime-9.9.dist-info/RECORD").decode()
        src = z.read("inbetweening/runtime/fill.py")
    assert "inbetweening/runtime/fill.py" in names and "inbetweening/__init__.py" in names
    assert src == (REPO / "src" / "inbetweening" / "runtime" / "fill.py").read_bytes()  # the file itself, no copy
    assert all(n in record for n in names if not n.endswith("RECORD"))


def test_a_runtime_module_that_imports_torch_fails_the_build(monkeypatch):
    from inbetweening.blender import build

    monkeypatch.setattr(build, "RUNTIME_LEFT_OUT", ())  # torch_backend imports torch at the top
    with pytest.raises(build.BuildError, match=r"inbetweening.runtime.torch_backend imports torch"):
        build.runtime_modules()


def test_extension_sources_need_no_torch():
    """Inside Blender only numpy, onnxruntime, bpy/mathutils, the extension's own modules and the bundled runtime's
    modules are imported."""
    from inbetweening.blender.build import runtime_modules

    bundled = set(runtime_modules())
    allowed = {"numpy", "onnxruntime", "bpy", "mathutils", "bpy_extras", "__future__", "os", "json", "math",
               "itertools", "time", "importlib", "hashlib", "inbetweening"}  # inbetweening: the runtime wheel
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
