"""Graph-attention transformer and shared blocks: graph modes, graph locality, trainability, its own setting checks
(the common model contract is tests/test_models_base.py)."""
from __future__ import annotations

import pytest
import torch
import torch.nn.functional as F

from conftest import TINY_PARENTS, sinusoid_batch, tiny_adjacency, tiny_model
from inbetweening.models import GraphTransformer
from inbetweening.models.blocks import MultiHeadAttention, Norm

J = len(TINY_PARENTS)
M = torch.tensor(tiny_adjacency())
OUTSIDE = [(j, k) for j in range(J) for k in range(J) if M[j, k] == 0]


def tiny(**kw) -> GraphTransformer:
    """GraphTransformer with its TINY sizes (conftest.tiny_model); ``kw`` wins."""
    return tiny_model("graph_transformer", **kw)


def make_batch(b=2, t=8, seed=0):
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(b, t, J, 7, generator=g)
    known = torch.zeros(b, t, J, dtype=torch.bool)
    known[:, :2] = True
    known[:, -1] = True
    known[0, 4, 3] = True  # a single known joint inside the gap
    return x * known[..., None], known


@pytest.fixture(autouse=True)
def _seed():
    torch.manual_seed(0)


# ------------------------------------------------------------------ graph modes, position encodings
@pytest.mark.parametrize("graph", ["multiply", "multiply_full", "learned", "none"])
def test_shape_known_passthrough_unit_quaternions(graph):
    model = tiny(graph=graph)
    x, known = make_batch()
    out = model(x, known)
    assert out.shape == x.shape
    assert torch.equal(out[known], x[known])
    qn = out[..., 3:7].norm(dim=-1)[~known]
    assert torch.allclose(qn, torch.ones_like(qn), atol=1e-5)


def test_dynamic_length_and_batch_eval():
    model = tiny(depth=1, pos_encoding="learned").eval()
    for b, t in [(1, 5), (3, 16)]:
        x, known = make_batch(b, t)
        with torch.no_grad():
            assert model(x, known).shape == (b, t, J, 7)


# ------------------------------------------------------------------ graph locality of the spatial attention
def _perturb(x: torch.Tensor, k: int) -> torch.Tensor:
    x2 = x.clone()
    x2[:, k] += torch.randn_like(x2[:, k])
    return x2


def test_effective_attention_is_zero_outside_neighbourhood():
    attn = MultiHeadAttention(16, 2)
    x = torch.randn(3, J, 16)
    w = attn.attention_probs(x, prob_mask=M)
    assert w.shape == (3, 2, J, J)
    outside = (M == 0).expand_as(w)
    assert torch.all(w[outside] == 0) and torch.all(w[~outside] > 0)
    assert torch.all(attn.attention_probs(x) > 0)


@pytest.mark.parametrize("j,k", OUTSIDE[:6])
def test_value_of_non_neighbour_does_not_reach_joint(j, k):
    """Exact locality of Z = (M ⊙ P) V: joint k's value never reaches joint j when M[j, k] = 0."""
    attn = MultiHeadAttention(16, 2)
    x = torch.randn(4, J, 16)
    delta = torch.randn(4, 16)

    def run(prob_mask, perturb):
        def hook(_mod, _inp, v):
            if perturb:
                v = v.clone()
                v[:, k] += delta
            return v

        handle = attn.v_proj.register_forward_hook(hook)
        try:
            return attn(x, prob_mask=prob_mask)[:, j]
        finally:
            handle.remove()

    assert torch.allclose(run(M, False), run(M, True), atol=1e-6)
    assert not torch.allclose(run(None, False), run(None, True), atol=1e-3)


