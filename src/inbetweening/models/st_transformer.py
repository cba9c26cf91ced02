"""Spatio-temporal transformer (PoseFormer-style, Zheng et al. 2021) for in-betweening.

Each joint of each frame is projected to ``spatial_dim`` channels (plus a learned joint embedding and a known-flag
embedding, so per-joint masks are seen) and a spatial pre-norm transformer mixes the ``J`` joints of every frame.
The ``J * spatial_dim`` features of a frame are then projected to ``d_model``, a learned temporal embedding is
added and a temporal pre-norm transformer mixes the frames; a regression head (LayerNorm + Linear) maps back to
``J * F``.  Pre-norm blocks: ``z' = MSA(LN(z)) + z``, ``z = MLP(LN(z')) + z'``.
"""
from __future__ import annotations

from typing import Any

import torch
from torch import Tensor, nn

from .base import Checks, InbetweenModel
from .blocks import PositionEmbedding, TransformerEncoder


class STTransformer(InbetweenModel):
    """Spatial (joints) then temporal (frames) pre-norm transformer.

    Args (plain values only; common ones, with their defaults, in :class:`InbetweenModel`):
        num_joints: ``J``.  adjacency: ``J x J`` joint relation matrix (checked, otherwise unused).
        spatial_dim, spatial_depth, spatial_heads: per-joint width ``C``, spatial layers, spatial heads (divide ``C``).
        spatial_ffn_dim: spatial MLP width (default ``2 * spatial_dim``).
        d_model, temporal_depth, heads: temporal width, layers and heads (``d_model % heads == 0``).
        ffn_dim: temporal MLP width (default ``2 * d_model``).
        dropout: attention / residual / MLP dropout.  activation: MLP activation.
        max_frames: longest window ``T``.
    """

    OUTPUT_HEAD = ("head",)
    TINY = {"spatial_dim": 8, "spatial_depth": 1, "spatial_heads": 2, "d_model": 16, "temporal_depth": 1, "heads": 2}

    def __init__(
        self,
        num_joints: int,
        adjacency: list[list[float]],
        spatial_dim: int = 32,
        spatial_depth: int = 4,
        spatial_heads: int = 4,
        spatial_ffn_dim: int | None = None,
        d_model: int = 256,
        temporal_depth: int = 4,
        heads: int = 8,
        ffn_dim: int | None = None,
        dropout: float = 0.1,
        activation: str = "gelu",
        **common: Any,
    ):
        super().__init__(num_joints, adjacency, dropout=dropout, **common)
        spatial_ffn_dim = 2 * spatial_dim if spatial_ffn_dim is None else spatial_ffn_dim
        ffn_dim = 2 * d_model if ffn_dim is None else ffn_dim
        self.spatial_dim, self.d_model = spatial_dim, d_model

        self.joint_proj = nn.Linear(self.input_dim, spatial_dim)
        self.joint_embed = nn.Parameter(torch.randn(num_joints, spatial_dim) * 0.02)
        self.flag_embed = nn.Embedding(2, spatial_dim)
        nn.init.normal_(self.flag_embed.weight, std=0.02)
        self.spatial = TransformerEncoder(spatial_dim, spatial_depth, spatial_heads, spatial_ffn_dim, dropout,
                                          activation=activation, norm_first=True, final_norm=True)
        self.frame_proj = nn.Linear(num_joints * spatial_dim, d_model)
        self.time_embed = PositionEmbedding(self.max_frames, d_model)
        self.temporal = TransformerEncoder(d_model, temporal_depth, heads, ffn_dim, dropout,
                                           activation=activation, norm_first=True, final_norm=False)
        self.head_norm = nn.LayerNorm(d_model)
        self.head = nn.Linear(d_model, num_joints * self.output_dim)

    @classmethod
    def check_settings(cls, checks: Checks) -> None:
        checks.integer("spatial_dim", "spatial_depth", "spatial_heads", "d_model", "temporal_depth", "heads")
        checks.integer("spatial_ffn_dim", "ffn_dim", optional=True)
        checks.divides("spatial_heads", "spatial_dim")
        checks.divides("heads", "d_model")
        checks.activation()

    def network(self, x: Tensor, known: Tensor, interp: Tensor | None) -> Tensor:
        """``x (B, T, J, F), known (B, T, J) bool, interp unused -> raw (B, T, J, F)``."""
        b, t = x.shape[0], x.shape[1]
        s = self.joint_proj(x) + self.joint_embed + self.flag_embed(known.long())  # (B, T, J, C)
        s = self.spatial(s.reshape(-1, self.num_joints, self.spatial_dim))  # (B*T, J, C)
        h = self.frame_proj(s.reshape(b, t, self.num_joints * self.spatial_dim)) + self.time_embed(t)
        h = self.temporal(h)  # (B, T, D)
        return self.head(self.head_norm(h)).reshape(*x.shape[:-1], self.output_dim)
