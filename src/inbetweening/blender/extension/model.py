"""The extension's model, from one owner (:func:`load_model`): the bundled models (``model/models.json`` lists them; by
default ``bn2_partial``, ``bn2_partial_twin`` and ``bn2_v2``) filling as their ensemble through the fill runtime's
:class:`~inbetweening.runtime.ensemble.EnsembleBackend`, as the command line fills with its shipped ensemble; or a
model file the animator chooses (``.onnx``), alone.  Each network runs on the runtime's ONNX backend."""
from __future__ import annotations

import json
import os

import bpy

from inbetweening.runtime.ensemble import EnsembleBackend
from inbetweening.runtime.model import ModelError
from inbetweening.runtime.onnx_backend import OnnxBackend

MODEL_DIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "model")
MODELS_INDEX = "models.json"  # written by inbetweening.blender.build (bundle_models)
LICENCE = ("The bundled models are trained on Bandai-Namco-Research-Motiondataset-2 (CC BY-NC 4.0): "
           "non-commercial use only.")
_MODELS: dict = {}


def bundled_model() -> str:
    """The first bundled model's file."""
    return os.path.join(MODEL_DIR, "model.onnx")


def bundled_models() -> list[str]:
    """The bundled models' files, in order (``model/models.json``; a build without one: ``model/model.onnx`` alone);
    :class:`ModelError` for an unreadable list."""
    index = os.path.join(MODEL_DIR, MODELS_INDEX)
    if not os.path.isfile(index):
        return [bundled_model()]
    try:
        with open(index, encoding="utf-8") as f:
            names = [str(m["onnx"]) for m in json.load(f)["members"]]
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise ModelError(f"{index}: not a list of bundled models ({type(e).__name__}: {e})") from None
    if not names or any(os.path.basename(n) != n for n in names):
        raise ModelError(f"{index}: not a list of bundled models (members {names!r})")
    return [os.path.join(MODEL_DIR, n) for n in names]


def load_model(path: str):
    """The model the extension fills with (``.info``, ``.predict``, ``.calls``): for an empty ``path`` the bundled
    models, their :class:`EnsembleBackend` (an :class:`OnnxBackend` where one is bundled); else the
    :class:`OnnxBackend` of the file ``path``.  Cached by files and modification times."""
    paths = [bpy.path.abspath(path)] if path else bundled_models()
    key = tuple((p, os.path.getmtime(p) if os.path.isfile(p) else None) for p in paths)
    if key not in _MODELS:
        _MODELS.clear()
        members = [OnnxBackend(p) for p in paths]
        _MODELS[key] = members[0] if len(members) == 1 else EnsembleBackend(members, [os.path.basename(p) for p in paths])
    return _MODELS[key]
