"""The extension's model: the bundled ONNX window model (or one the animator chooses), loaded once through the fill
runtime's ONNX backend."""
from __future__ import annotations

import os

import bpy

from inbetweening.runtime.onnx_backend import OnnxBackend

MODEL_DIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "model")
LICENCE = ("The bundled model is trained on Bandai-Namco-Research-Motiondataset-2 (CC BY-NC 4.0): "
           "non-commercial use only.")
_MODELS: dict = {}


def bundled_model() -> str:
    return os.path.join(MODEL_DIR, "model.onnx")


def load_model(path: str) -> OnnxBackend:
    """The model at ``path`` (default: the bundled one), cached by path and modification time."""
    path = bpy.path.abspath(path) if path else bundled_model()
    key = (path, os.path.getmtime(path) if os.path.isfile(path) else None)
    if key not in _MODELS:
        _MODELS.clear()
        _MODELS[key] = OnnxBackend(path)
    return _MODELS[key]
