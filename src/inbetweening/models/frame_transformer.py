"""Frame-token motion-completion transformer (Duan et al. 2021, "Single-Shot Motion Completion with Transformer").

One token per frame: all joints' features concatenated with the per-joint known flags (``J*F + J`` channels), a
Conv1d (kernel 3) input stem to ``d_model``, a learned position embedding plus a known/masked segment embedding
(a frame is "known" when all its joints are), a standard post-norm transformer encoder, and a Conv1d (kernel 3)
output head back to ``J*F``.  The graph matrix of the graph transformer is not used.
"""
from __future__ import annotations

from torch import Tensor, nn

from .base import FEATURE_DIM, InbetweenModel
from .blocks import (
    NORMS,
    PositionEmbedding,
    TransformerEncoder,
    check_input,
    check_length,
    frame_features,
    make_activation,
    require,
    validate_common,
)


class FrameTransformer(InbetweenModel):
    """Frame-token post-norm transformer.

    Args (plain values only):
        num_joints: ``J``.  adjacency: ``J x J`` joint relation matrix (checked, otherwise unused).
        feature_dim: features per joint ``F`` (>= 7).
        d_model, depth, heads, ffn_dim: transformer width, layers, heads (``d_model % heads == 0``), MLP width.
        dropout: attention / residual / MLP dropout and dropout on the input embedding.
        norm: ``"layer"`` or ``"batch"``.  activation: feed-forward activation.
        max_frames: longest window ``T`` (size of the learned position table).
        residual_to_interpolation: predict ``interp + head(h)`` when ``interp`` is given (head initialised to 0).
    """

    def __init__(
        self,
        num_joints: int,
        adjacency: list[list[float]],
        feature_dim: int = FEATURE_DIM,
        d_model: int = 256,
        depth: int = 8,
        heads: int = 8,
        ffn_dim: int = 512,
        dropout: float = 0.1,
        norm: str = "layer",
        activation: str = "gelu",
        max_frames: int = 128,
        residual_to_interpolation: bool = False,
    ):
        super().__init__()
        name = type(self).__name__
        validate_common(name, num_joints, adjacency, feature_dim, max_frames, dropout)
        require(depth >= 1, name, f"depth must be >= 1, got {depth}")
        require(d_model >= 1 and heads >= 1 and d_model % heads == 0, name,
                f"heads must divide d_model (d_model={d_model}, heads={heads})")
        require(ffn_dim >= 1, name, f"ffn_dim must be >= 1, got {ffn_dim}")
        require(norm in NORMS, name, f"norm must be one of {list(NORMS)}, got {norm!r}")
        make_activation(activation)
        self.num_joints, self.feature_dim, self.d_model, self.max_frames = num_joints, feature_dim, d_model, max_frames
        self.residual_to_interpolation = bool(residual_to_interpolation)

        in_ch = num_joints * feature_dim + num_joints
        self.stem = nn.Conv1d(in_ch, d_model, kernel_size=3, padding=1)
        self.pos_embed = PositionEmbedding(max_frames, d_model)
        self.segment_embed = nn.Embedding(2, d_model)  # 0 = frame with missing joints, 1 = fully known frame
        nn.init.normal_(self.segment_embed.weight, std=0.02)
        self.embed_dropout = nn.Dropout(dropout)
        self.encoder = TransformerEncoder(d_model, depth, heads, ffn_dim, dropout, norm, activation, norm_first=False)
        self.head = nn.Conv1d(d_model, num_joints * feature_dim, kernel_size=3, padding=1)
        if self.residual_to_interpolation:
            nn.init.zeros_(self.head.weight)
            nn.init.zeros_(self.head.bias)

    def forward(self, x: Tensor, known: Tensor, interp: Tensor | None = None) -> Tensor:
        """``x (B, T, J, F), known (B, T, J) bool, interp (B, T, J, F) | None -> (B, T, J, F)``."""
        check_input(type(self).__name__, x, known, self.num_joints, self.feature_dim)
        check_length(x.shape[1], self.max_frames)
        h = self.stem(frame_features(x, known).transpose(1, 2)).transpose(1, 2)  # (B, T, D)
        frame_known = known.to(x.dtype).amin(dim=-1).long()  # (B, T): 1 iff every joint of the frame is known
        h = self.embed_dropout(h + self.pos_embed(x.shape[1]) + self.segment_embed(frame_known))
        h = self.encoder(h)
        raw = self.head(h.transpose(1, 2)).transpose(1, 2).reshape(x.shape)
        if self.residual_to_interpolation and interp is not None:
            raw = interp + raw
        return self.finalize(raw, x, known)
