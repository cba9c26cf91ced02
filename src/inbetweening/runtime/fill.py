"""The fill: keys -> every frame between them (:class:`FillRuntime`).

How a gap is generated (the conditions the model was trained under):

* Gaps are filled left to right (:mod:`.plan`).  For keys ``a < b`` the network sees ``n_past`` context frames
  ending at ``a`` (the already completed output: earlier keys and generated frames; frames before the first key are
  the caller's existing animation where it gives finite values, and where fewer than ``n_past`` frames exist the
  first frame is repeated), the ``b - a - 1`` unknown frames and the known target ``b``.
* The window is moved into its canonical frame, decided by its known frames only
  (:func:`~inbetweening.geometry.canonical.canonical_frame`: the root's forward axis at the last context frame turned
  to +X about +Y; the origin at the known frames' mean root XZ, or the last context frame's), the backend predicts,
  and the prediction is taken back.
* The do-no-harm blend (:mod:`.trust`): the network's correction to the interpolation is scaled, per gap, by the
  model's weight for the gap's length (:meth:`ModelInfo.blend_weight`) times the trust of the self-check on the
  user's own keys (each interior key hidden and predicted by the network, before the fill); the weights and the
  checks are reported.
* Foot locking, for every model whose data names its feet: where a foot is planted (the model's contact channels,
  else the data's contact rule on the fill itself) it is held still and the leg bent to reach it, the root moved
  where the foot is out of the leg's reach (:mod:`.foot_lock`); keys are never changed.
* Keys, and every frame outside ``[first key, last key]``, come back exactly as given (bit for bit).

Arrays are ``root (F, 3)``, ``local_q (F, J, 4)`` (wxyz) in the model's skeleton: in the project's frame (Y up, cm),
or with ``file_frame=True`` in the training files' frame (:class:`~inbetweening.data.convention.FileConvention`,
recorded with the model), which is then converted on the way in and back.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from inbetweening.geometry import canonical
from inbetweening.geometry.interp import interpolate_keyframes, interpolate_pose
from inbetweening.geometry.quaternion import qnormalize, remove_discontinuities, slerp_np

from .foot_lock import SHORT_GAP, contact_rule, detected_contacts, key_contacts, lock_feet
from .model import Backend, InbetweenError, ModelInfo
from .plan import GapPlan, check_keys, plan_gaps
from .trust import Check, checks_of, gap_weights, scored

__all__ = ["Filled", "FillRuntime", "RigFilled"]


@dataclass
class Filled:
    """One filled clip.  ``root``/``local_q``: float64, keys and frames outside the filled span exactly the input;
    ``contact (F, J)``: foot contact in [0, 1] on generated frames (the model's prediction; for a model without
    contact channels, the contact rule on the fill), the keys' own on keys, ``None`` for a model whose data names no
    feet; ``pseudo_keyframes``: split points of long gaps;
    ``segments``: ``(a, b, weight)`` per generated window (``weight``: the network's share, the do-no-harm blend,
    :mod:`.trust`); ``checks``: the self-checks on the keys (:class:`~inbetweening.runtime.trust.Check`);
    ``locked``: whether the feet were locked."""

    root: np.ndarray
    local_q: np.ndarray
    contact: np.ndarray | None = None
    pseudo_keyframes: list[int] = field(default_factory=list)
    segments: list[tuple[int, int, float]] = field(default_factory=list)
    locked: bool = False
    checks: list[Check] = field(default_factory=list)


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


def _check_batch_size(batch_size) -> int:
    if isinstance(batch_size, bool) or not isinstance(batch_size, (int, np.integer)) or batch_size < 1:
        raise InbetweenError(f"batch_size must be a positive integer, got {batch_size!r}")
    return int(batch_size)


@dataclass
class RigFilled:
    """One filled clip of a rig (:meth:`FillRuntime.fill_rig`): the rig's ``local_q (F, J, 4)`` and ``local_p (F, J, 3)``
    (keys and frames outside the filled span exactly the input), and ``model``: the fill in the model's skeleton
    (:class:`Filled`; its root and rotations, the contacts and the blend weights)."""

    local_q: np.ndarray
    local_p: np.ndarray
    model: Filled


class _Clip:
    """A clip being filled: working arrays in the project's frame, its plan, the predicted contact."""

    def __init__(self, root, q, keys, plan: GapPlan, exact_root, exact_q):
        self.root, self.q, self.keys, self.plan = root, q, keys, plan
        self.exact_root, self.exact_q = exact_root, exact_q
        self.contact = np.full(q.shape[:2], np.nan)
        self.weights: dict[tuple[int, int], float] = {}
        self.checks: list[Check] = []


