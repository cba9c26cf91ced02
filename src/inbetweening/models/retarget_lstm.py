"""The retargeting seed's network: fully connected layers and a ResNet block, then fully connected layers and an LSTM,
mapping the source character's motion (one feature vector per frame) to the target character's.

Each frame's source vector goes through ``fc_layers`` fully connected layers and ``res_blocks`` residual MLP blocks,
one more fully connected layer, an LSTM over time (forward only by default: the seed's recurrent retargeter) and a
linear output layer.  ``(B, T, input_dim) -> (B, T, output_dim)``.  The features and losses live in the retargeting
task (:mod:`inbetweening.retarget.module`), not here.
"""
from __future__ import annotations

from torch import Tensor, nn

from .blocks import ResidualMLPBlock, make_activation


class RetargetLSTM(nn.Module):
    """FC + ResNet -> FC + LSTM -> linear.

    Args: input_dim, output_dim: per-frame feature sizes of the source and the target.  hidden_dim: width of the
    fully connected layers.  fc_layers: fully connected layers before the residual blocks (>= 1).  res_blocks:
    residual MLP blocks (>= 0).  lstm_hidden, lstm_layers, bidirectional: the LSTM.  dropout: in the residual blocks
    and between LSTM layers.  activation: of the fully connected layers.
    """

    TINY = {"hidden_dim": 16, "fc_layers": 1, "res_blocks": 1, "lstm_hidden": 16, "lstm_layers": 1}

    def __init__(self, input_dim: int, output_dim: int, hidden_dim: int = 256, fc_layers: int = 2,
                 res_blocks: int = 1, lstm_hidden: int = 256, lstm_layers: int = 1, bidirectional: bool = False,
                 dropout: float = 0.0, activation: str = "relu"):
        super().__init__()
        if min(input_dim, output_dim, hidden_dim, fc_layers, lstm_hidden, lstm_layers) < 1 or res_blocks < 0:
            raise ValueError(f"RetargetLSTM: sizes must be >= 1 (res_blocks >= 0), got input_dim={input_dim}, "
                             f"output_dim={output_dim}, hidden_dim={hidden_dim}, fc_layers={fc_layers}, "
                             f"res_blocks={res_blocks}, lstm_hidden={lstm_hidden}, lstm_layers={lstm_layers}")
        layers: list[nn.Module] = []
        for i in range(fc_layers):
            layers += [nn.Linear(input_dim if i == 0 else hidden_dim, hidden_dim), make_activation(activation)]
        self.encoder = nn.Sequential(*layers)
        self.res_blocks = nn.Sequential(*(ResidualMLPBlock(hidden_dim, hidden_dim, dropout, activation)
                                          for _ in range(res_blocks)))
        self.fc = nn.Sequential(nn.Linear(hidden_dim, hidden_dim), make_activation(activation))
        self.lstm = nn.LSTM(hidden_dim, lstm_hidden, num_layers=lstm_layers, batch_first=True,
                            bidirectional=bool(bidirectional), dropout=dropout if lstm_layers > 1 else 0.0)
        self.output = nn.Linear(lstm_hidden * (2 if bidirectional else 1), output_dim)

    def forward(self, x: Tensor) -> Tensor:
        """``(B, T, input_dim) -> (B, T, output_dim)``."""
        h, _ = self.lstm(self.fc(self.res_blocks(self.encoder(x))))
        return self.output(h)
