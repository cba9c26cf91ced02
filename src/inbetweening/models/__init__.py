"""Model zoo: every model is an :class:`InbetweenModel` built from plain config values."""
from __future__ import annotations

from .base import InbetweenModel
from .graph_transformer import GraphTransformer

MODELS: dict[str, type[InbetweenModel]] = {"graph_transformer": GraphTransformer}


def build_model(name: str, **kwargs) -> InbetweenModel:
    """Instantiate ``MODELS[name](**kwargs)``; ValueError for unknown names."""
    if name not in MODELS:
        raise ValueError(f"unknown model {name!r}; available: {sorted(MODELS)}")
    return MODELS[name](**kwargs)


__all__ = ["MODELS", "GraphTransformer", "InbetweenModel", "build_model"]
