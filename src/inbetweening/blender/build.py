"""Build the Blender extension: per-platform zips with the add-on, the models as ONNX + JSON metadata (by default the
ensemble of :data:`DEFAULT_CKPTS`, what the extension fills with: :func:`bundle_models`), the fill runtime as a wheel
of its own (:func:`runtime_wheel`: the project's own ``inbetweening.runtime``, the DCC core ``inbetweening.dcc`` and
the modules they import, not a copy) and the ``onnxruntime`` wheels (with their dependencies, except numpy: Blender's
own is used)."""
from __future__ import annotations

import ast
import base64
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import zipfile
from importlib import resources
from pathlib import Path

from inbetweening.api.shipped import SHIPPED_CKPTS

EXTENSION_FILES = ("__init__.py", "operators.py", "model.py", "curves.py", "rig.py", "humanoid.py", "rigify.py",
                   "rigify_solve.py", "rig_proxy.py", "bone_map_panel.py", "record.py", "loop.py")
RUNTIME = "inbetweening.runtime"  # bundled with every module of the package it imports
DCC = "inbetweening.dcc"  # the DCC core the extension fills through (numpy and the runtime only), bundled the same
BUNDLED = (RUNTIME, DCC)
RUNTIME_LEFT_OUT = ("inbetweening.runtime.torch_backend",)  # the torch backend stays behind (the one torch module)
RUNTIME_THIRD_PARTY = ("numpy", "onnxruntime")  # what the bundled modules may import besides the standard library
# Blender platform name -> pip platform tag of the wheels (Blender 4.2 and 5.0 run Python 3.11)
PLATFORMS = {
    "linux-x64": "manylinux_2_28_x86_64",
    "windows-x64": "win_amd64",
    "macos-arm64": "macosx_11_0_arm64",
    "macos-x64": "macosx_11_0_x86_64",  # not built by default
}
DEFAULT_PLATFORMS = ("linux-x64", "windows-x64", "macos-arm64")
PYTHON_VERSION = "3.11"
ONNXRUNTIME = "1.19.2"  # the newest with a cp311 wheel for macOS 11 on arm64 (Blender 4.2's minimum macOS)
SKIP_WHEELS = ("numpy",)  # Blender bundles numpy
DEFAULT_CKPTS = SHIPPED_CKPTS  # the bundled ensemble (runtime/ensemble.py): the shipped one, as predict fills by default
MODELS_INDEX = "models.json"  # model/models.json: the bundled members, in order (the extension's model.py reads it)


class BuildError(ValueError):
    """The extension could not be built (bad argument, failed download, failed export)."""


def wheel_cache_dir() -> Path:
    from inbetweening.data.cache import default_cache_dir

    return Path(os.environ.get("INBETWEENING_WHEELS", default_cache_dir() / "blender-wheels"))


