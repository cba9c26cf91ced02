"""The fill of a rig that is not the model's skeleton (:meth:`FillRuntime.fill_rig <inbetweening.runtime.fill.
FillRuntime.fill_rig>`): the keys retargeted onto the model's skeleton, filled there at the model's frame rate, and the
fill carried back onto the rig's frames (:class:`RigFilled`)."""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from inbetweening.geometry.interp import interpolate_keyframes, interpolate_known
from inbetweening.geometry.quaternion import remove_discontinuities, slerp_np

from .model import InbetweenError
from .partial import check_clip, known_values
from .plan import check_refill, key_gaps

__all__ = ["RigFilled", "fill_rig"]


@dataclass
class RigFilled:
    """One filled clip of a rig (:meth:`FillRuntime.fill_rig`): the rig's ``local_q (F, J, 4)`` and ``local_p (F, J, 3)``
    (keys, the frames of gaps not generated and frames outside the filled span exactly the input), ``model``: the fill
    in the model's skeleton (:class:`~inbetweening.runtime.fill.Filled`; its root and rotations, the contacts and the
    blend weights); ``generated`` and ``shares`` as the model's, in the rig's frames."""

    local_q: np.ndarray
    local_p: np.ndarray
    model: object
    generated: list[tuple[int, int]] = field(default_factory=list)
    shares: dict[tuple[int, int], tuple[float, ...]] = field(default_factory=dict)


def _model_frames(times: np.ndarray, ratio: float) -> np.ndarray:
    """Frames of the model's rate for rig frames ``times`` (relative to the first key, in order): rounded, and pushed
    on so that no two fall on one frame."""
    at = np.round(times * ratio).astype(int)
    for i in range(1, len(at)):
        at[i] = max(at[i], at[i - 1] + 1)
    return at


