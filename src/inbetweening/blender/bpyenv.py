"""A Python with Blender as a module (``bpy`` from the package index) for the extension's tests and benchmarks."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

from inbetweening.api.shipped import REPO

BPY_VERSION = "5.0.1"  # Blender 5.0 (Python 3.11); the 4.2 LTS wheel is bpy==4.2.x with numpy<2


def bpy_python(venv: str | Path | None = None, create: bool = True) -> Path | None:
    """The interpreter of a venv with ``bpy==BPY_VERSION``: ``$INBETWEENING_BPY_PYTHON`` if set, else
    ``<repo>/.venv-bpy`` (created with Python 3.11 and ``pip install bpy`` when ``create``).  ``None`` if there is
    no Python 3.11 to create it with."""
    if os.environ.get("INBETWEENING_BPY_PYTHON"):
        return Path(os.environ["INBETWEENING_BPY_PYTHON"])
    venv = Path(venv or REPO / ".venv-bpy")
    exe = venv / ("Scripts/python.exe" if os.name == "nt" else "bin/python")
    if exe.is_file() and subprocess.run([str(exe), "-c", "import bpy"], capture_output=True).returncode == 0:
        return exe
    if not create:
        return None
    base = shutil.which("python3.11") or (sys.executable if sys.version_info[:2] == (3, 11) else None)
    if base is None:
        return None
    subprocess.run([base, "-m", "venv", str(venv)], check=True)
    subprocess.run([str(exe), "-m", "pip", "install", "--quiet", "--disable-pip-version-check", f"bpy=={BPY_VERSION}"],
                   check=True)
    return exe
