"""``notebooks/walkthrough.ipynb`` runs top to bottom (with few training steps) and is stored without outputs."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")
pytest.importorskip("ipykernel")

REPO = Path(__file__).resolve().parents[1]
NOTEBOOK = REPO / "notebooks" / "walkthrough.ipynb"
KERNEL = "inbetweening-test"


def test_notebook_is_stored_without_outputs():
    nb = nbformat.read(NOTEBOOK, as_version=4)
    nbformat.validate(nb)
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert code and all(not c.outputs and c.execution_count is None for c in code)


def test_notebook_runs(tmp_path, monkeypatch):
    # a kernelspec for *this* interpreter, found first on JUPYTER_PATH, so the kernel sees this environment
    spec = tmp_path / "jupyter" / "kernels" / KERNEL
    spec.mkdir(parents=True)
    (spec / "kernel.json").write_text(json.dumps({
        "argv": [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"],
        "display_name": "inbetweening tests", "language": "python",
    }))
    monkeypatch.setenv("JUPYTER_PATH", str(tmp_path / "jupyter"))
    monkeypatch.delenv("MPLBACKEND", raising=False)  # a headless Agg override would hide the inline figures
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.setenv("WALKTHROUGH_DIR", str(work))
    monkeypatch.setenv("WALKTHROUGH_STEPS", "20")
    monkeypatch.setenv("INBETWEENING_CONF", str(REPO / "conf"))
    monkeypatch.setenv("INBETWEENING_CACHE", str(work / "cache"))
    nb = nbformat.read(NOTEBOOK, as_version=4)
    client = nbclient.NotebookClient(nb, kernel_name=KERNEL, timeout=300,
                                     resources={"metadata": {"path": str(work)}})
    client.execute()
    assert (work / "filled.bvh").is_file() and (work / "filled.gif").is_file()
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    images = [k for o in outputs for k in o.get("data", {}) if k.startswith("image/")]
    assert images.count("image/png") >= 3  # window, mask, per-joint errors
    assert "image/gif" in images  # the in-betweened clip
