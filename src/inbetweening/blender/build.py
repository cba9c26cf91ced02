"""Build the Blender extension: per-platform zips with the add-on, the model as ONNX + JSON metadata and the
``onnxruntime`` wheels (with their dependencies, except numpy: Blender's own is used)."""
from __future__ import annotations

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

EXTENSION_FILES = ("__init__.py", "engine.py", "operators.py", "rig.py")
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
DEFAULT_CKPT = "models/bn2_reference/model.ckpt"


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


def export_model(ckpt_path: str | Path, out_dir: Path) -> tuple[Path, Path, dict]:
    """Export the checkpoint's window graph to ``out_dir/model.onnx`` and its metadata to ``model.json``."""
    from inbetweening.tools.export import export_window_onnx
    from inbetweening.tools.inbetweener import Inbetweener

    ckpt_path = Path(ckpt_path)
    if not ckpt_path.is_file():
        raise BuildError(f"ckpt_path: {ckpt_path} does not exist")
    try:
        ib = Inbetweener.from_checkpoint(ckpt_path)
        info = export_window_onnx(ib, out_dir / "model.onnx", extra={"source_checkpoint": ckpt_path.name})
    except (ValueError, OSError) as e:  # CheckpointError, ExportError, InbetweenError are ValueErrors
        raise BuildError(f"ckpt_path: {e}") from None
    if info["max_abs_diff"] is None or info["max_abs_diff"] > 1e-4:
        raise BuildError(f"the exported graph differs from PyTorch by {info['max_abs_diff']}")
    meta = {k: json.loads(v) for k, v in info["metadata"].items()}
    meta["onnxruntime_vs_pytorch_max_abs_diff"] = info["max_abs_diff"]
    (out_dir / "model.json").write_text(json.dumps(meta, indent=1))
    return out_dir / "model.onnx", out_dir / "model.json", meta


def _version() -> str:
    try:
        from importlib.metadata import version

        return version("inbetweening")
    except Exception:  # pragma: no cover - not installed
        return "0.1.0"


def model_licence(meta: dict) -> str:
    ds = str(meta.get("dataset", ""))
    if "bandai" in ds.lower():
        return ("The bundled model's weights were trained on Bandai-Namco-Research-Motiondataset-2 (Bandai Namco "
                "Research Inc.; Kobayashi et al., arXiv:2306.08861), licensed CC BY-NC 4.0. Use the model and what it "
                "generates for non-commercial purposes only, with attribution.\n")
    return (f"The bundled model was trained on the dataset {ds!r}; its weights carry that dataset's licence terms.\n")


def build(out_dir: str | Path, ckpt_path: str | Path = DEFAULT_CKPT, platforms=DEFAULT_PLATFORMS,
          onnxruntime: str = ONNXRUNTIME, wheels: str | Path | None = None, log=print) -> list[Path]:
    """Write ``out_dir/inbetweening-<version>-<platform>.zip`` for each platform; returns their paths."""
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
        log(f"exporting {ckpt_path} to ONNX")
        onnx_path, json_path, meta = export_model(ckpt_path, tmp)
        log(f"  onnxruntime vs PyTorch: max abs diff {meta['onnxruntime_vs_pytorch_max_abs_diff']:.2g}")
        out_dir.mkdir(parents=True, exist_ok=True)
        manifest_in = (src / "blender_manifest.toml.in").read_text()
        readme = (src / "README.md").read_text()
        licence = model_licence(meta)
        zips = []
        for platform in platforms:
            log(f"wheels for {platform} (onnxruntime {onnxruntime})")
            whls = download_wheels(platform, onnxruntime, Path(wheels) if wheels else None)
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
                z.write(onnx_path, "model/model.onnx")
                z.write(json_path, "model/model.json")
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
