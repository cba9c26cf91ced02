"""The functional core of :class:`~inbetweening.predictor.predictor.Predictor`: mask -> (optional known-frame
centring) -> network on features, and the legacy function forms of the predictor's methods.

The centring mode has no default anywhere: every caller passes the checkpoint's own (``known`` for new runs,
``window`` for checkpoints made before the option), so no caller silently gets the leaky mode."""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
import torch

from inbetweening.geometry.skeleton import Skeleton
from inbetweening.predictor import features as F
from inbetweening.predictor.features import known_centre_shift
from inbetweening.predictor.masks import apply_mask

__all__ = ["CENTRES", "centred_forward", "check_centre", "known_centre_shift", "masked_forward", "predict_features",
           "predict_transitions", "window_features"]

CENTRES = ("window", "known", "last")

# (features (B, T, J, F), known (B, T, J), how) -> feature-space shift (B, 1, J, F) of the known frames' root XZ
ShiftFn = Callable[[torch.Tensor, torch.Tensor], torch.Tensor]


def _shift_with(std) -> ShiftFn:
    """The z-scored position features' centring shift with these statistics."""
    return lambda feats, known, how: known_centre_shift(feats, known, std, how)


def check_centre(centre: str) -> str:
    """``centre`` itself, or ValueError naming the allowed modes."""
    if centre not in CENTRES:
        raise ValueError(f"centre must be one of {list(CENTRES)}, got {centre!r}")
    return centre


def window_features(root, local_q, skeleton: Skeleton, mean, std, dtype=torch.float32, device=None) -> torch.Tensor:
    """``root (B, T, 3), local_q (B, T, J, 4)`` (numpy or torch, any float) -> features ``(B, T, J, 7)``.

    FK runs in float64; the result is cast to ``dtype``.  NaN frames stay NaN (masks never read them).
    """
    return F.GlobalPosLocalQuat(skeleton, mean, std).encode_windows(root, local_q, dtype, device)


def centred_forward(net, mask: str, feats: torch.Tensor, known: torch.Tensor, centre: str, shift_fn: ShiftFn):
    """``(pred, interp, target, shift)``: mask -> (``centre="known"``/``"last"``: subtract the known frames' root XZ
    shift, :func:`~inbetweening.predictor.features.anchor_xz`) -> ``net(x, known, interp)``.  ``target`` is ``feats`` in
    the prediction's frame; ``shift`` is ``None`` for
    ``centre="window"``.  Shapes ``(B, T, J, F)``, ``known (B, T, J)``."""
    shift = None
    if check_centre(centre) != "window":
        shift = shift_fn(feats, known, centre)
        feats = feats - shift
    x, interp = apply_mask(mask, feats, known)
    return net(x, known, interp), interp, feats, shift


def restore_frame(feats, known, pred, interp, shift) -> tuple[torch.Tensor, torch.Tensor]:
    """Prediction and interpolation back in the input's frame, known values copied bit-exactly from ``feats``."""
    if shift is not None:
        pred = torch.where(known[..., None], feats, pred + shift)
        interp = torch.where(known[..., None], feats, interp + shift)
    return pred, interp


def masked_forward(net, mask: str, feats: torch.Tensor, known: torch.Tensor, centre: str, std):
    """:func:`centred_forward` with the z-scored position features: ``(pred, interp, target)``, with gradients."""
    return centred_forward(net, mask, feats, known, centre, _shift_with(std))[:3]


@torch.no_grad()
def predict_features(net, mask: str, feats: torch.Tensor, known: torch.Tensor, centre: str,
                     std) -> tuple[torch.Tensor, torch.Tensor]:
    """Masked input -> network -> ``(prediction, interpolation)``, both ``(B, T, J, 7)`` in the input's frame;
    known values are returned bit-exactly; unknown input values are never read (they may be NaN)."""
    pred, interp, _, shift = centred_forward(net, mask, feats, known, centre, _shift_with(std))
    return restore_frame(feats, known, pred, interp, shift)


def predict_transitions(
    net, mask: str, root, local_q, n: int, skeleton: Skeleton, mean, std, centre: str, n_past: int = 10,
    device=None, batch_size: int = 256,
) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`Predictor.predict_transitions <inbetweening.predictor.predictor.Predictor.predict_transitions>` of a
    bare network (the benchmark's predictor contract)."""
    from inbetweening.predictor.predictor import Predictor

    pr = Predictor(net, skeleton, mean, std, mask=mask, centre=centre, n_past=n_past)
    return pr.predict_transitions(root, local_q, n, device=device, batch_size=batch_size)
