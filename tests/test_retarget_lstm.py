"""The retargeting seed's network (src/inbetweening/models/retarget_lstm.py)."""
from __future__ import annotations

import pytest
import torch

from inbetweening.models import RETARGETERS, build_retargeter
from inbetweening.models.retarget_lstm import RetargetLSTM


def test_shapes_and_the_registry():
    net = build_retargeter({"name": "retarget_lstm", **RetargetLSTM.TINY}, 10, 7)
    assert isinstance(net, RETARGETERS["retarget_lstm"])
    assert net(torch.randn(3, 20, 10)).shape == (3, 20, 7)


def test_forward_only_lstm_is_causal_and_bidirectional_is_not():
    """A frame's output depends on the frames up to it only (the seed's forward LSTM); bidirectional sees the future."""
    torch.manual_seed(0)
    x = torch.randn(1, 12, 5)
    later = x.clone()
    later[:, 8:] += 1.0
    for bi in (False, True):
        net = RetargetLSTM(5, 4, **{**RetargetLSTM.TINY, "bidirectional": bi}).eval()
        same = torch.allclose(net(x)[:, :8], net(later)[:, :8])
        assert same is (not bi)


def test_bad_sizes_and_names_say_which():
    with pytest.raises(ValueError, match="fc_layers=0"):
        RetargetLSTM(5, 4, fc_layers=0)
    with pytest.raises(ValueError, match="model.name: 'resnet_lstm' is not a retargeting network"):
        build_retargeter({"name": "resnet_lstm"}, 5, 4)
