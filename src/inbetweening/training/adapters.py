"""Low-rank adapters (LoRA) for fine-tuning (``optim.adapters``): the network's own weights stay where they started
and each chosen linear layer learns a low-rank change ``scale * B @ A`` (``A``: rank x in, ``B``: out x rank, ``B``
zero at the start), the "adapters" lever of the ten-minute fine-tune (issue 51, RESULTS.md 4).

The network always holds the merged weights ``base + scale * B @ A`` (:meth:`LowRankAdapters.merge` after every
optimiser step), so every checkpoint a run writes is a plain network that inference, ``init_keep``, the blend and the
export read as any other.  Gradients reach ``A`` and ``B`` through a forward hook on each layer that adds the low-rank
term of the detached input and takes its value back out (``term - term.detach()``): the output and the gradient
passed back to the input are the merged layer's, the gradients of ``A`` and ``B`` those of LoRA.  ``base``, ``A`` and
``B`` are in the training module's state, so a resume continues exactly.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from fnmatch import fnmatchcase

import torch
import torch.nn.functional as F

from inbetweening.training.config import ConfigError


class LowRankAdapters(torch.nn.Module):
    """Adapters on the ``torch.nn.Linear`` layers of ``net`` whose names match one of ``layers`` (``fnmatch``
    patterns, e.g. ``layers.*``).  Every other parameter of ``net`` is frozen.  ``rank`` > 0; ``alpha`` sets
    ``scale = alpha / rank``; ``A`` is drawn from torch's generator (the run's seed)."""

    def __init__(self, net: torch.nn.Module, rank: int, alpha: float, layers: Sequence[str]):
        super().__init__()
        found = [(n, m) for n, m in net.named_modules() if isinstance(m, torch.nn.Linear)
                 and any(fnmatchcase(n, p) for p in layers)]
        if not found:
            linear = [n for n, m in net.named_modules() if isinstance(m, torch.nn.Linear)]
            raise ConfigError(f"optim.adapters.layers: {list(layers)} matches no linear layer of the network "
                              f"({type(net).__name__}: {', '.join(linear[:6])}{', ...' if len(linear) > 6 else ''})")
        self.rank, self.scale = int(rank), float(alpha) / int(rank)
        self.a = torch.nn.ParameterList()
        self.b = torch.nn.ParameterList()
        for i, (_, m) in enumerate(found):
            fan_in = m.in_features
            self.a.append(torch.nn.Parameter(torch.randn(self.rank, fan_in) / math.sqrt(fan_in)))
            self.b.append(torch.nn.Parameter(torch.zeros(m.out_features, self.rank)))
            self.register_buffer(f"base_{i}", m.weight.detach().clone())
        # False until the first training step takes the network's weights then as the base (after init_from's
        # weights are in); a resumed run restores True with its base
        self.register_buffer("based", torch.zeros((), dtype=torch.bool))
        self._layers = [m for _, m in found]  # not registered: the network owns them
        for i, m in enumerate(self._layers):
            m.register_forward_hook(self._hook(i))
        for p in net.parameters():
            p.requires_grad_(False)

    @classmethod
    def of(cls, net: torch.nn.Module, cfg: Mapping | None) -> LowRankAdapters | None:
        """The adapters ``optim.adapters`` asks for (``rank``, ``alpha``, ``layers``), or ``None`` when it is
        null or its rank is 0."""
        if not cfg or not int(cfg.get("rank") or 0):
            return None
        return cls(net, int(cfg["rank"]), float(cfg.get("alpha") or cfg["rank"]), list(cfg.get("layers") or ["*"]))

    def base(self, i: int) -> torch.Tensor:
        return getattr(self, f"base_{i}")

    def delta(self, i: int) -> torch.Tensor:
        """Layer ``i``'s learned change of weight, ``scale * B @ A``."""
        return self.scale * (self.b[i] @ self.a[i])

    def _hook(self, i: int):
        def hook(module, inputs, out):
            if not (module.training and torch.is_grad_enabled()):
                return out  # the merged weight is the whole layer: nothing to add outside training
            # the input detached: its gradient already flows through the merged weight, low-rank part included
            term = self.scale * F.linear(F.linear(inputs[0].detach(), self.a[i]), self.b[i])
            return out + (term - term.detach())
        return hook

    @torch.no_grad()
    def start(self) -> None:
        """Take the network's weights now as the base (once per run: a resumed run keeps its own)."""
        if bool(self.based):
            return
        for i, m in enumerate(self._layers):
            self.base(i).copy_(m.weight)
        self.based.fill_(True)

    @torch.no_grad()
    def merge(self) -> None:
        """Write ``base + scale * B @ A`` into each adapted layer's weight."""
        for i, m in enumerate(self._layers):
            m.weight.copy_(self.base(i) + self.delta(i).to(m.weight.dtype))