def download_wheels(platform: str, version: str = ONNXRUNTIME, cache: Path | None = None) -> list[Path]:
    """``onnxruntime==version`` and its dependencies for ``platform`` (a key of :data:`PLATFORMS`), Python 3.11
    binary wheels from the package index, cached in ``cache/<platform>/onnxruntime-<version>``; numpy left out."""
    if platform not in PLATFORMS:
        raise BuildError(f"platform: unknown {platform!r}; choose from {', '.join(PLATFORMS)}")
    folder = Path(cache or wheel_cache_dir()) / platform / f"onnxruntime-{version}"
    done = folder / "complete.json"
    if done.is_file():
        names = json.loads(done.read_text())
        if all((folder / n).is_file() for n in names):
            return [folder / n for n in names]
    folder.mkdir(parents=True, exist_ok=True)
    cmd = [sys.executable, "-m", "pip", "download", f"onnxruntime=={version}", "--only-binary=:all:",
           "--platform", PLATFORMS[platform], "--python-version", PYTHON_VERSION, "--dest", str(folder),
           "--quiet", "--disable-pip-version-check"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        last = [ln for ln in proc.stderr.splitlines() if ln.strip() and "is ignored" not in ln][-1:] or ["?"]
        raise BuildError(f"downloading onnxruntime=={version} wheels for {platform} failed: {last[0]}")
    names = sorted(p.name for p in folder.glob("*.whl") if not p.name.lower().startswith(SKIP_WHEELS))
    if not any(n.startswith("onnxruntime-") for n in names):
        raise BuildError(f"no onnxruntime wheel for {platform} in {folder}")
    done.write_text(json.dumps(names))
    return [folder / n for n in names]


def source_name(ckpt_path: str | Path) -> str:
    """How the metadata names a checkpoint: its path relative to the working folder when inside it (the repository's
    ``models/bn2_v2/model.ckpt``), else its folder and name (no absolute path of the builder's machine)."""
    path = Path(ckpt_path).resolve()
    try:
        return path.relative_to(Path.cwd().resolve()).as_posix()
    except ValueError:
        return f"{path.parent.name}/{path.name}"


def export_model(ckpt_path: str | Path, out_dir: Path, stem: str = "model") -> tuple[Path, Path, dict]:
    """Export the checkpoint's window graph to ``out_dir/<stem>.onnx`` and its metadata to ``<stem>.json``."""
    from inbetweening.api.export import export_window_onnx
    from inbetweening.api.inbetweener import Inbetweener

    ckpt_path = Path(ckpt_path)
    if not ckpt_path.is_file():
        raise BuildError(f"ckpt_path: {ckpt_path} does not exist")
    try:
        ib = Inbetweener.from_checkpoint(ckpt_path)
        info = export_window_onnx(ib, out_dir / f"{stem}.onnx", extra={"source_checkpoint": source_name(ckpt_path)})
    except (ValueError, OSError) as e:  # CheckpointError, ExportError, InbetweenError are ValueErrors
        raise BuildError(f"ckpt_path: {e}") from None
    if info["max_abs_diff"] is None or info["max_abs_diff"] > 1e-4:
        raise BuildError(f"ckpt_path: the graph exported from {ckpt_path} differs from PyTorch by {info['max_abs_diff']}")
    meta = {k: json.loads(v) for k, v in info["metadata"].items()}
    meta["onnxruntime_vs_pytorch_max_abs_diff"] = info["max_abs_diff"]
    (out_dir / f"{stem}.json").write_text(json.dumps(meta, indent=1))
    return out_dir / f"{stem}.onnx", out_dir / f"{stem}.json", meta


def checkpoints(ckpt_path) -> list[Path]:
    """``ckpt_path`` (one path or a list) as a list of existing, distinct checkpoint files; :class:`BuildError`
    naming the first that is missing or repeated."""
    paths = [Path(ckpt_path)] if isinstance(ckpt_path, (str, Path)) else [Path(p) for p in ckpt_path]
    if not paths:
        raise BuildError("ckpt_path: no checkpoint given")
    seen = set()
    for p in paths:
        if not p.is_file():
            raise BuildError(f"ckpt_path: {p} does not exist")
        if p.resolve() in seen:
            raise BuildError(f"ckpt_path: {p} is given twice")
        seen.add(p.resolve())
    return paths


def bundle_models(ckpt_path, out_dir: Path, log=print) -> tuple[list[Path], list[dict]]:
    """Export each checkpoint of ``ckpt_path`` (one, or a list: their ensemble) into ``out_dir``: the first as
    ``model.onnx`` + ``model.json``, the others as ``model_2.onnx`` + ``model_2.json``, ..., and the index
    :data:`MODELS_INDEX` (each member's files, source checkpoint, onnxruntime-vs-PyTorch difference, dataset, trained
    gap and whether it predicts foot contact).  Members that are not models of one skeleton and data fail the build,
    naming the checkpoint.  Returns the files written (for the zip's ``model/`` folder) and each member's metadata."""
    from inbetweening.runtime.ensemble import ensemble_info
    from inbetweening.runtime.model import ModelError, ModelInfo

    paths = checkpoints(ckpt_path)
    files, metas, members = [], [], []
    for i, ckpt in enumerate(paths):
        log(f"exporting {ckpt} to ONNX")
        onnx_path, json_path, meta = export_model(ckpt, out_dir, "model" if i == 0 else f"model_{i + 1}")
        log(f"  onnxruntime vs PyTorch: max abs diff {meta['onnxruntime_vs_pytorch_max_abs_diff']:.2g}")
        files += [onnx_path, json_path]
        metas.append(meta)
        members.append({"onnx": onnx_path.name, "json": json_path.name, "source_checkpoint": meta["source_checkpoint"],
                        "onnxruntime_vs_pytorch_max_abs_diff": meta["onnxruntime_vs_pytorch_max_abs_diff"],
                        "dataset": meta.get("dataset", ""), "trained_gap": meta.get("trained_gap"),
                        "predicts_contact": "contact_out" in (meta.get("outputs") or ())})
    try:
        ensemble_info([ModelInfo.from_metadata(m, str(p)) for m, p in zip(metas, paths)], [str(p) for p in paths])
    except ModelError as e:
        raise BuildError(f"ckpt_path: {e}") from None
    what = ("the ensemble of these members (inbetweening.runtime.ensemble: each weighted per gap length by its "
            "calibrated blend weight)" if len(members) > 1 else "this model")
    index = {"fill": "ensemble" if len(members) > 1 else "single", "members": members,
             "about": f"the extension fills with {what}; a model file chosen in its Model field is used instead"}
    (out_dir / MODELS_INDEX).write_text(json.dumps(index, indent=1))
    return [*files, out_dir / MODELS_INDEX], metas


def _module_file(name: str) -> Path | None:
    """The source file of module ``name`` of this package (a package's ``__init__.py``), or None."""
    base = Path(resources.files("inbetweening")).parent
    path = base.joinpath(*name.split("."))
    if (path / "__init__.py").is_file():
        return path / "__init__.py"
    return path.with_suffix(".py") if path.with_suffix(".py").is_file() else None


def _optional(node, parents: dict) -> bool:
    """Whether an import node is not needed to import its module: inside a function (run when that function is
    called: the torch-only helpers of the geometry), a ``try`` that catches ImportError (an optional dependency) or
    an ``if TYPE_CHECKING:`` block (annotations only)."""
    while node in parents:
        node = parents[node]
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            return True
        if isinstance(node, ast.If) and ast.unparse(node.test) in ("TYPE_CHECKING", "typing.TYPE_CHECKING"):
            return True
        if isinstance(node, ast.Try) and any(
                h.type is None or "ImportError" in ast.unparse(h.type) for h in node.handlers):
            return True
    return False


def runtime_modules() -> dict[str, Path]:
    """``{module name: file}`` of the fill runtime and the DCC core (:data:`BUNDLED`) and every module of this package
    they import, transitively (with the packages' ``__init__``), read from the source; :class:`BuildError` when one of
    them imports anything but the standard library, :data:`RUNTIME_THIRD_PARTY` and the package itself at import time
    (imports inside functions, those guarded by ``except ImportError`` and ``if TYPE_CHECKING:`` are not followed)."""
    found: dict[str, Path] = {}
    todo = []
    for top in BUNDLED:
        package = _module_file(top).parent
        todo += [top, *(f"{top}.{f.stem}" for f in sorted(package.glob("*.py")) if f.stem != "__init__"),
                 *(f"{top}.{f.parent.name}" for f in sorted(package.glob("*/__init__.py")))]  # and its subpackages
    while todo:
        name = todo.pop()
        if name in found or name in RUNTIME_LEFT_OUT:
            continue
        file = _module_file(name)
        if file is None:
            raise BuildError(f"the runtime imports {name}, which is not a module of the package")
        found[name] = file
        parts = name.split(".")
        todo += [".".join(parts[:i]) for i in range(1, len(parts))]  # the packages above it
        package = name if file.name == "__init__.py" else ".".join(parts[:-1])
        tree = ast.parse(file.read_text(), str(file))
        parents = {c: n for n in ast.walk(tree) for c in ast.iter_child_nodes(n)}
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                mod = node.module or ""
                if node.level:
                    mod = ".".join(package.split(".")[: len(package.split(".")) - node.level + 1] + ([mod] if mod else []))
                targets = [mod] + [f"{mod}.{a.name}" for a in node.names if _module_file(f"{mod}.{a.name}")]
            else:
                continue
            if _optional(node, parents):
                continue
            for t in targets:
                top = t.split(".")[0]
                if top == "inbetweening":
                    todo.append(t)
                elif top not in sys.stdlib_module_names and top not in RUNTIME_THIRD_PARTY and top != "__future__":
                    raise BuildError(f"{name} imports {t}: the bundled runtime may import only the standard library, "
                                     f"{', '.join(RUNTIME_THIRD_PARTY)} and the package itself")
    return dict(sorted(found.items()))


def runtime_wheel(out_dir: Path, version: str) -> Path:
    """Write ``inbetweening_runtime-<version>-py3-none-any.whl`` into ``out_dir``: the :func:`runtime_modules` files
    under their package paths (Blender installs it as it installs every wheel of an extension)."""
    dist = f"inbetweening_runtime-{version}"
    files = {name.replace(".", "/") + ("/__init__.py" if f.name == "__init__.py" else ".py"): f.read_bytes()
             for name, f in runtime_modules().items()}
    files[f"{dist}.dist-info/METADATA"] = (f"Metadata-Version: 2.1\nName: inbetweening-runtime\nVersion: {version}\n"
                                           "Summary: The in-betweening fill runtime and DCC core (numpy; no PyTorch)\n"
                                           "Requires-Dist: numpy\n").encode()
    files[f"{dist}.dist-info/WHEEL"] = (b"Wheel-Version: 1.0\nGenerator: inbetweening.blender.build\n"
                                        b"Root-Is-Purelib: true\nTag: py3-none-any\n")
    record = [f"{path},sha256={base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b'=').decode()},{len(data)}"
              for path, data in files.items()]
    files[f"{dist}.dist-info/RECORD"] = ("\n".join([*record, f"{dist}.dist-info/RECORD,,"]) + "\n").encode()
    target = Path(out_dir) / f"{dist}-py3-none-any.whl"
    with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as z:
        for path, data in files.items():
            z.writestr(zipfile.ZipInfo(path, date_time=(2020, 1, 1, 0, 0, 0)), data)
    return target


def _version() -> str:
    try:
        from importlib.metadata import version

        return version("inbetweening")
    except Exception:  # pragma: no cover - not installed
        return "0.1.0"


def model_licence(meta) -> str:
    """The licence note of the bundled models' weights (``meta``: one model's metadata, or a list of them)."""
    metas = [meta] if isinstance(meta, dict) else list(meta)
    sets = sorted({str(m.get("dataset", "")) for m in metas})
    one = len(metas) == 1
    the = "The bundled model's weights were" if one else f"The weights of the {len(metas)} bundled models were all"
    if all("bandai" in ds.lower() for ds in sets):
        return (f"{the} trained on Bandai-Namco-Research-Motiondataset-2 (Bandai Namco Research Inc.; Kobayashi et al., "
                f"arXiv:2306.08861), licensed CC BY-NC 4.0. Use the {'model' if one else 'models'} and what "
                f"{'it generates' if one else 'they generate'} for non-commercial purposes only, with attribution.\n")
    names = ", ".join(repr(ds) for ds in sets)
    return (f"The bundled {'model was' if one else 'models were'} trained on the dataset{'s' if len(sets) > 1 else ''} "
            f"{names}; {'its' if one else 'their'} weights carry {'that dataset' if len(sets) == 1 else 'those datasets'}'s "
            "licence terms.\n")


def build(out_dir: str | Path, ckpt_path=DEFAULT_CKPTS, platforms=DEFAULT_PLATFORMS,
          onnxruntime: str = ONNXRUNTIME, wheels: str | Path | None = None, log=print) -> list[Path]:
    """Write ``out_dir/inbetweening-<version>-<platform>.zip`` for each platform; returns their paths.  ``ckpt_path``:
    the checkpoint to bundle, or a list of them (models of one skeleton): their ensemble (:func:`bundle_models`)."""
    out_dir = Path(out_dir)
    bad = [p for p in platforms if p not in PLATFORMS]
    if bad or not platforms:
        raise BuildError(f"platforms: unknown {', '.join(bad) or '(none)'}; choose from {', '.join(PLATFORMS)}")
    if not re.fullmatch(r"\d+(\.\d+)*", str(onnxruntime)):
        raise BuildError(f"onnxruntime: {onnxruntime!r} is not a version number")
    if out_dir.exists() and not out_dir.is_dir():
        raise BuildError(f"OUT_DIR: {out_dir} exists and is not a folder")
    src = resources.files("inbetweening.blender") / "extension"
    version = _version()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (tmp / "model").mkdir()
        model_files, metas = bundle_models(ckpt_path, tmp / "model", log)
        out_dir.mkdir(parents=True, exist_ok=True)
        manifest_in = (src / "blender_manifest.toml.in").read_text()
        readme = (src / "README.md").read_text()
        licence = model_licence(metas)
        runtime = runtime_wheel(tmp, version)
        log(f"fill runtime: {runtime.name} ({len(runtime_modules())} modules of the package)")
        zips = []
        for platform in platforms:
            log(f"wheels for {platform} (onnxruntime {onnxruntime})")
            whls = [runtime, *download_wheels(platform, onnxruntime, Path(wheels) if wheels else None)]
            manifest = (manifest_in.replace("@VERSION@", version).replace("@PLATFORM@", platform)
                        .replace("@WHEELS@", "\n".join(f'  "./wheels/{w.name}",' for w in whls)))
            target = out_dir / f"inbetweening-{version}-{platform}.zip"
            part = target.with_suffix(".zip.part")
            with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:
                z.writestr("blender_manifest.toml", manifest)
                for name in EXTENSION_FILES:
                    z.writestr(name, (src / name).read_text())
                z.writestr("README.md", readme + "\n## Model licence\n\n" + licence)
                z.writestr("model/MODEL_LICENSE.txt", licence)
                for f in model_files:
                    z.write(f, f"model/{f.name}")
                for w in whls:
                    z.write(w, f"wheels/{w.name}", compress_type=zipfile.ZIP_STORED)
            os.replace(part, target)
            zips.append(target)
            log(f"wrote {target} ({target.stat().st_size / 1e6:.1f} MB)")
    return zips


def export(ckpt_path: str | Path, output: str | Path) -> dict:
    """Export a checkpoint's window graph for the extension's ``model_path`` option (``output`` and a ``.json``)."""
    output = Path(output)
    if output.suffix.lower() != ".onnx":
        raise BuildError(f"output: {output} must end in .onnx")
    with tempfile.TemporaryDirectory() as tmp:
        onnx_path, json_path, meta = export_model(ckpt_path, Path(tmp))
        output.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(onnx_path, output)
        shutil.copyfile(json_path, output.with_suffix(".json"))
    return meta
