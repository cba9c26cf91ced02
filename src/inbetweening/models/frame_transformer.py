"""Frame-token motion-completion transformer (Duan et al. 2021, "Single-Shot Motion Completion with Transformer").

One token per frame: all joints' features concatenated with the per-joint known flags (``J*F + J`` channels), a
Conv1d (kernel 3) input stem to ``d_model``, a learned position embedding plus a known/masked segment embedding
(a frame is "known" when all its joints are), a standard post-norm transformer encoder, and a Conv1d (kernel 3)
output head back to ``J*F``.  The graph matrix of the graph transformer is not used.
"""
from __future__ import annotations

from typing import Any

from torch import Tensor, nn

from .base import Checks, InbetweenModel
from .blocks import NORMS, PositionEmbedding, TransformerEncoder, frame_features


class FrameTransformer(InbetweenModel):
    """Frame-token post-norm transformer.

    Args (plain values only; common ones, with their defaults, in :class:`InbetweenModel`):
        num_joints: ``J``.  adjacency: ``J x J`` joint relation matrix (checked, otherwise unused).
        d_model, depth, heads, ffn_dim: transformer width, layers, heads (``d_model % heads == 0``), MLP width.
        dropout: attention / residual / MLP dropout and dropout on the input embedding.
        norm: ``"layer"`` or ``"batch"``.  activation: feed-forward activation.
        max_frames: longest window ``T`` (size of the learned position table).
    """

    OUTPUT_HEAD = ("head",)
    TINY = {"d_model": 16, "depth": 2, "heads": 2, "ffn_dim": 32}

    def __init__(
        self,
        num_joints: int,
        adjacency: list[list[float]],
        d_model: int = 256,
        depth: int = 8,
        heads: int = 8,
        ffn_dim: int = 512,
        dropout: float = 0.1,
        norm: str = "layer",
        activation: str = "gelu",
        **common: Any,
    ):
        super().__init__(num_joints, adjacency, dropout=dropout, **common)
        self.d_model = d_model
        in_ch = num_joints * self.input_dim + num_joints
        self.stem = nn.Conv1d(in_ch, d_model, kernel_size=3, padding=1)
        self.pos_embed = PositionEmbedding(self.max_frames, d_model)
        self.segment_embed = nn.Embedding(2, d_model)  # 0 = frame with missing joints, 1 = fully known frame
        nn.init.normal_(self.segment_embed.weight, std=0.02)
        self.embed_dropout = nn.Dropout(dropout)
        self.encoder = TransformerEncoder(d_model, depth, heads, ffn_dim, dropout, norm, activation, norm_first=False)
        self.head = nn.Conv1d(d_model, num_joints * self.output_dim, kernel_size=3, padding=1)

    @classmethod
    def check_settings(cls, checks: Checks) -> None:
        checks.integer("d_model", "depth", "heads", "ffn_dim")
        checks.divides("heads", "d_model")
        checks.one_of("norm", NORMS)
        checks.activation()

    def network(self, x: Tensor, known: Tensor, interp: Tensor | None) -> Tensor:
        """``x (B, T, J, F), known (B, T, J) bool, interp unused -> raw (B, T, J, F)``."""
        h = self.stem(frame_features(x, known).transpose(1, 2)).transpose(1, 2)  # (B, T, D)
        frame_known = known.to(x.dtype).amin(dim=-1).long()  # (B, T): 1 iff every joint of the frame is known
        h = self.embed_dropout(h + self.pos_embed(x.shape[1]) + self.segment_embed(frame_known))
        h = self.encoder(h)
        return self.head(h.transpose(1, 2)).transpose(1, 2).reshape(*x.shape[:-1], self.output_dim)
