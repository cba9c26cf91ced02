"""Model zoo: every model is an :class:`InbetweenModel` built from plain config values.

Adding a model is one module (a subclass implementing ``network``, ``check_settings``, ``OUTPUT_HEAD`` and ``TINY``,
see :mod:`.base`), one ``conf/model/<name>.yaml`` and one line in :data:`MODELS`; config validation and the contract
tests (tests/test_models_base.py) find it there.
"""
from __future__ import annotations

from .base import InbetweenModel
from .baselines import Interpolation, ZeroVelocity
from .frame_transformer import FrameTransformer
from .graph_transformer import GraphTransformer
from .resnet_lstm import ResNetLSTM
from .retarget_lstm import RetargetLSTM
from .st_transformer import STTransformer
from .unet1d import UNet1D

MODELS: dict[str, type[InbetweenModel]] = {
    "graph_transformer": GraphTransformer,
    "frame_transformer": FrameTransformer,
    "st_transformer": STTransformer,
    "resnet_lstm": ResNetLSTM,
    "unet1d": UNet1D,
    "zero_velocity": ZeroVelocity,
    "interpolation": Interpolation,
}
# retargeting networks (task=retarget): source motion features -> target motion features, per frame over time
RETARGETERS: dict[str, type] = {"retarget_lstm": RetargetLSTM}


def build_model(name: str, **kwargs) -> InbetweenModel:
    """Instantiate ``MODELS[name](**kwargs)``; ValueError for unknown names."""
    if name not in MODELS:
        raise ValueError(f"unknown model {name!r}; available: {sorted(MODELS)}")
    return MODELS[name](**kwargs)


def build_retargeter(model_cfg: dict, input_dim: int, output_dim: int):
    """The retargeting network of a model config (``name`` + constructor values) for these feature sizes;
    ValueError naming ``model.name`` when it is not a retargeting network."""
    cfg = dict(model_cfg)
    name = cfg.pop("name")
    if name not in RETARGETERS:
        raise ValueError(f"model.name: {name!r} is not a retargeting network; task=retarget takes one of "
                         f"{sorted(RETARGETERS)}")
    return RETARGETERS[name](input_dim=input_dim, output_dim=output_dim, **cfg)


def build_network(model_cfg: dict, skeleton, layout: dict | None = None) -> InbetweenModel:
    """The network of a model config (``name`` + constructor values; ``hops`` builds a k-hop relation matrix)
    for a :class:`~inbetweening.geometry.skeleton.Skeleton` and a representation's feature ``layout``
    (:meth:`~inbetweening.representation.base.Representation.layout`; default: the default representation's);
    ValueError naming ``model.name`` if unknown."""
    cfg = dict(model_cfg)
    name = cfg.pop("name")
    if name not in MODELS:
        raise ValueError(f"model.name: unknown model {name!r}; choose one of {sorted(MODELS)}")
    hops = int(cfg.get("hops", 1))
    given = {"num_joints": skeleton.num_joints, "adjacency": skeleton.adjacency(hops).tolist()}
    if layout is not None:
        given.update(layout=dict(layout), feature_dim=int(layout["features"]))
    return build_model(name, **given, **cfg)


__all__ = [
    "MODELS",
    "RETARGETERS",
    "FrameTransformer",
    "GraphTransformer",
    "InbetweenModel",
    "Interpolation",
    "ResNetLSTM",
    "RetargetLSTM",
    "STTransformer",
    "UNet1D",
    "ZeroVelocity",
    "build_model",
    "build_retargeter",
    "build_network",
]
