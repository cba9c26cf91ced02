"""One path from (root, local quaternions) windows to predicted transitions, shared by validation,
``eval.py``, the benchmark and the animator tools, so every number comes from the same code.

The centring mode has no default anywhere: every caller passes the checkpoint's own (``known`` for new runs,
``window`` for checkpoints made before the option), so no caller silently gets the leaky mode."""
from __future__ import annotations

import numpy as np
import torch

from inbetweening.geometry.skeleton import Skeleton
from inbetweening.predictor import features as F
from inbetweening.predictor.masks import apply_mask, transition_known


def window_features(root, local_q, skeleton: Skeleton, mean, std, dtype=torch.float32, device=None) -> torch.Tensor:
    """``root (B, T, 3), local_q (B, T, J, 4)`` (numpy or torch, any float) -> features ``(B, T, J, 7)``.

    FK runs in float64; the result is cast to ``dtype``.  NaN frames stay NaN (masks never read them).
    """
    r = torch.as_tensor(root).double()
    q = torch.as_tensor(local_q).double()
    return F.encode(r, q, skeleton, mean, std).to(dtype=dtype, device=device)


CENTRES = ("window", "known")


def known_centre_shift(feats: torch.Tensor, known: torch.Tensor, std) -> torch.Tensor:
    """Feature-space shift that moves the mean root XZ of the KNOWN frames to the origin.  ``-> (B, 1, 1, 7)``.

    Benchmark windows are centred on the mean root XZ over all their frames, including the ones to be
    predicted, so absolute positions leak where the transition goes.  Subtracting this shift (and adding
    it back to the prediction) makes the network see only what is known: ``centre="known"``.
    """
    s = torch.as_tensor(std, dtype=feats.dtype, device=feats.device).reshape(-1, 3)
    root_known = known[:, :, 0]  # (B, T)
    xz_known = torch.where(root_known[..., None], feats[:, :, 0, [0, 2]], 0.0)  # unknown frames never read (NaN ok)
    xz = xz_known.sum(1) / root_known.to(feats.dtype).sum(1, keepdim=True).clamp(min=1)
    shift = torch.zeros(feats.shape[0], 1, feats.shape[2], feats.shape[3], dtype=feats.dtype, device=feats.device)
    # positions are z-scored per joint coordinate: a world shift d is d / std_j in each joint's features
    shift[:, 0, :, 0] = xz[:, None, 0] * s[0, 0] / s[:, 0]
    shift[:, 0, :, 2] = xz[:, None, 1] * s[0, 2] / s[:, 2]
    return shift


def _centred_forward(net, mask: str, feats: torch.Tensor, known: torch.Tensor, centre: str, std):
    """``(pred, interp, target, shift)``; ``shift`` is ``None`` for ``centre="window"``."""
    if centre not in CENTRES:
        raise ValueError(f"centre must be one of {list(CENTRES)}, got {centre!r}")
    shift = None
    if centre == "known":
        shift = known_centre_shift(feats, known, std)
        feats = feats - shift
    x, interp = apply_mask(mask, feats, known)
    return net(x, known, interp), interp, feats, shift


def masked_forward(net, mask: str, feats: torch.Tensor, known: torch.Tensor, centre: str, std):
    """Mask -> (optional known-frame centring) -> network, with gradients.  Returns ``(pred, interp, target)``
    where ``target`` is ``feats`` in the frame the prediction lives in (for the loss)."""
    return _centred_forward(net, mask, feats, known, centre, std)[:3]


@torch.no_grad()
def predict_features(net, mask: str, feats: torch.Tensor, known: torch.Tensor, centre: str,
                     std) -> tuple[torch.Tensor, torch.Tensor]:
    """Masked input -> network -> ``(prediction, interpolation)``, both ``(B, T, J, 7)`` in the input's frame;
    known values are returned bit-exactly; unknown input values are never read (they may be NaN)."""
    pred, interp, _, shift = _centred_forward(net, mask, feats, known, centre, std)
    if shift is not None:
        pred = torch.where(known[..., None], feats, pred + shift)
        interp = torch.where(known[..., None], feats, interp + shift)
    return pred, interp


def predict_transitions(
    net, mask: str, root, local_q, n: int, skeleton: Skeleton, mean, std, centre: str, n_past: int = 10,
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
        pred, _ = predict_features(net, mask, feats, known, centre, std)
        r, q = F.decode(pred.double(), mean, std)
        outs_r.append(r[:, n_past : n_past + n].cpu().numpy())
        outs_q.append(q[:, n_past : n_past + n].cpu().numpy())
    return np.concatenate(outs_r), np.concatenate(outs_q)