class FillRuntime:
    """Fill keys with a :class:`~inbetweening.runtime.model.Backend` (see the module docstring).

    Args:
        backend: the network (:class:`~inbetweening.runtime.torch_backend.TorchBackend` or
            :class:`~inbetweening.runtime.onnx_backend.OnnxBackend`).
        max_gap: longest gap generated in one window; default the model's ``trained_gap``.  May be raised up to
            ``hard_max_gap`` (beyond what it was trained on: quality not guaranteed).
        segment: split longer gaps (default) or refuse them (:class:`InbetweenError`).
        foot_lock: lock planted feet (every model whose data names its feet; default on).
        self_check: scale the network's share per gap by the self-check on the keys (:mod:`.trust`; default on);
            off: the calibrated weight per gap length alone.
        batch_size: gaps of the same length generated in one backend call (``fill_many``; about 4 runs fastest per
            gap on a 2-core CPU, BENCHMARKS.md "Inference latency").
    """

    def __init__(self, backend: Backend, *, max_gap: int | None = None, segment: bool = True, foot_lock: bool = True,
                 batch_size: int = 4, self_check: bool = True):
        self.backend = backend
        self.info: ModelInfo = backend.info
        self.max_gap = self.check_max_gap(max_gap)
        self.segment = bool(segment)
        self.foot_lock = bool(foot_lock)
        self.batch_size = _check_batch_size(batch_size)
        self.self_check = bool(self_check)

    def check_max_gap(self, max_gap: int | None) -> int:
        """``max_gap`` checked against the network (default: the model's ``trained_gap``)."""
        if max_gap is None:
            return self.info.trained_gap
        if isinstance(max_gap, bool) or not isinstance(max_gap, (int, np.integer)) or max_gap < 1:
            raise InbetweenError(f"max_gap must be a positive integer, got {max_gap!r}")
        if max_gap > self.info.hard_max_gap:
            raise InbetweenError(f"max_gap={max_gap} exceeds what the network supports "
                                 f"({self.info.hard_max_gap} = max_frames - {self.info.n_past} context - 1 target)")
        return int(max_gap)

    # ------------------------------------------------------------------ entry points
    def fill(self, root, local_q, keys: Sequence[int], *, file_frame: bool = False, max_gap: int | None = None,
             segment: bool | None = None, foot_lock: bool | None = None,
             progress: Callable[[int, int], None] | None = None) -> Filled:
        """Generate every frame strictly between consecutive ``keys`` (sorted indices into the arrays); values of
        those frames are never read (NaN is fine).  ``progress(done, total)`` is called after each window."""
        return self.fill_many([(root, local_q, keys)], file_frame=file_frame, max_gap=max_gap, segment=segment,
                              foot_lock=foot_lock, progress=progress)[0]

    def fill_many(self, clips, *, file_frame: bool = False, max_gap: int | None = None, segment: bool | None = None,
                  foot_lock: bool | None = None, batch_size: int | None = None,
                  progress: Callable[[int, int], None] | None = None) -> list[Filled]:
        """:meth:`fill` of many ``(root, local_q, keys)`` at once: the k-th gap of every clip is generated together,
        ``batch_size`` gaps of one length per backend call (gaps within a clip still left to right).  The same
        numbers as clip by clip, up to float rounding of the batched network.  Every clip is checked first."""
        limit = self.max_gap if max_gap is None else self.check_max_gap(max_gap)
        size = self.batch_size if batch_size is None else _check_batch_size(batch_size)
        seg = self.segment if segment is None else bool(segment)
        work = [self._prepare(r, q, k, limit, seg, file_frame) for r, q, k in clips]
        self._weigh(work, size)
        total, done = sum(len(c.plan.segments) for c in work), 0
        for step in range(max((len(c.plan.segments) for c in work), default=0)):
            groups: dict[int, list] = {}
            for c in work:
                if step < len(c.plan.segments):
                    a, b = c.plan.segments[step]
                    groups.setdefault(b - a, []).append((c, a, b))
            for items in groups.values():
                for i in range(0, len(items), size):
                    self._generate(items[i : i + size])
                    done += len(items[i : i + size])
                    if progress is not None:
                        progress(done, total)
        lock = self.foot_lock if foot_lock is None else bool(foot_lock)
        return [self._finish(c, lock, file_frame) for c in work]

    def fill_rig(self, retarget, local_q, local_p, keys: Sequence[int], *, movers: Sequence[int] | None = None,
                 fps: float | None = None, **kw) -> RigFilled:
        """Fill a humanoid rig that is not the model's skeleton: the keys are retargeted onto the model's skeleton
        (``retarget``: a :class:`~inbetweening.runtime.retarget.Retarget` from the rig to the model), filled there
        (:meth:`fill`; ``kw`` as there), and the fill retargeted back; the rig's bones without a slot (fingers, twist
        and face bones, props) and every local translation but the hips' are interpolated between the keys (rotations by
        slerp, translations linearly); the keys, and the frames outside ``[first key, last key]``, come back exactly.
        ``local_q (F, J, 4)``, ``local_p (F, J, 3)``: the rig's local rotations and translations (offsets or position
        channels); values at frames that are not keys are never read, but for context frames before the first key.
        ``movers``: the rig's joints with position channels (the hips' translation goes to the nearest at or above the
        hips; default: the root).  ``fps``: the rig's frame rate; when it is not the model's, the keys are placed on the
        model's frames by their time, the model fills at its own rate, and the rig's frames take the fill at their time
        (rotations by slerp, the root linearly)."""
        lq = np.array(local_q, dtype=np.float64)
        lp = np.array(local_p, dtype=np.float64)
        n = len(lq)
        if lq.ndim != 3 or lq.shape[1:] != (retarget.rig.num_joints, 4) or lp.shape != lq.shape[:2] + (3,):
            raise InbetweenError(f"fill_rig: expected local_q (F, {retarget.rig.num_joints}, 4) and local_p (F, "
                                 f"{retarget.rig.num_joints}, 3) of the rig, got {lq.shape} and {lp.shape}")
        keys = check_keys(keys, n, "keys")
        if not (np.isfinite(lq[keys]).all() and np.isfinite(lp[keys]).all()):
            raise InbetweenError("fill_rig: the keys contain NaN or infinite values")
        first, last = keys[0], keys[-1]
        ratio = 1.0 if not fps or abs(float(fps) - self.info.fps) <= 0.5 else self.info.fps / float(fps)
        context = [t for t in range(first) if np.isfinite(lq[t]).all() and np.isfinite(lp[t]).all()]
        rows = context + list(keys)
        at = _model_frames(np.array(rows, dtype=np.float64) - first, ratio)  # the rows' model frames, from the first key
        shift = max(0, -int(at.min()))
        at = at + shift
        m = int(at.max()) + 1
        root = np.full((m, 3), np.nan)
        q = np.full((m, self.info.skeleton.num_joints, 4), np.nan)
        root[at], q[at] = retarget.to_model(lq[rows], lp[rows])
        model_keys = [int(a) for a in at[len(context):]]
        model = self.fill(root, q, model_keys, **kw)
        span = np.arange(first, last + 1)
        times = (span - first) * ratio + shift
        times[np.searchsorted(span, keys)] = model_keys  # the keys at their own model frames
        m_root, m_q = _resample(model.root, model.local_q, times)
        free_p, free_q = interpolate_keyframes(lp[span].reshape(len(span), -1), lq[span], [k - first for k in keys])
        out_q, out_p = lq.copy(), lp.copy()
        out_q[span], out_p[span] = retarget.to_rig(m_root, m_q, free_q, free_p.reshape(len(span), -1, 3), movers)
        out_q[keys], out_p[keys] = lq[keys], lp[keys]
        return RigFilled(out_q, out_p, model)

    # ------------------------------------------------------------------ stages
    def _prepare(self, root, local_q, keys, limit: int, seg: bool, file_frame: bool) -> _Clip:
        """Check one clip, convert it to the project's frame and lay out its plan; pseudo-keyframes interpolated."""
        info = self.info
        exact_root = np.array(root, dtype=np.float64)
        exact_q = np.array(local_q, dtype=np.float64)
        j = info.skeleton.num_joints
        if exact_root.ndim != 2 or exact_root.shape[1] != 3 or exact_q.shape != (exact_root.shape[0], j, 4):
            raise InbetweenError(f"fill: expected root (F, 3) and local_q (F, {j}, 4) of the model's skeleton, "
                                 f"got {exact_root.shape} and {exact_q.shape}")
        keys = check_keys(keys, len(exact_root), "keys")
        if not (np.isfinite(exact_root[keys]).all() and np.isfinite(exact_q[keys]).all()):
            raise InbetweenError("fill: the keys contain NaN or infinite values")
        r, q = exact_root.copy(), exact_q.copy()
        if file_frame and not info.convention.is_project:
            r, q = info.convention.to_project(r, q)
        first = keys[0]
        bad = ~(np.isfinite(r[:first]).all(-1) & np.isfinite(q[:first]).all((-1, -2)))
        r[:first][bad], q[:first][bad] = r[first], q[first]  # no usable context there: the first key's pose
        q[: keys[-1] + 1] = qnormalize(q[: keys[-1] + 1])
        plan = plan_gaps(keys, limit, seg, info.trained_gap)
        for a, b, points in plan.pseudo:
            w = (np.array(points) - a) / (b - a)
            r[points], q[points] = interpolate_pose(r[a], q[a], r[b], q[b], w)
        return _Clip(r, q, keys, plan, exact_root, exact_q)

    def windows(self, roots: Sequence[np.ndarray], qs: Sequence[np.ndarray], spans: Sequence[tuple[int, int]]):
        """The context windows of gaps ``(a, b)`` of one length, one per clip ``roots[i] (F, 3)``, ``qs[i] (F, J, 4)``:
        ``root (B, T, 3), local_q (B, T, J, 4)`` (frames ``a - n_past + 1 .. a``, the gap holding frame ``a``'s values,
        never read, then ``b``), sign-continuous along time."""
        p = self.info.n_past
        wr, wq = [], []
        for root, q, (a, b) in zip(roots, qs, spans):
            idx = np.concatenate([np.clip(np.arange(a - p + 1, a + 1), 0, None), np.full(b - a - 1, a), [b]])
            wr.append(root[idx])
            wq.append(remove_discontinuities(q[idx], axis=0))
        return np.stack(wr), np.stack(wq)

    def known_mask(self, batch: int, gap: int) -> np.ndarray:
        """``known (B, T, J)``: ``n_past`` context frames, ``gap`` unknown frames, the target."""
        p, j = self.info.n_past, self.info.skeleton.num_joints
        known = np.zeros((batch, p + gap + 1, j), dtype=bool)
        known[:, :p] = True
        known[:, -1] = True
        return known

    def predict_windows(self, wr: np.ndarray, wq: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Windows in the clip's frame -> the network's prediction of the gap (no blend): ``root (B, n, 3), local_q
        (B, n, J, 4)`` (unit), contact ``(B, n, J)`` or ``None``: canonical frame, backend, back."""
        info = self.info
        b, t = wr.shape[:2]
        p = info.n_past
        n = t - p - 1
        known = self.known_mask(b, n)
        centre, rot = canonical.canonical_frame(wr, wq, info.forward_axis, p - 1, known[..., 0],
                                                centre_at_frame=info.centre == "last")
        croot, cq = canonical.canonicalise(wr, wq, centre, rot)
        pr, pq, pc = self.backend.predict(croot, cq, known, None)
        pr, pq = canonical.uncanonicalise(np.asarray(pr, np.float64), np.asarray(pq, np.float64), centre, rot)
        pr, pq = pr[:, p : p + n], pq[:, p : p + n]
        pq = pq / np.linalg.norm(pq, axis=-1, keepdims=True)  # exactly unit
        pc = None if pc is None else np.asarray(pc, np.float64)[:, p : p + n]
        return pr, pq, pc

    def _weigh(self, work: list[_Clip], size: int) -> None:
        """The do-no-harm weight of every window of every clip (:func:`.trust.gap_weights`): the self-checks first
        (``size`` windows of one length per backend call; context: the keys' interpolation)."""
        todo = []
        for c in work:
            if self.self_check:
                c.checks = checks_of(c.keys, self.info.trained_gap)
                known = [t for t in range(c.keys[0])] + list(c.keys)
                base = interpolate_keyframes(c.root, c.q, known)
                todo += [(c, base, i) for i in range(len(c.checks))]
        groups: dict[int, list] = {}
        for item in todo:
            ch = item[0].checks[item[2]]
            groups.setdefault(ch.b - ch.a, []).append(item)
        for items in groups.values():
            for s in range(0, len(items), size):
                part = items[s : s + size]
                spans = [(c.checks[i].a, c.checks[i].b) for c, _, i in part]
                wr, wq = self.windows([b[0] for _, b, _ in part], [b[1] for _, b, _ in part], spans)
                pr, pq, _ = self.predict_windows(wr, wq)
                for j, (c, base, i) in enumerate(part):
                    ch = c.checks[i]
                    t = ch.key - ch.a - 1
                    c.checks[i] = scored(ch, self.info.skeleton, base[0], base[1], pr[j, t], pq[j, t])
        for c in work:
            weights = gap_weights(c.plan.segments, c.keys, c.checks, self.info.blend_weight)
            c.weights = {k: w for k, (w, _) in weights.items()}

    def _generate(self, items) -> None:
        """Fill frames ``a+1 .. b-1`` of each ``(clip, a, b)`` in place (gaps of one length, one backend call): the
        network's prediction blended with the interpolation by the window's weight."""
        wr, wq = self.windows([c.root for c, _, _ in items], [c.q for c, _, _ in items], [(a, b) for _, a, b in items])
        pr, pq, pc = self.predict_windows(wr, wq)
        for i, (c, a, b) in enumerate(items):
            w = c.weights.get((a, b), 1.0)
            r, q = pr[i], pq[i]
            if w < 1.0:
                ir, iq = interpolate_pose(c.root[a], c.q[a], c.root[b], c.q[b], (np.arange(a + 1, b) - a) / (b - a))
                r, q = ir + w * (r - ir), slerp_np(iq, q, np.full(q.shape[:-1], w))
            c.root[a + 1 : b] = r
            c.q[a + 1 : b] = remove_discontinuities(np.concatenate([c.q[a : a + 1], q]), axis=0)[1:]
            if pc is not None:
                c.contact[a + 1 : b] = pc[i]

    def _finish(self, c: _Clip, lock: bool, file_frame: bool) -> Filled:
        """Keys exact, the keys' own contacts, feet locked, back to the file's frame, keys and outside frames exact."""
        info = self.info
        keys = c.keys
        root, q = c.root, c.q
        if file_frame and not info.convention.is_project:
            exact_r, exact_q = info.convention.to_project(c.exact_root[keys], c.exact_q[keys])
        else:
            exact_r, exact_q = c.exact_root[keys], c.exact_q[keys]
        root[keys], q[keys] = exact_r, exact_q
        contact, locked = None, False
        rule = contact_rule(info.contact, info.skeleton, root, q, keys)
        if rule.feet:  # on the filled span alone: frames before the first key are context, never feet to lock
            s, e = keys[0], keys[-1] + 1
            span = [k - s for k in keys]
            detected = detected_contacts(info.skeleton, rule, info.fps, root[s:e], q[s:e], span)
            contact = np.full(c.contact.shape, np.nan)
            if info.has_contacts and not np.isnan(c.contact).all():
                labels = key_contacts(info.skeleton, rule, info.fps, root, q, keys)
                contact = np.where(np.isnan(c.contact), labels, c.contact)
                for a, b in zip(keys, keys[1:]):  # short gaps: what the keys say
                    if b - a - 1 < SHORT_GAP:
                        contact[a + 1 : b] = detected[a + 1 - s : b - s]
            else:
                contact[s:e] = detected
            if lock:
                feet = rule.indices(info.skeleton.names, "the model's feet")
                root, q = root.copy(), q.copy()
                root[s:e], q[s:e] = lock_feet(info.skeleton, root[s:e], q[s:e], span, contact[s:e], feet)
                locked = True
        if file_frame and not info.convention.is_project:
            root, q = info.convention.to_file(root, q)
        outside = np.ones(len(root), dtype=bool)
        outside[keys[0] + 1 : keys[-1]] = False
        outside[keys] = True
        root[outside], q[outside] = c.exact_root[outside], c.exact_q[outside]
        segments = [(a, b, c.weights.get((a, b), 1.0)) for a, b in c.plan.segments]
        return Filled(root, q, contact, c.plan.pseudo_keyframes, segments, locked, c.checks)
