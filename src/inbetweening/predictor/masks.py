"""Masks: which values are known, and what the model sees in place of the unknown ones.

Small pure functions on torch tensors.  ``known`` is ``(B, T, J)`` bool (True = given); features are
``(B, T, J, F)`` whose position and rotation channels the representation names (``layout``: an object with ``pos``
and ``quat`` slices, :class:`inbetweening.representation.base.Representation`).

* :func:`transition_known` - the in-betweening mask: context frames, then a gap, then a target keyframe.
* :func:`joints_known`     - the mocap-recovery mask: random joints missing over random gaps.
* :func:`gap_lengths`      - for each unknown value, the length of the gap (run of unknown frames) holding it.
* ``MASKS[name](x, known, layout)`` - fill the unknown values: ``zero`` (zeros) or ``lerp`` (positions
  linear, quaternions slerp between the nearest known frames of the same joint, other channels held).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import torch

from inbetweening.geometry.interp import lerp, slerp

MASK_NAMES = ("zero", "lerp", "joints")


def transition_known(batch: int, frames: int, joints: int, n_past: int, n_trans, device=None) -> torch.Tensor:
    """Whole-frame mask ``(B, T, J)``: frames ``< n_past`` and frame ``n_past + n_trans`` are known.

    ``n_past`` and ``n_trans`` are ints or ``(B,)`` tensors (per-sample context and transition lengths); frames after
    the target are marked known too (callers fill them with copies of the target and leave them out of the loss).
    """
    t = torch.arange(frames, device=device)[None, :]
    n = torch.as_tensor(n_trans, device=device).reshape(-1, 1).expand(batch, 1)
    p = torch.as_tensor(n_past, device=device).reshape(-1, 1).expand(batch, 1)
    known = (t < p) | (t >= p + n)
    return known[:, :, None].expand(batch, frames, joints).clone()


def gap_lengths(known: torch.Tensor) -> torch.Tensor:
    """``known (B, T, J)`` bool -> ``(B, T, J)`` int64: for an unknown value, the number of consecutive unknown
    frames of its joint that hold it (frames from the previous known frame to the next one, both excluded; a gap
    open at the window's start or end counts to that edge); 0 for a known value.

    Built from comparisons and reductions only (no loop, no ``cummax``), so it traces into an ONNX graph."""
    t = known.shape[1]
    idx = torch.arange(t, device=known.device)
    k = known.transpose(1, 2)[:, :, None, :]  # (B, J, 1, T_s)
    s_, t_ = idx[None, :], idx[:, None]  # (T_t, T_s) comparisons
    prev = torch.where(k & (s_ <= t_), idx, -1).amax(dim=-1)  # (B, J, T_t): last known frame at or before t
    nxt = torch.where(k & (s_ >= t_), idx, t).amin(dim=-1)  # first known frame at or after t
    return torch.where(known, 0, (nxt - prev - 1).transpose(1, 2))


@dataclass(frozen=True)
class JointGaps:
    """The mocap-recovery task's gap settings (``mask=joints``; ``conf/mask/joints.yaml``), defaults in one place:
    per sample a ``frac_min..frac_max`` share of the joints is missing over one gap of ``gap_min..gap_max``
    frames.  Used by the training batches and by the recovery scores of validation/test alike."""

    gap_min: int = 10
    gap_max: int = 200
    frac_min: float = 0.1
    frac_max: float = 0.3

    @classmethod
    def from_config(cls, cfg: dict | None) -> JointGaps:
        """From the ``mask`` group's values (its ``name`` ignored; missing keys take the defaults)."""
        return cls(**{k: v for k, v in (cfg or {}).items() if k != "name"})

    def known(self, batch: int, frames: int, joints: int, generator: torch.Generator | None = None,
              device=None) -> torch.Tensor:
        """:func:`joints_known` with these settings."""
        return joints_known(batch, frames, joints, int(self.gap_min), int(self.gap_max), float(self.frac_min),
                            float(self.frac_max), generator=generator, device=device)


def joints_known(
    batch: int, frames: int, joints: int, gap_min: int, gap_max: int, frac_min: float, frac_max: float,
    generator: torch.Generator | None = None, device=None,
) -> torch.Tensor:
    """Mocap-recovery mask ``(B, T, J)``: per sample, a random ``frac`` of the joints is missing over one
    random gap of ``gap_min..gap_max`` frames (clipped to the window, first and last frame kept known)."""
    known = torch.ones(batch, frames, joints, dtype=torch.bool, device=device)
    gmax = min(gap_max, frames - 2)
    gmin = min(gap_min, gmax)
    for b in range(batch):
        g = int(torch.randint(gmin, gmax + 1, (1,), generator=generator))
        s = int(torch.randint(1, frames - g, (1,), generator=generator))
        frac = frac_min + (frac_max - frac_min) * float(torch.rand(1, generator=generator))
        k = max(1, round(frac * joints))
        sel = torch.randperm(joints, generator=generator)[:k]
        known[b, s : s + g, sel.to(known.device)] = False
    return known


def zero_fill(x: torch.Tensor, known: torch.Tensor, layout=None) -> torch.Tensor:
    """Unknown values set to 0.  ``(B, T, J, F), (B, T, J) -> (B, T, J, F)``."""
    return torch.where(known[..., None], x, torch.zeros_like(x))


def _neighbour_known(known: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Index of the previous and next known frame of each joint (or -1 / T when none).  ``(B, T, J)`` each.

    While exporting to ONNX (which has no ``cummax``) the same integers come from a masked max / min over a
    ``(T, T)`` triangle (:func:`_neighbour_known_exportable`)."""
    if torch.onnx.is_in_onnx_export():
        return _neighbour_known_exportable(known)
    b, t, j = known.shape
    idx = torch.arange(t, device=known.device)[None, :, None].expand(b, t, j)
    prev = torch.where(known, idx, torch.full_like(idx, -1)).cummax(dim=1).values
    rev = torch.where(known, t - 1 - idx, torch.full_like(idx, -1)).flip(1).cummax(dim=1).values.flip(1)
    nxt = torch.where(rev >= 0, t - 1 - rev, torch.full_like(rev, t))
    return prev, nxt


def _neighbour_known_exportable(known: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """:func:`_neighbour_known` as a masked max / min over a ``(T, T)`` triangle (ONNX operators only; memory
    ``B * J * T * T``, so only for export): the same integers."""
    t = known.shape[1]
    idx = torch.arange(t, device=known.device)
    kn = known.permute(0, 2, 1)[:, :, None, :]  # (B, J, 1, S)
    prev = torch.where(kn & (idx[None, :] <= idx[:, None]), idx, torch.full_like(idx, -1)).amax(-1)
    nxt = torch.where(kn & (idx[None, :] >= idx[:, None]), idx, torch.full_like(idx, t)).amin(-1)
    return prev.permute(0, 2, 1), nxt.permute(0, 2, 1)


def lerp_fill(x: torch.Tensor, known: torch.Tensor, layout) -> torch.Tensor:
    """Unknown values interpolated from the nearest known frames of the same joint.

    Positions (``layout.pos``) linearly, quaternions (``layout.quat``) by slerp (shortest arc, linear fallback when
    nearly equal), other channels held from the previous known frame; before the first / after the last known frame
    the nearest known value is held.
    ``(B, T, J, F), (B, T, J) -> (B, T, J, F)``.
    """
    prev, nxt = _neighbour_known(known)
    t = x.shape[1]
    p = prev.clamp(min=0)
    n = nxt.clamp(max=t - 1)
    p = torch.where(prev < 0, n, p)
    n = torch.where(nxt >= t, p, n)
    idx = torch.arange(t, device=x.device)[None, :, None]
    span = (n - p).clamp(min=1).to(x.dtype)
    w = ((idx - p).to(x.dtype) / span).clamp(0, 1)
    safe = torch.where(known[..., None], x, torch.zeros_like(x))  # never read unknown values, even NaN ones
    xp = torch.gather(safe, 1, p[..., None].expand_as(x))
    xn = torch.gather(safe, 1, n[..., None].expand_as(x))
    filled = xp.clone()
    filled[..., layout.pos] = lerp(xp[..., layout.pos], xn[..., layout.pos], w[..., None])
    filled[..., layout.quat] = slerp(xp[..., layout.quat], xn[..., layout.quat], w)
    return torch.where(known[..., None], x, filled)


# name -> fill function; "joints" is the mocap-recovery task, which fills its gaps by interpolation
MASKS: dict[str, Callable[..., torch.Tensor]] = {
    "zero": zero_fill,
    "lerp": lerp_fill,
    "joints": lerp_fill,
}


def apply_mask(name: str, x: torch.Tensor, known: torch.Tensor, layout) -> tuple[torch.Tensor, torch.Tensor]:
    """Model input and interpolation for a mask: ``(masked x, lerp interpolation)``, both ``(B, T, J, F)``.

    The interpolation is always returned (models with ``residual_to_interpolation`` and the
    interpolation baseline use it), whatever the mask shows the model.
    """
    if name not in MASKS:
        raise ValueError(f"unknown mask {name!r}; choose one of {sorted(MASKS)}")
    interp = lerp_fill(x, known, layout)
    shown = interp if MASKS[name] is lerp_fill else MASKS[name](x, known, layout)
    return shown, interp
