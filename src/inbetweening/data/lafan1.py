"""The official Ubisoft LAFAN1 archive: download it when missing, and verify its size and sha256."""
from __future__ import annotations

import hashlib
import os
import urllib.request
from pathlib import Path

from inbetweening.data.errors import DatasetError

LAFAN1_URL = "https://github.com/ubisoft/ubisoft-laforge-animation-dataset/raw/master/lafan1/lafan1.zip"
LAFAN1_SIZE = 144_051_503
LAFAN1_SHA256 = "ea918082b500a5d158e9d3aa39039df04cd42e25f5c02fe8f7e88e8e9365a977"

__all__ = ["LAFAN1_SHA256", "LAFAN1_SIZE", "LAFAN1_URL", "download_lafan1", "verify_lafan1"]


def download_lafan1(dest: Path, url: str = LAFAN1_URL, timeout: float = 30.0) -> Path:
    """Download the official ``lafan1.zip`` to ``dest`` and verify its size and sha256."""
    dest = dest if dest.suffix == ".zip" else dest / "lafan1.zip"
    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = dest.with_suffix(".part")
    try:
        with urllib.request.urlopen(url, timeout=timeout) as r, open(tmp, "wb") as f:
            while chunk := r.read(1 << 20):
                f.write(chunk)
    except OSError as e:  # URLError is an OSError
        tmp.unlink(missing_ok=True)
        raise DatasetError(
            f"lafan1: could not download {url} ({e}); this machine seems offline. Put lafan1.zip "
            f"({LAFAN1_SIZE} bytes) at {dest} or pass data.path=<zip or folder of .bvh>"
        ) from None
    return verify_lafan1(tmp, final=dest)


def verify_lafan1(path: Path, final: Path | None = None) -> Path:
    """Check ``path`` is the official archive (size and sha256); move it to ``final`` when given."""
    size = path.stat().st_size
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    if size != LAFAN1_SIZE or digest != LAFAN1_SHA256:
        raise DatasetError(f"lafan1: {path} has size {size} and sha256 {digest}; expected {LAFAN1_SIZE} / {LAFAN1_SHA256}")
    if final is not None:
        os.replace(path, final)
        return final
    return path
