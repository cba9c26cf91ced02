"""The predictor's persisted settings: what a checkpoint records to rebuild a
:class:`~inbetweening.predictor.predictor.Predictor` (its ``hyper_parameters``), and what the exported network's
metadata tells a consumer of the bare graph.  Listed once, here: :class:`PredictorSettings` yields the hparams
(:meth:`~PredictorSettings.hparams`), the predictor's constructor values (:meth:`~PredictorSettings.
predictor_kwargs`), the export metadata (:meth:`~PredictorSettings.metadata`) and the values a dataset decides
(:meth:`~PredictorSettings.from_data`, what the training data module hands the LightningModule).
"""
from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import MISSING, dataclass, fields

from inbetweening.data.windows import N_PAST
from inbetweening.representation import DEFAULT_REPRESENTATION

__all__ = ["EXPORT_FORMAT", "PredictorSettings"]

EXPORT_FORMAT = "inbetweening-onnx/1"  # the ``format`` of the export metadata

# the constructor's first values, given positionally with the network (``Predictor(net, skeleton, pos_mean, ...)``)
_POSITIONAL = ("skeleton", "pos_mean", "pos_std")


@dataclass(frozen=True, kw_only=True)
class PredictorSettings:
    """Plain values (dicts, lists, numbers, strings) that rebuild a predictor with its network's weights; the field
    order is the order of a checkpoint's ``hyper_parameters``.  Meanings: see the
    :class:`~inbetweening.predictor.predictor.Predictor` constructor.

    ``model``: the network's config (``name`` + constructor values); ``skeleton``: ``Skeleton.to_dict()``;
    ``pos_mean``, ``pos_std``: ``J*3`` floats each; ``contact``, ``convention``: ``FootContact.to_dict()``,
    ``FileConvention.to_dict()`` (``None``: none recorded); ``blend``: the do-no-harm blend (``None``: none).
    """

    model: dict
    skeleton: dict
    pos_mean: Sequence[float]
    pos_std: Sequence[float]
    mask: str = "lerp"
    centre: str
    n_past: int = N_PAST
    forward_axis: Sequence[float] = (0.0, 1.0, 0.0)
    representation: str = DEFAULT_REPRESENTATION
    fps: float = 30.0
    train_window: int = 50
    dataset: str = ""
    contact: dict | None = None
    convention: dict | None = None
    blend: Sequence[float] | None = None

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """The settings' names, in the order of a checkpoint's ``hyper_parameters``."""
        return tuple(f.name for f in fields(cls))

    @classmethod
    def defaults(cls) -> dict:
        """The defaults of the settings that have one (name -> value)."""
        return {f.name: f.default for f in fields(cls) if f.default is not MISSING}

    @classmethod
    def from_hparams(cls, hp: Mapping) -> PredictorSettings:
        """The settings among ``hp`` (a checkpoint's ``hyper_parameters``, which also holds the training's own values:
        those are left out); a missing or ``None`` value takes the default; ``KeyError`` without ``model``,
        ``skeleton``, ``pos_mean`` or ``pos_std``."""
        required = {k: hp[k] for k in ("model", *_POSITIONAL)}
        return cls(**required, **{k: hp[k] for k in cls.names() if k not in required and hp.get(k) is not None})

    @staticmethod
    def from_data(data, train_window: int) -> dict:
        """The settings a dataset decides (a :class:`~inbetweening.data.clips.MotionData`: skeleton, statistics,
        name, conventions) and the training window length, as plain values."""
        return {"skeleton": data.skeleton.to_dict(), "pos_mean": data.pos_mean.tolist(),
                "pos_std": data.pos_std.tolist(), "dataset": data.name, "forward_axis": list(data.forward_axis),
                "fps": float(data.fps), "contact": data.contact.to_dict(), "convention": data.convention.to_dict(),
                "train_window": int(train_window)}

    def hparams(self) -> dict:
        """Every setting, by name, in order (what :meth:`from_hparams` reads back)."""
        return {k: getattr(self, k) for k in self.names()}

    def predictor_kwargs(self) -> dict:
        """The predictor's keyword values (all but the network and the positional ``skeleton``, ``pos_mean``,
        ``pos_std``; ``model`` is recorded, the network itself is built from it)."""
        return {k: v for k, v in self.hparams().items() if k not in _POSITIONAL}

    def metadata(self, max_frames: int | None, representation: Mapping, inputs: Sequence[str]) -> dict[str, str]:
        """What a consumer of the bare network needs to prepare its inputs, one JSON string per key.
        ``max_frames``: the longest window the network accepts (``None``: any, written 0); ``representation``: the
        feature layout's metadata (:meth:`~inbetweening.representation.base.Representation.metadata`); ``inputs``:
        the graph's input names."""
        sk = self.skeleton
        meta = {
            "format": EXPORT_FORMAT,
            "model": dict(self.model),
            "skeleton_names": list(sk["names"]),
            "skeleton_parents": list(sk["parents"]),
            "skeleton_offsets": [list(o) for o in sk["offsets"]],
            "pos_mean": list(self.pos_mean),
            "pos_std": list(self.pos_std),
            "mask": self.mask,
            "centre": self.centre,
            "forward_axis": list(self.forward_axis),
            "n_past": self.n_past,
            "fps": self.fps,
            "train_window": self.train_window,
            "max_frames": max_frames or 0,
            "dataset": self.dataset,
            **representation,
            "blend": None if self.blend is None else list(self.blend),
            "inputs": list(inputs),
        }
        return {k: json.dumps(v) for k, v in meta.items()}
