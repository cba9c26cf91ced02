"""One path from (root, local quaternions) windows to predicted transitions, shared by validation,
``eval.py``, the benchmark and the animator tools, so every number comes from the same code."""
from __future__ import annotations

import numpy as np
import torch

from . import features as F
from .masks import apply_mask, transition_known
from .skeleton import Skeleton


def window_features(root, local_q, skeleton: Skeleton, mean, std, dtype=torch.float32, device=None) -> torch.Tensor:
    """``root (B, T, 3), local_q (B, T, J, 4)`` (numpy or torch, any float) -> features ``(B, T, J, 7)``.

    FK runs in float64; the result is cast to ``dtype``.  NaN frames stay NaN (masks never read them).
    """
    r = torch.as_tensor(np.asarray(root) if not isinstance(root, torch.Tensor) else root).double()
    q = torch.as_tensor(np.asarray(local_q) if not isinstance(local_q, torch.Tensor) else local_q).double()
    return F.encode(r, q, skeleton, mean, std).to(dtype=dtype, device=device)


@torch.no_grad()
def predict_features(net, mask: str, feats: torch.Tensor, known: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Masked input -> network -> ``(prediction, interpolation)``, both ``(B, T, J, 7)``."""
    x, interp = apply_mask(mask, feats, known)
    return net(x, known, interp), interp


def predict_transitions(
    net, mask: str, root, local_q, n: int, skeleton: Skeleton, mean, std, n_past: int = 10,
    device=None, batch_size: int = 256,
) -> tuple[np.ndarray, np.ndarray]:
    """The benchmark's predictor contract for a network.

    ``root (B, n_past+n+1, 3), local_q (B, n_past+n+1, J, 4)`` (transition frames may be NaN) ->
    predicted ``root (B, n, 3)``, ``local_q (B, n, J, 4)`` as float64 numpy.
    """
    device = device or next((p.device for p in net.parameters()), torch.device("cpu"))
    outs_r, outs_q = [], []
    for s in range(0, len(root), batch_size):
        feats = window_features(root[s : s + batch_size], local_q[s : s + batch_size], skeleton, mean, std,
                                device=device)
        b, t, j, _ = feats.shape
        known = transition_known(b, t, j, n_past, n, device=device)
        pred, _ = predict_features(net, mask, feats, known)
        r, q = F.decode(pred.double(), mean, std)
        outs_r.append(r[:, n_past : n_past + n].cpu().numpy())
        outs_q.append(q[:, n_past : n_past + n].cpu().numpy())
    return np.concatenate(outs_r), np.concatenate(outs_q)