@pytest.mark.parametrize("j,k", OUTSIDE[:6])
def test_input_of_non_neighbour_only_rescales_heads(j, k):
    """Perturbing input joint k (M[j, k] = 0) changes joint j only through the softmax denominator (the method does
    not renormalise after ⊙ M): each head's output at j is multiplied by a positive scalar.  With plain attention
    the direction changes."""
    heads, d = 2, 16
    attn = MultiHeadAttention(d, heads)
    with torch.no_grad():  # identity W_O so the output exposes the concatenated heads
        attn.out_proj.weight.copy_(torch.eye(d))
        attn.out_proj.bias.zero_()
    x = torch.randn(4, J, d)
    x2 = _perturb(x, k)

    def head_cos(prob_mask):
        a = attn(x, prob_mask=prob_mask)[:, j].reshape(4, heads, -1)
        b = attn(x2, prob_mask=prob_mask)[:, j].reshape(4, heads, -1)
        return F.cosine_similarity(a, b, dim=-1)

    assert torch.allclose(head_cos(M), torch.ones(4, heads), atol=1e-5)
    assert (head_cos(None) < 1 - 1e-4).any()


@pytest.mark.parametrize("j,k", OUTSIDE[:4])
def test_spatial_sublayer_locality_with_masked_softmax(j, k):
    """graph='multiply' (softmax over the neighbourhood, then ⊙ M): locality holds exactly at the input level."""
    attn = MultiHeadAttention(16, 2)
    x = torch.randn(4, J, 16)
    x2 = _perturb(x, k)
    mask = M == 0
    assert torch.allclose(attn(x, prob_mask=M, attn_mask=mask)[:, j], attn(x2, prob_mask=M, attn_mask=mask)[:, j], atol=1e-6)
    assert not torch.allclose(attn(x)[:, j], attn(x2)[:, j], atol=1e-4)


def test_model_depth1_graph_multiply_locality():
    """Depth 1 with graph='multiply': joint j's outputs (all frames) ignore non-neighbour input joints; with
    'none' or the literal 'multiply_full' (softmax over all joints) they do not."""
    j, k = OUTSIDE[0]
    x, known = make_batch()
    x2 = x.clone()
    x2[:, 3:6, k] += 1.0  # unknown frames only, known values are passed through anyway
    for graph, same in [("multiply", True), ("none", False), ("multiply_full", False)]:
        model = tiny(depth=1, graph=graph).eval()
        with torch.no_grad():
            diff = (model(x, known)[:, :, j] - model(x2, known)[:, :, j]).abs().max()
        assert (diff < 1e-5) == same, (graph, diff)


# ------------------------------------------------------------------ attention vs reference
def _reference(attn: MultiHeadAttention, x, mask=None):
    n, length, d = x.shape

    def split(t):
        return t.reshape(n, length, attn.heads, -1).transpose(1, 2)

    q, k, v = split(attn.q_proj(x)), split(attn.k_proj(x)), split(attn.v_proj(x))
    z = F.scaled_dot_product_attention(q, k, v, attn_mask=mask)
    return attn.out_proj(z.transpose(1, 2).reshape(n, length, d))


def test_attention_matches_sdpa_reference():
    attn = MultiHeadAttention(16, 4).eval()
    x = torch.randn(3, 7, 16)
    ref = _reference(attn, x)
    assert torch.allclose(attn(x), ref, atol=1e-5)
    assert torch.allclose(attn(x, prob_mask=torch.ones(7, 7)), ref, atol=1e-6)
    causal = torch.triu(torch.ones(7, 7, dtype=torch.bool), 1)  # True = not allowed (nn.MultiheadAttention style)
    assert torch.allclose(attn(x, attn_mask=causal), _reference(attn, x, ~causal), atol=1e-5)
    pad = torch.zeros(3, 7, dtype=torch.bool)
    pad[1, 5:] = True
    assert torch.allclose(attn(x, key_padding_mask=pad), _reference(attn, x, ~pad[:, None, None, :]), atol=1e-5)
    additive = torch.randn(7, 7)
    assert torch.allclose(attn(x, attn_mask=additive), _reference(attn, x, additive), atol=1e-5)


