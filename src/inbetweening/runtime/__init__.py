"""The fill runtime: one path from an animator's keys to the filled motion, shared by every front end.

``python -m inbetweening.predict``, the Python API (:class:`inbetweening.Inbetweener`), ``eval.py protocol=keyframes``
and the Blender extension all fill through :class:`FillRuntime`.  It holds every stage around the network: the
file's unit and up axis, the gap plan (long gaps split at interpolated pseudo-keyframes), the context windows and
their canonical frame, the do-no-harm blend's weights, foot locking and the keys copied back exactly.  The network
itself is a *backend* (:class:`Backend`): the trained torch module (:mod:`.torch_backend`) or its exported window
graph run by ONNX Runtime (:mod:`.onnx_backend`); both describe their model with the same :class:`ModelInfo`.

numpy only: this package and the geometry it uses import no PyTorch (``torch_backend`` excepted), so the Blender
extension bundles the very same files (``python -m inbetweening.blender build``).
"""
from __future__ import annotations

from .errors import InbetweenError, ModelError

__all__ = ["Backend", "FillRuntime", "Filled", "InbetweenError", "ModelError", "ModelInfo"]


def __getattr__(name: str):
    """The rest on first use: a command line that reads its options (``predict --help``, the fill's settings,
    :mod:`.settings`) loads neither the fill nor the geometry behind it (which loads PyTorch where it is installed)."""
    if name in ("FillRuntime", "Filled"):
        from . import fill

        return getattr(fill, name)
    if name in ("Backend", "ModelInfo"):
        from . import model

        return getattr(model, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
