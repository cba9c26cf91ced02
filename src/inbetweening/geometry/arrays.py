"""numpy arrays and torch tensors alike: the one place geometry learns whether PyTorch is there.

Every function of :mod:`inbetweening.geometry` takes either kind and returns the same kind.  PyTorch is optional:
the fill runtime (:mod:`inbetweening.runtime`) and the geometry it uses run on numpy alone (the Blender extension
bundles them without PyTorch), so ``torch`` is ``None`` there and every array is a numpy array.
"""
from __future__ import annotations

import numpy as np

try:
    import torch
except ImportError:  # the torch-free runtime (Blender): numpy only
    torch = None

__all__ = ["Array", "is_tensor", "torch"]

Array = np.ndarray if torch is None else np.ndarray | torch.Tensor


def is_tensor(x) -> bool:
    """Whether ``x`` is a torch tensor (never, without PyTorch)."""
    return torch is not None and isinstance(x, torch.Tensor)