def test_explicit_attention_gives_the_fused_values_and_gradients(monkeypatch):
    """``fused_attention=false`` (the speed option for bf16 autocast on the CPU) runs no fused kernel, spatial or
    temporal, and computes the same outputs and gradients."""
    x, known = make_batch()
    calls, sdpa = [], F.scaled_dot_product_attention
    monkeypatch.setattr(F, "scaled_dot_product_attention", lambda *a, **k: calls.append(1) or sdpa(*a, **k))
    outs = []
    for fused in (True, False):
        torch.manual_seed(0)
        model = tiny(fused_attention=fused, residual_to_interpolation=False).train()
        calls.clear()
        out = model(x, known)
        out.square().sum().backward()
        assert bool(calls) == fused
        outs.append((out.detach(), [p.grad for p in model.parameters()]))
    (o1, g1), (o2, g2) = outs
    assert torch.allclose(o1, o2, atol=1e-5)
    assert all(torch.allclose(a, b, atol=1e-4, rtol=1e-4) for a, b in zip(g1, g2))


def test_batch_norm_flattens_leading_dims():
    norm = Norm("batch", 8)
    x = torch.randn(2, 3, 4, 8)
    assert torch.allclose(norm(x), norm.norm(x.reshape(-1, 8)).reshape(x.shape))
    with pytest.raises(ValueError, match="norm"):
        Norm("group", 8)


# ------------------------------------------------------------------ trainability
@pytest.mark.parametrize("norm", ["layer", "batch"])
def test_trains(norm):
    model = tiny(norm=norm)
    opt = torch.optim.Adam(model.parameters(), lr=3e-3)
    x, known, y = sinusoid_batch(J)
    losses = []
    for _ in range(30):
        loss = (model(x, known) - y).abs().mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(loss.item())
    assert sum(losses[-5:]) / 5 < 0.7 * losses[0], losses


# ------------------------------------------------------------------ validation
@pytest.mark.parametrize(
    "kw,match",
    [
        ({"depth": 0}, r"depth: must be an integer >= 1, got 0$"),
        ({"heads": 3}, r"heads: 3 must divide d_model=16$"),
        ({"d_model": 0}, r"d_model: must be an integer >= 1, got 0$"),
        ({"ffn_dim": 0}, r"ffn_dim: must be an integer >= 1, got 0$"),
        ({"hops": -1}, r"hops: must be an integer >= 0, got -1$"),
        ({"norm": "group"}, r"norm: must be one of \['layer', 'batch'\], got 'group'$"),
        ({"graph": "add"}, r"graph: must be one of \['multiply', 'multiply_full', 'learned', 'none'\], got 'add'$"),
        ({"pos_encoding": "rope"}, r"pos_encoding: must be one of \['sinusoidal', 'learned'\], got 'rope'$"),
        ({"activation": "swish"}, r"activation: must be one of"),
        ({"adjacency": [[1.0, 0.0], [0.0]]}, r"adjacency: must be a J x J nested list of numbers"),
    ],
)
def test_invalid_args(kw, match):
    with pytest.raises(ValueError, match=rf"^GraphTransformer: {match}"):
        tiny(**kw)


def test_learned_relation_starts_at_m_and_is_trained():
    """graph='learned': M is a parameter that starts as the skeleton's M (so the first forward equals multiply_full's)
    and moves with training, also where M is 0 (a relation to a joint that is not a neighbour can open)."""
    torch.manual_seed(0)
    learned, full = tiny(graph="learned"), tiny(graph="multiply_full")
    full.load_state_dict({k: v for k, v in learned.state_dict().items() if k != "relation"})
    assert torch.equal(learned.relation.detach(), learned.adjacency)
    x, known = make_batch()
    out = learned(x, known)
    assert torch.allclose(out, full(x, known), atol=1e-6)
    out[~known].pow(2).mean().backward()
    grad = learned.relation.grad
    assert grad is not None and grad[M == 0].abs().max() > 0
