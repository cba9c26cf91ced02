"""Shared transformer building blocks (plain ``nn.Module`` s, ONNX-friendly: explicit matmuls, no fused kernels).

Reused by every model of the zoo (graph transformer, frame transformer, spatio-temporal transformer, ResNet-LSTM,
1D U-Net...): attention, norms, generic pre-/post-norm transformer encoder, residual MLP, and the small helpers
every model needs (sequence length check, per-frame feature flattening with the per-joint known flags).
"""
from __future__ import annotations

import math

import torch
from torch import Tensor, nn

__all__ = [
    "ACTIVATIONS",
    "NORMS",
    "AddNorm",
    "FeedForward",
    "MultiHeadAttention",
    "Norm",
    "PositionEmbedding",
    "ResidualMLPBlock",
    "SinusoidalPositionalEncoding",
    "TransformerBlock",
    "TransformerEncoder",
    "check_length",
    "frame_features",
    "make_activation",
]

NORMS = ("layer", "batch")
ACTIVATIONS = {"gelu": nn.GELU, "relu": nn.ReLU, "silu": nn.SiLU, "tanh": nn.Tanh}


def make_activation(name: str) -> nn.Module:
    """``"gelu" | "relu" | "silu" | "tanh"`` -> module; ValueError otherwise."""
    if name not in ACTIVATIONS:
        raise ValueError(f"activation must be one of {sorted(ACTIVATIONS)}, got {name!r}")
    return ACTIVATIONS[name]()


def check_length(length: int, max_len: int, what: str = "sequence length") -> None:
    """Raise ValueError if ``length > max_len`` (skipped while tracing, where ``length`` is symbolic)."""
    if torch.jit.is_tracing() or torch.compiler.is_compiling():
        return
    if int(length) > max_len:
        raise ValueError(f"{what} {int(length)} exceeds max_frames={max_len}; raise max_frames in the model config")


class MultiHeadAttention(nn.Module):
    """Multi-head self-attention with an optional multiplicative mask on the attention *probabilities*.

    Per head: ``Z = (prob_mask ⊙ softmax(Q Kᵀ / √d_head + attn_mask)) V`` — no renormalisation after the
    multiplication (that is the graph-attention of the method).  Heads are concatenated and projected (W_O).
    With both masks ``None`` this is standard scaled dot-product attention.

    Mask conventions (same as :class:`torch.nn.MultiheadAttention`):

    * ``attn_mask``: bool ``True`` = position NOT allowed, or float added to the scores; shape ``(L, L)`` or
      broadcastable to ``(N, heads, L, L)``.
    * ``key_padding_mask``: bool ``(N, L)``, ``True`` = padded key (ignored).
    * ``prob_mask``: float ``(L, L)`` (or broadcastable to ``(N, heads, L, L)``) multiplied into the probabilities.

    Fully masked rows get a uniform (not NaN) distribution, since masked scores use the dtype's finite minimum.
    """

    def __init__(self, d_model: int, heads: int, dropout: float = 0.0, bias: bool = True):
        super().__init__()
        if heads < 1 or d_model % heads != 0:
            raise ValueError(f"heads must divide d_model (d_model={d_model}, heads={heads})")
        self.d_model, self.heads, self.head_dim = d_model, heads, d_model // heads
        self.scale = 1.0 / math.sqrt(self.head_dim)
        self.q_proj = nn.Linear(d_model, d_model, bias=bias)
        self.k_proj = nn.Linear(d_model, d_model, bias=bias)
        self.v_proj = nn.Linear(d_model, d_model, bias=bias)
        self.out_proj = nn.Linear(d_model, d_model, bias=bias)
        self.dropout = nn.Dropout(dropout)

    def _split(self, t: Tensor) -> Tensor:
        """``(N, L, D) -> (N, heads, L, head_dim)``."""
        return t.reshape(t.shape[0], -1, self.heads, self.head_dim).transpose(1, 2)

    def attention_probs(
        self,
        x: Tensor,
        prob_mask: Tensor | None = None,
        attn_mask: Tensor | None = None,
        key_padding_mask: Tensor | None = None,
    ) -> Tensor:
        """Effective attention weights ``(N, heads, L, L)`` = ``prob_mask ⊙ softmax(...)`` (before dropout)."""
        q, k = self._split(self.q_proj(x)), self._split(self.k_proj(x))
        scores = torch.matmul(q, k.transpose(-2, -1)) * self.scale
        neg = torch.finfo(scores.dtype).min
        if attn_mask is not None:
            if attn_mask.dtype == torch.bool:
                scores = scores.masked_fill(attn_mask, neg)
            else:
                scores = scores + attn_mask.to(scores.dtype)
        if key_padding_mask is not None:
            scores = scores.masked_fill(key_padding_mask[:, None, None, :].to(torch.bool), neg)
        probs = torch.softmax(scores, dim=-1)
        if prob_mask is not None:
            probs = probs * prob_mask.to(probs.dtype)
        return probs

    def forward(
        self,
        x: Tensor,
        prob_mask: Tensor | None = None,
        attn_mask: Tensor | None = None,
        key_padding_mask: Tensor | None = None,
        fused: bool | None = None,
    ) -> Tensor:
        """``x (N, L, D) -> (N, L, D)``; masks as described in the class docstring.

        Without ``prob_mask`` (and with at most a boolean ``attn_mask``) this is PyTorch's fused
        ``scaled_dot_product_attention``: the ``(N, heads, L, L)`` scores and probabilities are never kept for the
        backward pass (a fraction of the memory, faster), and it exports to ONNX.  A ``prob_mask`` (the graph
        multiplication with a non-binary ``M``), a key padding mask or a fully masked row takes the explicit path.
        ``fused``: the caller's decision for a mask it has checked once (the per-call check reads the mask's values,
        which splits a ``torch.compile`` graph); ``None`` checks here.
        """
        if fused is None:
            fused = fused_attention_ok(prob_mask, attn_mask, key_padding_mask)
        if fused:
            q, k, v = self._split(self.q_proj(x)), self._split(self.k_proj(x)), self._split(self.v_proj(x))
            allowed = None if attn_mask is None else ~attn_mask  # SDPA's boolean convention: True = may attend
            p = self.dropout.p if self.training else 0.0
            out = nn.functional.scaled_dot_product_attention(q, k, v, attn_mask=allowed, dropout_p=p)
        else:
            probs = self.dropout(self.attention_probs(x, prob_mask, attn_mask, key_padding_mask))
            out = torch.matmul(probs, self._split(self.v_proj(x)))  # (N, H, L, head_dim)
        out = out.transpose(1, 2).reshape(x.shape[0], -1, self.d_model)
        return self.out_proj(out)


