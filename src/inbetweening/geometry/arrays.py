"""numpy arrays and torch tensors alike: the one place geometry learns whether PyTorch is there.

Every function of :mod:`inbetweening.geometry` takes either kind and returns the same kind.  PyTorch is optional and
never imported here: the fill runtime (:mod:`inbetweening.runtime`) and the geometry it uses run on numpy alone (the
Blender extension bundles them without PyTorch, and ``python -m inbetweening.predict`` with ONNX models starts without
it).  A tensor can only exist once its caller imported PyTorch, so :func:`is_tensor` asks ``sys.modules`` and
:data:`torch` imports the module on its first attribute, inside a tensor branch.
"""
from __future__ import annotations

import sys
from typing import TYPE_CHECKING

import numpy as np

__all__ = ["Array", "is_tensor", "torch"]

if TYPE_CHECKING:  # pragma: no cover
    import torch as _torch

    Array = np.ndarray | _torch.Tensor
else:
    Array = np.ndarray  # annotations only; tensors are accepted wherever an Array is


def is_tensor(x) -> bool:
    """Whether ``x`` is a torch tensor (never, while PyTorch is not imported)."""
    module = sys.modules.get("torch")
    return module is not None and isinstance(x, module.Tensor)


class _LazyTorch:
    """``torch``, imported on first use (only the tensor branches use it, after their caller imported it)."""

    def __getattr__(self, name: str):
        import torch as module

        return getattr(module, name)


torch = _LazyTorch()
