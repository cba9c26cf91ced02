"""What the runtime knows of a model: :class:`ModelInfo`, built from the window graph's metadata (one JSON value per
key, as :func:`inbetweening.runtime.torch_backend.window_metadata` writes them), and the :class:`Backend` contract."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from inbetweening.data.contacts import FootContact
from inbetweening.data.convention import FileConvention
from inbetweening.geometry.skeleton import Skeleton

from .errors import InbetweenError, ModelError

__all__ = ["Backend", "InbetweenError", "ModelError", "ModelInfo", "WINDOW_FORMAT"]

WINDOW_FORMAT = "inbetweening-window-onnx/2"
REQUIRED = ("skeleton_names", "skeleton_parents", "skeleton_offsets", "n_past", "forward_axis", "trained_gap")


@dataclass(frozen=True)
class ModelInfo:
    """A model as the runtime needs it.

    ``skeleton``: the model's joints and offsets (project frame: Y up, cm); ``n_past``: context frames before a gap;
    ``forward_axis``: the root's forward direction (the canonical frame turns it to +X); ``centre``: ``known`` (the
    canonical frame's origin is the known frames' mean root XZ) or ``last`` (the last context frame's root XZ);
    ``trained_gap``: the longest gap generated in one window (longer ones are split); ``hard_max_gap``: the longest
    the network accepts at all; ``blend``: the do-no-harm weights per gap length 1, 2, ... (``None``: the network as
    it is); ``contact``: the training data's feet and contact rule; ``has_contacts``: the network predicts foot
    contact; ``convention``: the training files' up axis and unit; ``fps``: the training frame rate.
    """

    skeleton: Skeleton
    n_past: int
    forward_axis: tuple[float, ...]
    centre: str
    trained_gap: int
    hard_max_gap: int
    fps: float
    blend: tuple[float, ...] | None = None
    contact: FootContact = FootContact()
    has_contacts: bool = False
    convention: FileConvention = FileConvention()
    dataset: str = ""

    @classmethod
    def from_metadata(cls, meta: dict, where: str = "model") -> ModelInfo:
        """From decoded metadata; :class:`ModelError` naming ``where`` when a key is missing or the format differs."""
        fmt = meta.get("format")
        if fmt != WINDOW_FORMAT or any(k not in meta for k in REQUIRED):
            old = isinstance(fmt, str) and fmt.startswith("inbetweening-window-onnx/")
            raise ModelError(f"{where} is {'an older' if old else 'not an'} in-betweening window model (export one with "
                             "`python -m inbetweening.blender export ckpt_path=... output=model.onnx`)")
        n_past = int(meta["n_past"])
        max_frames = int(meta.get("max_frames") or 0)
        hard = (max_frames or 10**9) - n_past - 1
        window = int(meta.get("train_window") or 0)
        gap = int(meta["trained_gap"])
        gap = min(gap, window - n_past - 1, hard) if window else min(gap, hard)
        if gap < 1:
            raise ModelError(f"{where}: its window ({window} frames, n_past={n_past}) leaves no room for a gap")
        names = [str(n) for n in meta["skeleton_names"]]
        skeleton = Skeleton(names, [int(p) for p in meta["skeleton_parents"]],
                            np.asarray(meta["skeleton_offsets"], dtype=np.float64).reshape(len(names), 3))
        blend = meta.get("blend")
        return cls(skeleton, n_past, tuple(float(a) for a in meta["forward_axis"]),
                   "last" if meta.get("frame_centre") == "last" else "known", gap, hard, float(meta.get("fps") or 30.0),
                   None if blend is None else tuple(float(w) for w in blend), FootContact.from_dict(meta.get("contact")),
                   "contact_out" in (meta.get("outputs") or ()), FileConvention.from_dict(meta.get("convention")),
                   str(meta.get("dataset", "")))

    def blend_weight(self, gap: int) -> float | None:
        """The do-no-harm weight of the network in a gap of ``gap`` frames (longer gaps than the table: its last);
        ``None`` without a blend."""
        if self.blend is None:
            return None
        return self.blend[min(max(int(gap), 1), len(self.blend)) - 1]

    def same_rate(self, fps: float) -> bool:
        """Whether motion at ``fps`` frames per second runs at the model's rate: within half a frame per second (a
        file's frame time rounded, 30 against 30.00003, is the same rate; 24 or 60 is not)."""
        return abs(float(fps) - float(self.fps)) <= 0.5


class Backend(Protocol):
    """The network, as the runtime calls it.

    ``info``: the :class:`ModelInfo`.  ``predict(root (B, T, 3), local_q (B, T, J, 4), known (B, T, J) bool,
    weight (B, T, J) float32 | None)``: windows already in their canonical frame -> ``(root, local_q, contact)``, the
    decoded prediction (float64; ``contact (B, T, J)`` in [0, 1], or ``None`` for a network without contact channels),
    the network's correction to the interpolation scaled by ``weight`` (``None``: unscaled; the fill runtime asks for
    the network unscaled and blends per gap itself, :mod:`.trust`).  ``contacts=False``: the caller does not read the
    contact (the self-check's windows), so a backend may leave out work done only for it (an ensemble's members
    with no share in the pose; :mod:`.ensemble`)."""

    info: ModelInfo

    def predict(self, root: np.ndarray, local_q: np.ndarray, known: np.ndarray, weight: np.ndarray | None,
                contacts: bool = True): ...
