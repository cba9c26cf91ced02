"""The fill runtime's errors, importable alone (a command line checks its options with them before loading anything
else).  :class:`InbetweenError`: the caller's input; :class:`ModelError`: the model file."""
from __future__ import annotations

__all__ = ["InbetweenError", "ModelError"]


class InbetweenError(ValueError):
    """Bad keyframes, gap or skeleton for in-betweening; the message says what and where."""


class ModelError(ValueError):
    """The model file is missing, unreadable, or not an in-betweening window model of this version."""
