"""ResNet + LSTM in-betweening baseline (per-frame residual MLP encoder, recurrent core, MLP decoder).

Each frame's vector (all joints' features followed by the per-joint known flags, ``J*F + J``) goes through fully
connected input layers and residual MLP blocks, an LSTM (bidirectional by default, so the future keyframes are
seen) runs over time, and fully connected output layers map back to ``J*F``.
"""
from __future__ import annotations

from torch import Tensor, nn

from .base import FEATURE_DIM, InbetweenModel
from .blocks import (
    ResidualMLPBlock,
    check_input,
    check_length,
    frame_features,
    make_activation,
    require,
    validate_common,
)


class ResNetLSTM(InbetweenModel):
    """Per-frame residual MLP encoder + LSTM over time + MLP decoder.

    Args (plain values only):
        num_joints: ``J``.  adjacency: ``J x J`` joint relation matrix (checked, otherwise unused).
        feature_dim: features per joint ``F`` (>= 7).
        hidden_dim: width of the fully connected input / residual / output layers.
        res_blocks: number of residual MLP blocks after the input layer (>= 0).
        lstm_hidden, lstm_layers, bidirectional: LSTM size (the output is ``2 * lstm_hidden`` when bidirectional).
        dropout: dropout in the residual blocks, between LSTM layers and before the output layers.
        activation: activation of the fully connected layers.
        max_frames: longest window ``T`` (no position table; checked for consistency with the other models).
        residual_to_interpolation: predict ``interp + head(h)`` when ``interp`` is given (last layer initialised to 0).
    """

    def __init__(
        self,
        num_joints: int,
        adjacency: list[list[float]],
        feature_dim: int = FEATURE_DIM,
        hidden_dim: int = 512,
        res_blocks: int = 2,
        lstm_hidden: int = 512,
        lstm_layers: int = 2,
        bidirectional: bool = True,
        dropout: float = 0.1,
        activation: str = "relu",
        max_frames: int = 128,
        residual_to_interpolation: bool = False,
    ):
        super().__init__()
        name = type(self).__name__
        validate_common(name, num_joints, adjacency, feature_dim, max_frames, dropout)
        require(hidden_dim >= 1, name, f"hidden_dim must be >= 1, got {hidden_dim}")
        require(res_blocks >= 0, name, f"res_blocks must be >= 0, got {res_blocks}")
        require(lstm_hidden >= 1, name, f"lstm_hidden must be >= 1, got {lstm_hidden}")
        require(lstm_layers >= 1, name, f"lstm_layers must be >= 1, got {lstm_layers}")
        make_activation(activation)
        self.num_joints, self.feature_dim, self.max_frames = num_joints, feature_dim, max_frames
        self.residual_to_interpolation = bool(residual_to_interpolation)

        in_dim = num_joints * feature_dim + num_joints
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
            nn.Linear(hidden_dim, num_joints * feature_dim),
        )
        if self.residual_to_interpolation:
            nn.init.zeros_(self.output_layers[-1].weight)
            nn.init.zeros_(self.output_layers[-1].bias)

    def forward(self, x: Tensor, known: Tensor, interp: Tensor | None = None) -> Tensor:
        """``x (B, T, J, F), known (B, T, J) bool, interp (B, T, J, F) | None -> (B, T, J, F)``."""
        check_input(type(self).__name__, x, known, self.num_joints, self.feature_dim)
        check_length(x.shape[1], self.max_frames)
        h = self.res_blocks(self.input_layers(frame_features(x, known)))  # (B, T, H)
        h, _ = self.lstm(h)
        raw = self.output_layers(h).reshape(x.shape)
        if self.residual_to_interpolation and interp is not None:
            raw = interp + raw
        return self.finalize(raw, x, known)
