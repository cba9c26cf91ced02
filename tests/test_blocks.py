"""The fused attention path (``scaled_dot_product_attention``) against the explicit one it replaces."""
import numpy as np
import pytest
import torch

from inbetweening.geometry.skeleton import Skeleton
from inbetweening.models.blocks import MultiHeadAttention
from inbetweening.models.graph_transformer import GraphTransformer

SK = Skeleton(("a", "b", "c", "d", "e"), (-1, 0, 1, 1, 3), np.zeros((5, 3)))


def _explicit(attn: MultiHeadAttention, x, prob_mask=None, attn_mask=None):
    probs = attn.attention_probs(x, prob_mask, attn_mask)
    out = torch.matmul(probs, attn._split(attn.v_proj(x))).transpose(1, 2).reshape(x.shape[0], -1, attn.d_model)
    return attn.out_proj(out)


@pytest.mark.parametrize("masked", [False, True])
def test_fused_equals_explicit_forward_and_gradients(masked):
    torch.manual_seed(0)
    attn = MultiHeadAttention(16, 4).train()
    x = torch.randn(6, 5, 16, requires_grad=True)
    mask = torch.as_tensor(SK.adjacency() <= 0) if masked else None
    fused = attn(x, attn_mask=mask)
    (gf,) = torch.autograd.grad(fused.square().sum(), x)
    ref = _explicit(attn, x, attn_mask=mask)
    (gr,) = torch.autograd.grad(ref.square().sum(), x)
    assert torch.allclose(fused, ref, atol=1e-6)
    assert torch.allclose(gf, gr, atol=1e-5)
    if masked:  # a non-neighbour's value cannot reach a joint
        x2 = x.detach().clone()
        x2[:, 4] += 10.0  # joint e (child of d) is not a neighbour of a
        assert torch.allclose(attn(x2, attn_mask=mask)[:, 0], fused.detach()[:, 0], atol=1e-6)


def test_binary_graph_multiply_skips_the_product_exactly():
    """For a 0/1 relation matrix, M ⊙ softmax over the neighbourhood equals the neighbourhood softmax itself."""
    torch.manual_seed(0)
    attn = MultiHeadAttention(8, 2)
    x = torch.randn(3, 5, 8)
    adj = torch.as_tensor(SK.adjacency())
    with_product = attn.attention_probs(x, prob_mask=adj, attn_mask=adj <= 0)
    without = attn.attention_probs(x, attn_mask=adj <= 0)
    assert torch.equal(with_product, without)


def test_graph_transformer_uses_the_product_only_for_weighted_graphs():
    binary = GraphTransformer(5, SK.adjacency().tolist(), d_model=8, depth=1, heads=2)
    weighted_adj = SK.adjacency() * 0.5 + np.eye(5) * 0.5
    weighted = GraphTransformer(5, weighted_adj.tolist(), d_model=8, depth=1, heads=2)
    assert binary._graph_masks()[0] is None and binary._graph_masks()[1] is not None
    assert weighted._graph_masks()[0] is not None


def test_fully_masked_row_stays_finite():
    attn = MultiHeadAttention(8, 2)
    mask = torch.zeros(4, 4, dtype=torch.bool)
    mask[0] = True  # query 0 may attend to nothing
    out = attn(torch.randn(2, 4, 8), attn_mask=mask)
    assert torch.isfinite(out).all()


@pytest.mark.parametrize("dropout", [0.0, 0.2])
def test_checkpointed_layers_give_the_same_output_and_gradients(dropout):
    """Activation checkpointing recomputes each layer in backward: same values, same gradients (dropout's RNG
    state is replayed), only the memory differs."""
    grads = []
    for ck in (False, True):
        torch.manual_seed(0)
        m = GraphTransformer(5, SK.adjacency().tolist(), d_model=8, depth=2, heads=2, dropout=dropout,
                             checkpoint_layers=ck, residual_to_interpolation=False).train()
        torch.manual_seed(1)
        x = torch.randn(3, 6, 5, 7)
        known = torch.zeros(3, 6, 5, dtype=torch.bool)
        known[:, 0] = True
        out = m(x, known, x)
        out.square().sum().backward()
        grads.append((out.detach(), [p.grad.clone() for p in m.parameters() if p.grad is not None]))
    assert torch.equal(grads[0][0], grads[1][0])
    assert len(grads[0][1]) == len(grads[1][1]) > 0
    for a, b in zip(grads[0][1], grads[1][1]):
        assert torch.allclose(a, b, rtol=1e-5, atol=1e-7)
