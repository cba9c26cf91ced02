"""``benchmarks/train_throughput.py`` counts the FLOPs of the fused CPU attention that torch's own table leaves out."""
import pytest
import torch
from torch.utils.flop_counter import FlopCounterMode

from conftest import benchmark_script


@pytest.fixture(scope="module")
def tp():
    return benchmark_script("train_throughput")


def test_fused_cpu_attention_flops_are_counted(tp):
    n, h, L, d = 3, 2, 7, 4
    q, k, v = (torch.randn(n, h, L, d, requires_grad=True) for _ in range(3))
    with FlopCounterMode(display=False) as plain:
        torch.nn.functional.scaled_dot_product_attention(q, k, v).sum().backward()
    with FlopCounterMode(display=False, custom_mapping=tp.SDPA_CPU_FLOPS) as fc:
        torch.nn.functional.scaled_dot_product_attention(q, k, v).sum().backward()
    qk_pv = 2 * (2 * n * h * L * L * d)  # QKᵀ and PV, 2 FLOPs per multiply-add
    assert plain.get_total_flops() == 0  # what the benchmark reported before: attention counted as free
    # forward: QKᵀ and PV; backward (torch's flash-attention formula): QKᵀ recomputed, dV, dP, dQ, dK
    assert fc.get_total_flops() == qk_pv + qk_pv * 5 // 2


def test_set_groups_apply_only_to_models_with_the_key(tp):
    assert tp.applies("graph_transformer", "model.checkpoint_layers=false")
    assert not tp.applies("unet1d", "model.checkpoint_layers=false")
    assert tp.applies("unet1d", "") and tp.applies("unet1d", "data.batch_size=8")
