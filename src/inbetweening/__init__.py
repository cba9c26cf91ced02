"""inbetweening: motion in-betweening experiments (graph-attention transformer, baselines, LAFAN1 benchmark)."""
__version__ = "0.1.0"

__all__ = ["Inbetweener", "__version__"]


def __getattr__(name: str):
    # lazy: ``import inbetweening`` stays light (no torch) until the animator API is used
    if name == "Inbetweener":
        from inbetweening.api.inbetweener import Inbetweener

        return Inbetweener
    raise AttributeError(f"module 'inbetweening' has no attribute {name!r}")
