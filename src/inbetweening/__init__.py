"""inbetweening: motion in-betweening experiments (graph-attention transformer, baselines, LAFAN1 benchmark)."""
__version__ = "0.1.0"
