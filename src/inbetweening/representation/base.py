"""The feature representation's contract: how (root position, local quaternion) windows become the network's
features and back, and the feature layout every other part asks for.

A representation is one class (a subclass of :class:`Representation`, registered in
:data:`inbetweening.representation.REPRESENTATIONS`).  It owns:

* the layout: ``features`` channels per joint and the named channel groups (:meth:`Representation.channels`:
  ``position``, ``rotation`` and any further group, e.g. contacts), exported as plain values by :meth:`layout`
  (the network's contract, :class:`inbetweening.models.base.InbetweenModel`, is built from it);
* the maps: :meth:`encode` / :meth:`decode`, :meth:`global_positions` (what the features say about world positions)
  and :meth:`normalise_positions` (world positions in the features' units, for the losses);
* the statistics it was built with (``mean``/``std`` of global positions, ``J*3`` each) and one length scale of the
  data, :meth:`position_scale`.

Shapes: windows ``root (..., T, 3), local_q (..., T, J, 4)``, features ``(..., T, J, F)``.  Windows reach a
representation already canonicalised (the predictor's one centring stage), so a representation holds no centring.
"""
from __future__ import annotations

import numpy as np
import torch

from inbetweening.data.contacts import FootContact
from inbetweening.geometry.skeleton import Skeleton


class Representation:
    """Base class.  Subclasses set ``name``, ``features``, ``pos``, ``quat``, ``description`` and implement
    :meth:`encode`, :meth:`decode`, :meth:`global_positions` and :meth:`normalise_positions`."""

    name: str = ""
    features: int = 0  # channels per joint
    pos: slice = slice(0, 0)  # the joint's position channels (xyz)
    quat: slice = slice(0, 0)  # the joint's local rotation channels (quaternion wxyz)
    description: str = ""

    def __init__(self, skeleton: Skeleton, mean, std, contact: FootContact | None = None, fps: float = 30.0):
        self.skeleton = skeleton
        self.mean = np.asarray(mean, dtype=np.float64)
        self.std = np.asarray(std, dtype=np.float64)
        self.contact = contact or FootContact()  # the data's feet and contact rule (representations with contacts)
        self.fps = float(fps)

    # ------------------------------------------------------------------ layout
    @classmethod
    def channels(cls) -> dict[str, slice]:
        """Named channel groups of a joint's features (``position``, ``rotation``, ...)."""
        return {"position": cls.pos, "rotation": cls.quat}

    @classmethod
    def layout(cls) -> dict:
        """The layout as plain values, what a network is built with: ``{"features": F, "position": [a, b],
        "rotation": [a, b], ...}``."""
        return {"features": cls.features, **{k: [s.start, s.stop] for k, s in cls.channels().items()}}

    def metadata(self) -> dict:
        """Plain values describing the layout (export metadata)."""
        extra = {f"{k}_slice": [v.start, v.stop] for k, v in self.channels().items() if k not in ("position", "rotation")}
        return {"representation": self.name, "features_per_joint": self.features,
                "position_slice": [self.pos.start, self.pos.stop], "quaternion_slice": [self.quat.start, self.quat.stop],
                **extra, "features": self.description}

    # ------------------------------------------------------------------ maps
    def encode(self, root: torch.Tensor, local_q: torch.Tensor) -> torch.Tensor:
        """``root (..., T, 3), local_q (..., T, J, 4) -> features (..., T, J, F)`` (same dtype)."""
        raise NotImplementedError

    def encode_np(self, root: np.ndarray, local_q: np.ndarray) -> np.ndarray | None:
        """:meth:`encode` of float64 numpy windows, the same numbers (``None``: not implemented, use torch)."""
        return None

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

    def decode(self, feats: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``features (..., T, J, F) -> root (..., T, 3), local_q (..., T, J, 4)`` (unit quaternions)."""
        raise NotImplementedError

    def global_positions(self, feats: torch.Tensor) -> torch.Tensor:
        """Global joint positions the features carry.  ``(..., J, F) -> (..., J, 3)``."""
        raise NotImplementedError

    def normalise_positions(self, positions: torch.Tensor) -> torch.Tensor:
        """Global positions ``(..., J, 3)`` in the units of the position channels (the inverse of
        :meth:`global_positions` on them)."""
        raise NotImplementedError

    def contacts(self, feats: torch.Tensor) -> torch.Tensor | None:
        """Foot contact per joint, in [0, 1], the features carry: ``(..., J, F) -> (..., J)``; ``None`` when the
        representation has no contact channels."""
        return None

    def position_scale(self) -> float:
        """One length scale of the data (the mean position std), to keep length-valued losses O(1)."""
        return float(torch.as_tensor(self.std).float().mean())
