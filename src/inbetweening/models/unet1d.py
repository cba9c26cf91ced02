"""1D fully convolutional U-Net over time (conv in-betweening baseline).

Channels are the per-frame vector (all joints' features followed by the per-joint known flags, ``J*F + J``).
Encoder: ``levels`` stages of (Conv1d - GroupNorm - act) x 2, each followed by a stride-2 Conv1d downsample;
bottleneck; decoder: ConvTranspose1d (x2) upsample, concatenation with the skip, (Conv1d - GroupNorm - act) x 2;
1x1 Conv1d output to ``J*F``.  Any ``T`` works: the sequence is zero-padded (known flags 0) up to a multiple of
``2**levels`` and the output cropped back.
"""
from __future__ import annotations

from typing import Any

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from .base import Checks, InbetweenModel
from .blocks import frame_features, make_activation


class ConvBlock1d(nn.Module):
    """``(Conv1d(k=3) - GroupNorm - act) x 2`` on ``(N, C_in, L) -> (N, C_out, L)``."""

    def __init__(self, in_ch: int, out_ch: int, groups: int, activation: str, dropout: float = 0.0):
        super().__init__()
        self.net = nn.Sequential(
            nn.Conv1d(in_ch, out_ch, kernel_size=3, padding=1),
            nn.GroupNorm(groups, out_ch),
            make_activation(activation),
            nn.Dropout(dropout),
            nn.Conv1d(out_ch, out_ch, kernel_size=3, padding=1),
            nn.GroupNorm(groups, out_ch),
            make_activation(activation),
        )

    def forward(self, x: Tensor) -> Tensor:
        """``(N, C_in, L) -> (N, C_out, L)``."""
        return self.net(x)


class UNet1D(InbetweenModel):
    """Temporal 1D U-Net.

    Args (plain values only; common ones, with their defaults, in :class:`InbetweenModel`):
        num_joints: ``J``.  adjacency: ``J x J`` joint relation matrix (checked, otherwise unused).
        base_channels: channels of the first stage; stage ``i`` has ``base_channels * 2**i`` (bottleneck ``i=levels``).
        levels: number of down/up-sampling stages (>= 1); ``T`` is padded to a multiple of ``2**levels``.
        norm_groups: GroupNorm groups (must divide ``base_channels``).
        dropout: dropout inside the conv blocks.  activation: conv activation.
        max_frames: longest window ``T`` (no position table; checked for consistency with the other models).
    """

    OUTPUT_HEAD = ("head",)
    TINY = {"base_channels": 16, "levels": 2, "norm_groups": 4}

    def __init__(
        self,
        num_joints: int,
        adjacency: list[list[float]],
        base_channels: int = 64,
        levels: int = 3,
        norm_groups: int = 8,
        activation: str = "silu",
        **common: Any,
    ):
        super().__init__(num_joints, adjacency, **common)
        self.levels, self.multiple = levels, 2**levels
        chans = [base_channels * 2**i for i in range(levels + 1)]
        in_ch = num_joints * self.input_dim + num_joints
        self.down_blocks = nn.ModuleList()
        self.downsample = nn.ModuleList()
        for i in range(levels):
            self.down_blocks.append(ConvBlock1d(in_ch if i == 0 else chans[i - 1], chans[i], norm_groups, activation,
                                                self.dropout))
            self.downsample.append(nn.Conv1d(chans[i], chans[i], kernel_size=3, stride=2, padding=1))
        self.bottleneck = ConvBlock1d(chans[levels - 1], chans[levels], norm_groups, activation, self.dropout)
        self.upsample = nn.ModuleList()
        self.up_blocks = nn.ModuleList()
        for i in reversed(range(levels)):
            self.upsample.append(nn.ConvTranspose1d(chans[i + 1], chans[i], kernel_size=2, stride=2))
            self.up_blocks.append(ConvBlock1d(2 * chans[i], chans[i], norm_groups, activation, self.dropout))
        self.head = nn.Conv1d(chans[0], num_joints * self.output_dim, kernel_size=1)

    @classmethod
    def check_settings(cls, checks: Checks) -> None:
        checks.integer("base_channels", "levels", "norm_groups")
        checks.divides("norm_groups", "base_channels")
        checks.activation()

    def network(self, x: Tensor, known: Tensor, interp: Tensor | None) -> Tensor:
        """``x (B, T, J, F), known (B, T, J) bool, interp unused -> raw (B, T, J, F)``."""
        t = x.shape[1]
        h = frame_features(x, known).transpose(1, 2)  # (B, C, T)
        h = F.pad(h, (0, (self.multiple - t % self.multiple) % self.multiple))  # T -> multiple of 2**levels
        skips = []
        for block, down in zip(self.down_blocks, self.downsample):
            h = block(h)
            skips.append(h)
            h = down(h)
        h = self.bottleneck(h)
        for up, block, skip in zip(self.upsample, self.up_blocks, reversed(skips)):
            h = block(torch.cat([up(h), skip], dim=1))
        return self.head(h)[:, :, :t].transpose(1, 2).reshape(*x.shape[:-1], self.output_dim)