def _resample(root: np.ndarray, q: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A motion at fractional frames ``times``: the root linearly, rotations by slerp between the frames around."""
    lo = np.clip(np.floor(times).astype(int), 0, len(root) - 1)
    hi = np.clip(lo + 1, 0, len(root) - 1)
    w = times - lo
    exact = w < 1e-9
    r = root[lo] + w[:, None] * (root[hi] - root[lo])
    out = slerp_np(q[lo], q[hi], np.repeat(w[:, None], q.shape[1], axis=1))
    out = np.where(exact[:, None, None], q[lo], out)
    return np.where(exact[:, None], root[lo], r), out


def fill_rig(runtime, retarget, local_q, local_p, keys: Sequence[int], *, movers: Sequence[int] | None = None,
             fps: float | None = None, only=None, previous=None, partial=None, **kw) -> RigFilled:
    """Fill a humanoid rig that is not the model's skeleton: the keys are retargeted onto the model's skeleton
    (``retarget``: a :class:`~inbetweening.runtime.retarget.Retarget` from the rig to the model), filled there
    (:meth:`~inbetweening.runtime.fill.FillRuntime.fill`; ``kw`` as there), and the fill retargeted back; the rig's
    bones without a slot (fingers, twist and face bones, props) and every local translation but the hips' are
    interpolated between the keys (rotations by slerp, translations linearly); the keys, and the frames outside
    ``[first key, last key]``, come back exactly.  ``local_q (F, J, 4)``, ``local_p (F, J, 3)``: the rig's local
    rotations and translations (offsets or position channels); values at frames that are not keys are never read, but
    for context frames before the first key and, in a re-fill, the frames of the gaps it may keep.  ``movers``: the
    rig's joints with position channels (the hips' translation goes to the nearest at or above the hips; default: the
    root).  ``fps``: the rig's frame rate; when it is not the model's, the keys are placed on the model's frames by
    their time, the model fills at its own rate, and the rig's frames take the fill at their time (rotations by slerp,
    the root linearly).  ``only``/``previous``: a re-fill, as :meth:`~inbetweening.runtime.fill.FillRuntime.fill`'s,
    in the rig's frames (the kept gaps' frames are carried to the model's at their time; they come back exactly).
    ``partial``: partial keys of the rig, ``{frame: bones}`` (a bool mask, indices or names of the rig's bones): the
    frame's other bones interpolated between their own keys, it is retargeted, and a model joint is keyed there when
    the rig bones its rotation comes from are (:attr:`Retarget.model_source`; the hips: the rig's hips bone); the
    keyed bones come back exactly."""
    info = runtime.info
    lq = np.array(local_q, dtype=np.float64)
    lp = np.array(local_p, dtype=np.float64)
    n = len(lq)
    if lq.ndim != 3 or lq.shape[1:] != (retarget.rig.num_joints, 4) or lp.shape != lq.shape[:2] + (3,):
        raise InbetweenError(f"fill_rig: expected local_q (F, {retarget.rig.num_joints}, 4) and local_p (F, "
                             f"{retarget.rig.num_joints}, 3) of the rig, got {lq.shape} and {lp.shape}")
    keys, part = check_clip("fill_rig", n, keys, partial, list(retarget.rig.names), [lq, lp])
    only, previous = check_refill(keys, only, previous)
    first, last = keys[0], keys[-1]
    ratio = 1.0 if not fps or info.same_rate(fps) else info.fps / float(fps)
    finite = np.isfinite(lq).all((1, 2)) & np.isfinite(lp).all((1, 2))
    context = [t for t in range(first) if finite[t]]
    rows = context + sorted(set(keys) | set(part))
    at = _model_frames(np.array(rows, dtype=np.float64) - first, ratio)  # the rows' model frames, from the first key
    shift = max(0, -int(at.min()))
    at = at + shift
    m = int(at.max()) + 1
    root = np.full((m, 3), np.nan)
    q = np.full((m, info.skeleton.num_joints, 4), np.nan)
    src_q, src_p = lq, lp
    if part:  # the partial keys' other bones: between their own keys (rotations), between the keys (translations)
        known = known_values(part, keys, n, retarget.rig.num_joints)
        src_q = interpolate_known(np.zeros((n, 3)), np.where(known[..., None], lq, np.nan), known)[1]
        src_p = interpolate_keyframes(lp.reshape(n, -1), lq, keys)[0].reshape(lp.shape)
        for t, mask in part.items():
            src_p[t, mask] = lp[t, mask]
    model_at = dict(zip(rows, (int(a) for a in at)))
    model_keys = [model_at[k] for k in keys]
    hips = retarget.rig_slot["Hips"]
    model_part = {model_at[t]: np.array([all(mask[s] for s in retarget.model_source[j][:2]) and (j > 0 or mask[hips])
                                         for j in range(info.skeleton.num_joints)]) for t, mask in part.items()}
    to_model = dict(zip(zip(keys, keys[1:]), zip(model_keys, model_keys[1:])))
    to_rig = {v: k for k, v in to_model.items()}
    kept_gaps = [] if only is None else [  # the gaps the fill may keep: the rig's frames carried to the model's
        ((ka, kb), (ma, mb)) for (ka, kb), (ma, mb) in to_model.items()
        if (ka, kb) not in only and mb - ma >= 2 and finite[ka : kb + 1].all()]
    # one retargeting of every frame it needs (frame by frame, so the same numbers as one call per span)
    spans = [(src_q[rows], src_p[rows])] + [(lq[ka : kb + 1], lp[ka : kb + 1]) for (ka, kb), _ in kept_gaps]
    all_root, all_q = retarget.to_model(np.concatenate([a for a, _ in spans]), np.concatenate([b for _, b in spans]))
    ends = np.cumsum([len(a) for a, _ in spans])[:-1]
    parts = list(zip(np.split(all_root, ends), np.split(all_q, ends)))
    root[at], q[at] = parts[0]
    model_only = None
    if only is not None:
        for ((ka, kb), (ma, mb)), (g_root, g_q) in zip(kept_gaps, parts[1:]):  # at the model's frames, by their time
            g_q = remove_discontinuities(g_q, axis=0)  # continuous from the key, as the runtime makes a gap it fills
            root[ma + 1 : mb], q[ma + 1 : mb] = _resample(g_root, g_q, (np.arange(ma + 1, mb) - ma) * (kb - ka) / (mb - ma))
        model_only = {to_model[g] for g in only}
        previous = {to_model[g]: w for g, w in previous.items()}
    model = runtime.fill(root, q, model_keys, only=model_only, previous=previous, partial=model_part or None, **kw)
    span = np.arange(first, last + 1)
    times = (span - first) * ratio + shift
    times[np.searchsorted(span, keys)] = model_keys  # the keys at their own model frames
    for t in part:
        times[t - first] = model_at[t]
    generated, kept = [], np.zeros(n, dtype=bool)
    for a, b in key_gaps(keys):  # a gap without frames at the model's rate: the keys' alone, changed when they are
        ma, mb = to_model[(a, b)]
        if (ma, mb) in model.generated or (mb - ma < 2 and (only is None or (a, b) in only
                                                            or not finite[a + 1 : b].all())):
            generated.append((a, b))
        else:
            kept[a + 1 : b] = True
    kept[keys] = True
    free_p, free_q = interpolate_keyframes(src_p[span].reshape(len(span), -1), lq[span], [k - first for k in keys])
    if part:  # bones without a slot: through their partial keys too
        free_q = src_q[span]
    out_q, out_p = lq.copy(), lp.copy()
    new = ~kept[span]  # the frames the fill changes: carried back frame by frame (the others are the input's)
    if new.any():
        m_root, m_q = _resample(model.root, model.local_q, times[new])
        out_q[span[new]], out_p[span[new]] = retarget.to_rig(m_root, m_q, free_q[new],
                                                             free_p[new].reshape(int(new.sum()), -1, 3), movers)
    out_q[kept], out_p[kept] = lq[kept], lp[kept]
    for t, mask in part.items():  # the partial keys' bones exactly as keyed
        out_q[t, mask], out_p[t, mask] = lq[t, mask], lp[t, mask]
    return RigFilled(out_q, out_p, model, generated, {to_rig[g]: w for g, w in model.shares.items()})
