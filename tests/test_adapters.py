"""``optim.adapters`` (training/adapters.py): low-rank adapters for fine-tuning.  The layer's output and gradients are
checked against LoRA written out here by hand; a fine-tune with adapters writes plain checkpoints whose weights moved
by a change of at most the rank (checked with ``torch.linalg.matrix_rank``), every other weight as it started; a
resumed fine-tune equals the uninterrupted one; bad settings are one line naming the key."""
from __future__ import annotations

import pytest
import torch
import torch.nn.functional as F

from conftest import TINY_CKPT_OVERRIDES, compose_cfg
from inbetweening.predictor.checkpoint import load_predictor, predictor_state
from inbetweening.training.adapters import LowRankAdapters
from inbetweening.training.config import ConfigError, validate
from inbetweening.training.train import train


def test_outputs_and_gradients_are_loras():
    """Through the hooks: the merged network's output, and the gradients of the input and of A and B, equal those of
    y = (W + alpha/r B A) x written out with the same tensors."""
    torch.manual_seed(0)
    net = torch.nn.Sequential(torch.nn.Linear(6, 5), torch.nn.GELU(), torch.nn.Linear(5, 4))
    ad = LowRankAdapters(net, rank=2, alpha=3.0, layers=["*"])
    assert [n for n, p in net.named_parameters() if p.requires_grad] == []  # the network itself is frozen
    for b in ad.b:
        torch.nn.init.normal_(b)  # as after some steps (B starts at zero)
    ad.start()
    ad.merge()
    x = torch.randn(3, 6, requires_grad=True)
    net(x).square().sum().backward()
    a = [t.detach().clone().requires_grad_() for t in ad.a]
    b = [t.detach().clone().requires_grad_() for t in ad.b]
    x2 = x.detach().clone().requires_grad_()
    w = [ad.base(i) + 1.5 * b[i] @ a[i] for i in range(2)]  # alpha / rank = 1.5
    y2 = F.linear(F.gelu(F.linear(x2, w[0], net[0].bias)), w[1], net[2].bias)
    y2.square().sum().backward()
    assert torch.allclose(net(x), y2, atol=1e-6)
    assert torch.allclose(x.grad, x2.grad, atol=1e-5)
    for i in range(2):
        assert torch.allclose(ad.a[i].grad, a[i].grad, atol=1e-5)
        assert torch.allclose(ad.b[i].grad, b[i].grad, atol=1e-5)
    with pytest.raises(ConfigError, match=r"^optim.adapters.layers: \['encoder.\*'\] matches no linear layer"):
        LowRankAdapters(torch.nn.Sequential(torch.nn.Linear(2, 2)), 1, 1.0, ["encoder.*"])


def _finetune(tiny_checkpoint, out, cache_dir, epochs, extra=()):
    data = [o for o in TINY_CKPT_OVERRIDES if o.startswith("data.")]
    cfg = compose_cfg("train", ["experiment=finetune", *data, f"init_from='{tiny_checkpoint}'", "trainer.max_steps=-1",
                                f"trainer.max_epochs={epochs}", "trainer.val_check_interval=null",
                                "trainer.check_val_every_n_epoch=1", "callbacks=default", "callbacks.progress_bar=null",
                                "callbacks.skeleton_figure=null", "logger=none", "run_test=false",
                                "+trainer.enable_progress_bar=false", "optim.adapters.rank=2",
                                "optim.adapters.layers=['layers.*']", "optim.scheduler=null",
                                "optim.optimizer.lr=1e-2", *extra], out, cache_dir)
    validate(cfg)
    train(cfg)
    return out / "checkpoints"


def test_a_finetune_with_adapters_moves_each_layer_by_a_low_rank_change(tiny_checkpoint, tmp_path, cache_dir):
    ckpts = _finetune(tiny_checkpoint, tmp_path / "ft", cache_dir, 1)
    start = predictor_state(torch.load(tiny_checkpoint, map_location="cpu", weights_only=True)["state_dict"])
    last = predictor_state(torch.load(ckpts / "last.ckpt", map_location="cpu", weights_only=True)["state_dict"])
    assert start.keys() == last.keys()  # a plain network: no adapter tensors among the predictor's
    adapted = [k for k in start if k.startswith("net.layers.") and k.endswith(".weight") and start[k].dim() == 2]
    assert adapted
    for k in start:
        if k in adapted:
            change = (last[k] - start[k]).double()
            assert change.abs().max() > 0, k
            assert int(torch.linalg.matrix_rank(change, atol=1e-6)) <= 2, k
        else:
            assert torch.equal(last[k], start[k]), k  # biases, norms, embeddings, the layers outside layers.*
    # what inference reads is what training held: the merged weights
    net = load_predictor(ckpts / "last.ckpt").net
    assert all(torch.equal(v, last["net." + n]) for n, v in net.state_dict().items())


def test_a_resumed_finetune_with_adapters_equals_the_uninterrupted_one(tiny_checkpoint, tmp_path, cache_dir):
    """One epoch, then resumed for a second, against two at once (a constant learning rate: a schedule's length is
    the run's)."""
    full = _finetune(tiny_checkpoint, tmp_path / "full", cache_dir, 2) / "last.ckpt"
    part = _finetune(tiny_checkpoint, tmp_path / "part", cache_dir, 1) / "last.ckpt"
    model = [o for o in TINY_CKPT_OVERRIDES if o.startswith("model.")]  # a resume names the network, not init_from
    _finetune(tiny_checkpoint, tmp_path / "part", cache_dir, 2, [f"ckpt_path={part}", "init_from=null", *model])
    a = torch.load(full, map_location="cpu", weights_only=True)["state_dict"]
    b = torch.load(part, map_location="cpu", weights_only=True)["state_dict"]
    assert a.keys() == b.keys() and any(k.startswith("adapters.") for k in a)
    assert all(torch.equal(a[k], b[k]) for k in a)


@pytest.mark.parametrize("override,pattern", [
    ("optim.adapters.rank=-1", r"^optim.adapters.rank: must be an integer >= 0"),
    ("optim.adapters.alpha=0", r"^optim.adapters.alpha: must be a number > 0"),
    ("optim.adapters.layers=layers", r"^optim.adapters.layers: must be a list of linear-layer name patterns"),
    ("+optim.adapters.dropout=0.1", r"^optim.adapters.dropout: not a setting of the adapters"),
])
def test_bad_adapter_settings_name_the_key(override, pattern, tmp_path, cache_dir):
    with pytest.raises(ConfigError, match=pattern):
        validate(compose_cfg("train", [override], tmp_path, cache_dir))