def fused_attention_ok(prob_mask: Tensor | None, attn_mask: Tensor | None, key_padding_mask: Tensor | None) -> bool:
    """Whether :class:`MultiHeadAttention` may use the fused kernel with these masks: no probability mask, no key
    padding, and at most a boolean ``attn_mask (L, L)`` without a fully masked row (the fused kernel gives NaN there)."""
    return prob_mask is None and key_padding_mask is None and (
        attn_mask is None or (attn_mask.dtype == torch.bool and not bool(attn_mask.all(-1).any())))


class Norm(nn.Module):
    """Normalise the last dim of ``(..., D)``: ``"layer"`` (LayerNorm) or ``"batch"`` (BatchNorm1d over all
    leading dims flattened, i.e. statistics over every token of the batch)."""

    def __init__(self, kind: str, d_model: int):
        super().__init__()
        if kind not in NORMS:
            raise ValueError(f"norm must be one of {list(NORMS)}, got {kind!r}")
        self.kind = kind
        self.norm = nn.LayerNorm(d_model) if kind == "layer" else nn.BatchNorm1d(d_model)

    def forward(self, x: Tensor) -> Tensor:
        """``(..., D) -> (..., D)``."""
        if self.kind == "layer":
            return self.norm(x)
        return self.norm(x.reshape(-1, x.shape[-1])).reshape(x.shape)


class AddNorm(nn.Module):
    """Post-norm residual: ``norm(x + dropout(y))``."""

    def __init__(self, d_model: int, norm: str = "layer", dropout: float = 0.0):
        super().__init__()
        self.norm = Norm(norm, d_model)
        self.dropout = nn.Dropout(dropout)

    def forward(self, x: Tensor, y: Tensor) -> Tensor:
        """``x, y (..., D) -> (..., D)``."""
        return self.norm(x + self.dropout(y))


class FeedForward(nn.Module):
    """Position-wise MLP ``D -> ffn_dim -> D`` with activation and dropout on the hidden layer."""

    def __init__(self, d_model: int, ffn_dim: int, dropout: float = 0.0, activation: str = "gelu"):
        super().__init__()
        self.net = nn.Sequential(
            nn.Linear(d_model, ffn_dim), make_activation(activation), nn.Dropout(dropout), nn.Linear(ffn_dim, d_model)
        )

    def forward(self, x: Tensor) -> Tensor:
        """``(..., D) -> (..., D)``."""
        return self.net(x)


