"""The shipped ensemble: the models a source checkout fills with by default, one list for every front end
(``python -m inbetweening.predict`` without ``ckpt_path``, the Blender extension's bundle, the docs' commands).

``bn2_partial`` and ``bn2_partial_twin`` (the v1 recipe with two seeds, fine-tuned for keys of some bones only) and
``bn2_v2`` (foot contact channels), in the ensemble's member order (RESULTS.md section 2).  Each ships as its
training checkpoint (``model.ckpt``) and its exported window graph (``model.onnx``: what ``predict`` fills with by
default, without PyTorch, and what the Blender extension bundles; ``tests/test_shipped.py`` checks that each graph
predicts what its checkpoint does).  Re-export after a checkpoint changes:
``python -m inbetweening.blender export ckpt_path=models/<name>/model.ckpt output=models/<name>/model.onnx``."""
from __future__ import annotations

from pathlib import Path

__all__ = ["REPO", "SHIPPED", "SHIPPED_CKPTS", "SHIPPED_ONNX"]

REPO = Path(__file__).resolve().parents[3]  # the source checkout (models/, .venv-bpy)
SHIPPED = ("bn2_partial", "bn2_partial_twin", "bn2_v2")
SHIPPED_CKPTS = tuple(f"models/{name}/model.ckpt" for name in SHIPPED)  # relative to REPO
SHIPPED_ONNX = tuple(f"models/{name}/model.onnx" for name in SHIPPED)  # their window graphs, relative to REPO
