"""Graph-attention in-betweening transformer (patent CN113112577A).

Tokens are the joints of every frame.  Each layer: (a) spatial self-attention across the ``J`` joints of a frame
whose attention probabilities are multiplied by the joint relation matrix ``M`` (``Z = (M ⊙ softmax(QKᵀ/√d)) V``
per head, no renormalisation); residual + norm; (b) temporal self-attention across the ``T`` frames of each joint;
residual + norm; (c) feed-forward; residual + norm (post-norm throughout).
"""
from __future__ import annotations

from typing import Any

import torch
from torch import Tensor, nn
from torch.utils.checkpoint import checkpoint

from .base import Checks, InbetweenModel
from .blocks import (
    NORMS,
    AddNorm,
    FeedForward,
    MultiHeadAttention,
    PositionEmbedding,
    SinusoidalPositionalEncoding,
    fused_attention_ok,
)

# multiply      : Z = (M ⊙ softmax_M(QKᵀ/√d)) V, the softmax taken over the M-neighbourhood, so a joint's output
#                 depends only on its neighbours (exact locality; for binary M the product keeps the support).
# multiply_full : the formula read literally, softmax over ALL joints then ⊙ M, no renormalisation; non-neighbours
#                 still leak in through the softmax normaliser (kept as an ablation).
# none          : plain attention over all joints (what M buys).
GRAPH_MODES = ("multiply", "multiply_full", "learned", "none")
POS_ENCODINGS = ("sinusoidal", "learned")


class GraphTransformerLayer(nn.Module):
    """One spatial (graph) + temporal + feed-forward layer on ``(B, T, J, D)``."""

    def __init__(self, d_model: int, heads: int, ffn_dim: int, dropout: float, norm: str, activation: str = "gelu"):
        super().__init__()
        self.spatial = MultiHeadAttention(d_model, heads, dropout)
        self.spatial_norm = AddNorm(d_model, norm, dropout)
        self.temporal = MultiHeadAttention(d_model, heads, dropout)
        self.temporal_norm = AddNorm(d_model, norm, dropout)
        self.ffn = FeedForward(d_model, ffn_dim, dropout, activation)
        self.ffn_norm = AddNorm(d_model, norm, dropout)

    def forward(self, h: Tensor, prob_mask: Tensor | None = None, attn_mask: Tensor | None = None,
                fused: bool | None = None, fused_temporal: bool | None = None) -> Tensor:
        """``h (B, T, J, D), prob_mask / attn_mask (J, J) | None -> (B, T, J, D)``; ``fused`` (spatial) and
        ``fused_temporal``: see :meth:`MultiHeadAttention.forward`."""
        j, d = h.shape[-2], h.shape[-1]
        t = h.shape[1]
        s = h.reshape(-1, j, d)  # (B*T, J, D)
        s = self.spatial_norm(s, self.spatial(s, prob_mask=prob_mask, attn_mask=attn_mask, fused=fused))
        tm = s.reshape(-1, t, j, d).transpose(1, 2).reshape(-1, t, d)  # (B*J, T, D)
        tm = self.temporal_norm(tm, self.temporal(tm, fused=fused_temporal))
        h = tm.reshape(-1, j, t, d).transpose(1, 2)  # (B, T, J, D)
        return self.ffn_norm(h, self.ffn(h))


