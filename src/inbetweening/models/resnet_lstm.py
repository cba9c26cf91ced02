"""ResNet + LSTM in-betweening baseline (per-frame residual MLP encoder, recurrent core, MLP decoder).

Each frame's vector (all joints' features followed by the per-joint known flags, ``J*F + J``) goes through fully
connected input layers and residual MLP blocks, an LSTM (bidirectional by default, so the future keyframes are
seen) runs over time, and fully connected output layers map back to ``J*F``.
"""
from __future__ import annotations

from typing import Any

from torch import Tensor, nn

from .base import Checks, InbetweenModel
from .blocks import ResidualMLPBlock, frame_features, make_activation


class ResNetLSTM(InbetweenModel):
    """Per-frame residual MLP encoder + LSTM over time + MLP decoder.

    Args (plain values only; common ones, with their defaults, in :class:`InbetweenModel`):
        num_joints: ``J``.  adjacency: ``J x J`` joint relation matrix (checked, otherwise unused).
        hidden_dim: width of the fully connected input / residual / output layers.
        res_blocks: number of residual MLP blocks after the input layer (>= 0).
        lstm_hidden, lstm_layers, bidirectional: LSTM size (the output is ``2 * lstm_hidden`` when bidirectional).
        dropout: dropout in the residual blocks, between LSTM layers and before the output layers.
        activation: activation of the fully connected layers.
        max_frames: longest window ``T`` (no position table; checked for consistency with the other models).
    """

    OUTPUT_HEAD = ("output_layers.3",)  # the last Linear of output_layers
    TINY = {"hidden_dim": 32, "res_blocks": 1, "lstm_hidden": 16, "lstm_layers": 2}

    def __init__(
        self,
        num_joints: int,
        adjacency: list[list[float]],
        hidden_dim: int = 512,
        res_blocks: int = 2,
        lstm_hidden: int = 512,
        lstm_layers: int = 2,
        bidirectional: bool = True,
        dropout: float = 0.1,
        activation: str = "relu",
        **common: Any,
    ):
        super().__init__(num_joints, adjacency, dropout=dropout, **common)
        in_dim = num_joints * self.input_dim + num_joints
        self.input_layers = nn.Sequential(nn.Linear(in_dim, hidden_dim), make_activation(activation))
        self.res_blocks = nn.Sequential(
            *(ResidualMLPBlock(hidden_dim, hidden_dim, dropout, activation) for _ in range(res_blocks))
        )
        self.lstm = nn.LSTM(hidden_dim, lstm_hidden, num_layers=lstm_layers, batch_first=True,
                            bidirectional=bool(bidirectional), dropout=dropout if lstm_layers > 1 else 0.0)
        lstm_out = lstm_hidden * (2 if bidirectional else 1)
        self.output_layers = nn.Sequential(
            nn.Dropout(dropout),
            nn.Linear(lstm_out, hidden_dim),
            make_activation(activation),
            nn.Linear(hidden_dim, num_joints * self.output_dim),
        )

    @classmethod
    def check_settings(cls, checks: Checks) -> None:
        checks.integer("hidden_dim", "lstm_hidden", "lstm_layers")
        checks.integer("res_blocks", minimum=0)
        checks.activation()

    def network(self, x: Tensor, known: Tensor, interp: Tensor | None) -> Tensor:
        """``x (B, T, J, F), known (B, T, J) bool, interp unused -> raw (B, T, J, F)``."""
        h = self.res_blocks(self.input_layers(frame_features(x, known)))  # (B, T, H)
        h, _ = self.lstm(h)
        return self.output_layers(h).reshape(*x.shape[:-1], self.output_dim)