class SinusoidalPositionalEncoding(nn.Module):
    """Fixed sine/cosine table; ``forward(length) -> (length, D)`` (``length <= max_len``)."""

    def __init__(self, d_model: int, max_len: int):
        super().__init__()
        self.max_len = max_len
        pos = torch.arange(max_len, dtype=torch.float32)[:, None]
        freq = torch.exp(torch.arange(0, d_model, 2, dtype=torch.float32) * (-math.log(10000.0) / d_model))
        pe = torch.zeros(max_len, d_model)
        pe[:, 0::2] = torch.sin(pos * freq)
        pe[:, 1::2] = torch.cos(pos * freq)[:, : d_model // 2]
        self.register_buffer("pe", pe, persistent=False)

    def forward(self, length: int) -> Tensor:
        """``length -> (length, D)``; ValueError if ``length > max_len``."""
        check_length(length, self.max_len)
        return self.pe[:length]


class PositionEmbedding(nn.Module):
    """Learned position table ``(max_len, D)``; ``forward(length) -> (length, D)``."""

    def __init__(self, max_len: int, d_model: int):
        super().__init__()
        self.max_len = max_len
        self.weight = nn.Parameter(torch.randn(max_len, d_model) * 0.02)

    def forward(self, length: int) -> Tensor:
        """``length -> (length, D)``; ValueError if ``length > max_len``."""
        check_length(length, self.max_len)
        return self.weight[:length]


class TransformerBlock(nn.Module):
    """Standard transformer encoder layer on ``(N, L, D)``: self-attention then feed-forward, each with a residual.

    * ``norm_first=False`` (post-norm, Vaswani et al.): ``z = norm(z + MSA(z))``, ``z = norm(z + MLP(z))``.
    * ``norm_first=True`` (pre-norm, ViT / PoseFormer): ``z' = MSA(norm(z)) + z``, ``z = MLP(norm(z')) + z'``.

    Explicit ops only (no fused ``nn.TransformerEncoderLayer`` fast path), so it exports to ONNX.
    """

    def __init__(
        self,
        d_model: int,
        heads: int,
        ffn_dim: int,
        dropout: float = 0.0,
        norm: str = "layer",
        activation: str = "gelu",
        norm_first: bool = False,
    ):
        super().__init__()
        self.norm_first = bool(norm_first)
        self.attn = MultiHeadAttention(d_model, heads, dropout)
        self.ffn = FeedForward(d_model, ffn_dim, dropout, activation)
        self.norm1 = Norm(norm, d_model)
        self.norm2 = Norm(norm, d_model)
        self.dropout1 = nn.Dropout(dropout)
        self.dropout2 = nn.Dropout(dropout)

    def forward(self, x: Tensor, attn_mask: Tensor | None = None, key_padding_mask: Tensor | None = None) -> Tensor:
        """``x (N, L, D) -> (N, L, D)``; masks as in :class:`MultiHeadAttention`."""
        if self.norm_first:
            x = x + self.dropout1(self.attn(self.norm1(x), attn_mask=attn_mask, key_padding_mask=key_padding_mask))
            return x + self.dropout2(self.ffn(self.norm2(x)))
        x = self.norm1(x + self.dropout1(self.attn(x, attn_mask=attn_mask, key_padding_mask=key_padding_mask)))
        return self.norm2(x + self.dropout2(self.ffn(x)))


class TransformerEncoder(nn.Module):
    """Stack of ``depth`` :class:`TransformerBlock` s on ``(N, L, D)``, optionally followed by a final norm
    (``final_norm=None``: on for pre-norm stacks, whose residual stream is otherwise unnormalised, off for post-norm)."""

    def __init__(
        self,
        d_model: int,
        depth: int,
        heads: int,
        ffn_dim: int,
        dropout: float = 0.0,
        norm: str = "layer",
        activation: str = "gelu",
        norm_first: bool = False,
        final_norm: bool | None = None,
    ):
        super().__init__()
        self.layers = nn.ModuleList(
            TransformerBlock(d_model, heads, ffn_dim, dropout, norm, activation, norm_first) for _ in range(depth)
        )
        final_norm = norm_first if final_norm is None else final_norm
        self.norm: nn.Module = Norm(norm, d_model) if final_norm else nn.Identity()

    def forward(self, x: Tensor, attn_mask: Tensor | None = None, key_padding_mask: Tensor | None = None) -> Tensor:
        """``x (N, L, D) -> (N, L, D)``."""
        for layer in self.layers:
            x = layer(x, attn_mask=attn_mask, key_padding_mask=key_padding_mask)
        return self.norm(x)


class ResidualMLPBlock(nn.Module):
    """Residual fully connected block on ``(..., D)``: ``act(x + Linear(drop(act(Linear(x)))))`` (ResNet basic block
    with linear layers)."""

    def __init__(self, dim: int, hidden_dim: int | None = None, dropout: float = 0.0, activation: str = "relu"):
        super().__init__()
        hidden_dim = dim if hidden_dim is None else hidden_dim
        self.fc1 = nn.Linear(dim, hidden_dim)
        self.fc2 = nn.Linear(hidden_dim, dim)
        self.act1 = make_activation(activation)
        self.act2 = make_activation(activation)
        self.dropout = nn.Dropout(dropout)

    def forward(self, x: Tensor) -> Tensor:
        """``(..., D) -> (..., D)``."""
        return self.act2(x + self.fc2(self.dropout(self.act1(self.fc1(x)))))


# ---------------------------------------------------------------------------------------------------- helpers
def frame_features(x: Tensor, known: Tensor) -> Tensor:
    """One vector per frame: ``x (B, T, J, F), known (B, T, J) -> (B, T, J*F + J)`` = all joints' features followed
    by the per-joint known flags (1.0 known, 0.0 missing), so per-joint masks reach frame-level models."""
    return torch.cat([x.flatten(2), known.to(x.dtype)], dim=-1)