class GraphTransformer(InbetweenModel):
    """Graph-attention in-betweening transformer.

    Args (plain values only, so it can be built from a Hydra config; common ones, with their defaults, in
    :class:`InbetweenModel`):
        num_joints, adjacency: ``J`` and the joint relation matrix ``M`` (1 for parent/child and the diagonal; it
            may already encode k-hop neighbourhoods, see ``hops``).
        d_model, depth, heads: transformer width, number of layers, attention heads (``d_model % heads == 0``).
        ffn_dim: feed-forward hidden width (default ``2 * d_model``).
        dropout: dropout of attention probabilities, residual branches and the feed-forward hidden layer.
        norm: ``"layer"`` or ``"batch"``.
        graph: ``"multiply"`` (the method: M ⊙ softmax over the M-neighbourhood), ``"multiply_full"`` (softmax over
            all joints then ⊙ M, the formula read literally), ``"learned"`` (as ``multiply_full`` with M a trained
            parameter, initialised at the skeleton's M: the relation may open to joints that are not neighbours, or
            close) or ``"none"`` (plain attention); see ``GRAPH_MODES``.
        max_frames: longest supported window ``T``.
        hops: documentation only (the adjacency passed in already encodes it).
        pos_encoding: temporal position encoding, ``"sinusoidal"`` or ``"learned"``.
        activation: feed-forward activation (``gelu``, ``relu``, ``silu``, ``tanh``).
        checkpoint_layers: while training, keep only each layer's input for the backward pass and recompute the
            layer there (activation checkpointing): a fraction of the memory for about one more forward pass.
        fused_attention: attention through PyTorch's fused ``scaled_dot_product_attention`` where the masks allow it
            (``True``), or always the explicit matmul-softmax-matmul path (``False``: the same values; under bf16
            autocast on the CPU the fused kernel's backward is slow, BENCHMARKS.md "Training step: where the time
            goes").
    """

    OUTPUT_HEAD = ("out_weight", "out_bias")
    TINY = {"d_model": 16, "depth": 1, "heads": 2}

    def __init__(
        self,
        num_joints: int,
        adjacency: list[list[float]],
        d_model: int = 64,
        depth: int = 6,
        heads: int = 4,
        ffn_dim: int | None = None,
        norm: str = "layer",
        graph: str = "multiply",
        hops: int = 1,
        pos_encoding: str = "sinusoidal",
        activation: str = "gelu",
        checkpoint_layers: bool = True,
        fused_attention: bool = True,
        **common: Any,
    ):
        super().__init__(num_joints, adjacency, **common)
        self.checkpoint_layers = bool(checkpoint_layers)
        ffn_dim = 2 * d_model if ffn_dim is None else ffn_dim
        adj = torch.as_tensor(adjacency, dtype=torch.float32)
        self.d_model, self.graph, self.hops = d_model, graph, hops
        self.register_buffer("adjacency", adj)
        if graph == "multiply":  # softmax restricted to the neighbourhood: -inf (finite min) outside it
            self.register_buffer("graph_attn_mask", adj <= 0, persistent=False)
        if graph == "learned":  # M trained, from the skeleton's
            self.relation = nn.Parameter(adj.clone())
        self.binary_graph = bool(((adj == 0) | (adj == 1)).all())
        # the masks are fixed: whether the fused attention applies is decided once (not per layer call, which would
        # read the mask's values and split a torch.compile graph at every layer)
        self._fused_temporal = bool(fused_attention)
        self._fused = self._fused_temporal and fused_attention_ok(*self._graph_masks(), None)

        # per-joint input projection (J separate Linear layers as one batched einsum)
        self.in_weight = nn.Parameter(torch.empty(num_joints, self.input_dim, d_model))
        self.in_bias = nn.Parameter(torch.zeros(num_joints, d_model))
        self.joint_embed = nn.Parameter(torch.randn(num_joints, d_model) * 0.02)
        self.flag_embed = nn.Embedding(2, d_model)
        nn.init.normal_(self.flag_embed.weight, std=0.02)
        if pos_encoding == "learned":
            self.time_embed: nn.Module = PositionEmbedding(self.max_frames, d_model)
        else:
            self.time_embed = SinusoidalPositionalEncoding(d_model, self.max_frames)
        self.layers = nn.ModuleList(
            GraphTransformerLayer(d_model, heads, ffn_dim, self.dropout, norm, activation) for _ in range(depth)
        )
        # per-joint output head
        self.out_weight = nn.Parameter(torch.empty(num_joints, d_model, self.output_dim))
        self.out_bias = nn.Parameter(torch.zeros(num_joints, self.output_dim))
        with torch.no_grad():  # same scale as nn.Linear's default init (uniform ±1/sqrt(fan_in)), per joint
            self.in_weight.uniform_(-self.input_dim**-0.5, self.input_dim**-0.5)

    @classmethod
    def check_settings(cls, checks: Checks) -> None:
        checks.integer("d_model", "depth", "heads")
        checks.integer("ffn_dim", optional=True)
        checks.integer("hops", minimum=0)
        checks.divides("heads", "d_model")
        checks.one_of("norm", NORMS)
        checks.one_of("graph", GRAPH_MODES)
        checks.one_of("pos_encoding", POS_ENCODINGS)
        checks.activation()

    def init_output_head(self) -> None:
        with torch.no_grad():  # uniform ±1/sqrt(d_model) like nn.Linear, per joint (zero when residual)
            self.out_weight.uniform_(-self.d_model**-0.5, self.d_model**-0.5)

    def _graph_masks(self) -> tuple[Tensor | None, Tensor | None]:
        if self.graph == "multiply":
            # binary M: the softmax over the neighbourhood is exactly 0 outside it and M is 1 inside, so the product
            # changes nothing and the fused attention (no (N, H, J, J) tensors kept for backward) computes it
            return (None if self.binary_graph else self.adjacency), self.graph_attn_mask
        if self.graph == "multiply_full":
            return self.adjacency, None
        if self.graph == "learned":
            return self.relation, None
        return None, None

    def network(self, x: Tensor, known: Tensor, interp: Tensor | None) -> Tensor:
        """``x (B, T, J, F), known (B, T, J) bool, interp unused -> raw (B, T, J, F)``."""
        h = torch.einsum("btjf,jfd->btjd", x, self.in_weight) + self.in_bias
        h = h + self.joint_embed + self.flag_embed(known.long())
        h = h + self.time_embed(x.shape[1])[:, None, :]
        prob_mask, attn_mask = self._graph_masks()
        fused, fused_temporal = self._fused, self._fused_temporal
        recompute = self.checkpoint_layers and self.training and torch.is_grad_enabled()
        for layer in self.layers:
            if recompute:  # keep only each layer's input for backward; its activations are recomputed there
                h = checkpoint(layer, h, prob_mask=prob_mask, attn_mask=attn_mask, fused=fused,
                               fused_temporal=fused_temporal, use_reentrant=False)
            else:
                h = layer(h, prob_mask=prob_mask, attn_mask=attn_mask, fused=fused, fused_temporal=fused_temporal)
        return torch.einsum("btjd,jdf->btjf", h, self.out_weight) + self.out_bias
