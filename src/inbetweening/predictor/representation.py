"""Feature representations: how (root position, local quaternions) windows become the network's features.

A representation is a small class registered by name (:data:`REPRESENTATIONS`); it defines the feature layout
(``features`` per joint, the ``pos`` and ``quat`` slices) and the maps between windows and features.  The
predictor, the export metadata and the tools read the layout from here.  Built from plain values
(``build_representation(name, skeleton, mean, std)``) so it is restored from a checkpoint's hyper-parameters.
"""
from __future__ import annotations

import numpy as np
import torch

from inbetweening.geometry.skeleton import Skeleton


class Representation:
    """Base class.  Subclasses set ``name``, ``features``, ``pos``, ``quat``, ``description`` and implement the
    methods below; shapes: windows ``root (..., T, 3), local_q (..., T, J, 4)``, features ``(..., T, J, F)``."""

    name: str = ""
    features: int = 0  # per joint
    pos: slice = slice(0, 0)  # the joint's position
    quat: slice = slice(0, 0)  # the joint's local rotation, wxyz
    description: str = ""

    def __init__(self, skeleton: Skeleton, mean, std):
        self.skeleton = skeleton
        self.mean = np.asarray(mean, dtype=np.float64)
        self.std = np.asarray(std, dtype=np.float64)

    def encode(self, root: torch.Tensor, local_q: torch.Tensor) -> torch.Tensor:
        """``root (..., T, 3), local_q (..., T, J, 4) -> features (..., T, J, F)`` (same dtype)."""
        raise NotImplementedError

    def encode_windows(self, root, local_q, dtype=torch.float32, device=None) -> torch.Tensor:
        """:meth:`encode` of numpy or torch windows (any float): FK in float64, the result cast to ``dtype`` on
        ``device``.  NaN frames stay NaN (nothing downstream reads unknown values)."""
        if not isinstance(root, torch.Tensor) and not isinstance(local_q, torch.Tensor):
            feats = self.encode_np(np.asarray(root, dtype=np.float64), np.asarray(local_q, dtype=np.float64))
            if feats is not None:
                return torch.from_numpy(feats).to(dtype=dtype, device=device)
        r = torch.as_tensor(root).double()
        q = torch.as_tensor(local_q).double()
        return self.encode(r, q).to(dtype=dtype, device=device)

    def encode_np(self, root: np.ndarray, local_q: np.ndarray) -> np.ndarray | None:
        """:meth:`encode` of float64 numpy windows, the same numbers (``None``: not implemented, use torch)."""
        return None

    def decode(self, feats: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``features (..., T, J, F) -> root (..., T, 3), local_q (..., T, J, 4)`` (unit quaternions)."""
        raise NotImplementedError

    def global_positions(self, feats: torch.Tensor) -> torch.Tensor:
        """Global joint positions the features carry.  ``(..., J, F) -> (..., J, 3)``."""
        raise NotImplementedError

    def centre_shift(self, feats: torch.Tensor, known: torch.Tensor, how: str = "known") -> torch.Tensor:
        """Feature-space shift that moves the root XZ anchor of the known frames to the origin (subtract it from
        the features; add it back to the prediction): ``how="known"`` their mean, ``"last"`` the last context
        frame.  ``(B, T, J, F), (B, T, J) -> (B, 1, J, F)``."""
        raise NotImplementedError

    def metadata(self) -> dict:
        """Plain values describing the layout (for export metadata)."""
        return {"representation": self.name, "features_per_joint": self.features,
                "position_slice": [self.pos.start, self.pos.stop], "quaternion_slice": [self.quat.start, self.quat.stop],
                "features": self.description}


REPRESENTATIONS: dict[str, type[Representation]] = {}
DEFAULT_REPRESENTATION = "global_pos_local_quat"  # what every checkpoint made before the option used


def register_representation(cls: type[Representation]) -> type[Representation]:
    """Class decorator: make a representation available by its ``name``."""
    REPRESENTATIONS[cls.name] = cls
    return cls


def build_representation(name: str, skeleton: Skeleton, mean, std) -> Representation:
    """``REPRESENTATIONS[name](skeleton, mean, std)``; ValueError naming ``representation`` if unknown."""
    _load_builtin()
    if name not in REPRESENTATIONS:
        raise ValueError(f"representation: unknown representation {name!r}; choose one of {sorted(REPRESENTATIONS)}")
    return REPRESENTATIONS[name](skeleton, mean, std)


def _load_builtin() -> None:
    from inbetweening.predictor import features  # noqa: F401 - registers the built-in representation


__all__: list[str] = ["DEFAULT_REPRESENTATION", "REPRESENTATIONS", "Representation", "build_representation",
                      "register_representation"]
