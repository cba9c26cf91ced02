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

**Re-fills** (``only``/``previous``): a caller that filled before hands over every key and, in the other gaps, the
earlier fill's output; the runtime computes the self-check and the weights as for a fill of every gap and generates the
gaps :func:`.plan.chosen_gaps` names (the changed ones, those whose weight changed, those whose context was generated
now), in the same order and with the same context as a fill of every gap; the other gaps' frames come back exactly as
given (:attr:`Filled.generated`).  The feet are found and locked gap by gap, each between its two keys, so a generated
gap is locked as a fill of every gap locks it, and the kept frames are never moved.

Arrays are ``root (F, 3)``, ``local_q (F, J, 4)`` (wxyz) in the model's skeleton: in the project's frame (Y up, cm),
or with ``file_frame=True`` in the training files' frame (:class:`~inbetweening.data.convention.FileConvention`,
recorded with the model), which is then converted on the way in and back.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from inbetweening.geometry import canonical
from inbetweening.geometry.interp import interpolate_keyframes, interpolate_known, interpolate_pose
from inbetweening.geometry.quaternion import qnormalize, remove_discontinuities

from . import rig_fill
from .adapt import Adaptation, adapt_clip, check_adaptable
from .foot_lock import ClipFeet, clip_feet, gap_contacts, lock_gap
from .model import Backend, InbetweenError
from .partial import check_clip, known_values
from .plan import GapPlan, check_refill, chosen_gaps, gap_windows, key_gaps, plan_gaps
from .rig_fill import RigFilled
from .settings import DEFAULT_SETTINGS, FillSettings
from .trust import Check, blend, checks_of, gap_share, gap_weights, scored

__all__ = ["Filled", "FillRuntime", "RigFilled"]


@dataclass
class Filled:
    """One filled clip.  ``root``/``local_q``: float64, keys, frames outside the filled span and the frames of gaps
    not generated exactly the input; ``contact (F, J)``: foot contact in [0, 1] on generated frames (the model's
    prediction; for a model without contact channels, the contact rule on the fill), the keys' own on keys, the rule on
    the frames of gaps not generated, ``None`` for a model whose data names no feet; ``pseudo_keyframes``: split
    points of long gaps; ``segments``: ``(a, b, weight)`` per window of every gap (``weight``: the network's share,
    the do-no-harm blend, :mod:`.trust`); ``shares``: the same per key gap, ``{(key, next key): (weight, ...)}`` (a
    re-fill's ``previous``); ``generated``: the key gaps generated, in order (every gap but in a re-fill);
    ``checks``: the self-checks on the keys (:class:`~inbetweening.runtime.trust.Check`); ``locked``: whether the feet
    were locked; ``feet``: the foot joints ``contact`` is about (the model's, or found by name for a model whose data
    did not record them); ``adaptation``: what test-time adaptation did (:class:`~.adapt.Adaptation`; ``None`` when
    off)."""

    root: np.ndarray
    local_q: np.ndarray
    contact: np.ndarray | None = None
    pseudo_keyframes: list[int] = field(default_factory=list)
    segments: list[tuple[int, int, float]] = field(default_factory=list)
    locked: bool = False
    checks: list[Check] = field(default_factory=list)
    shares: dict[tuple[int, int], tuple[float, ...]] = field(default_factory=dict)
    generated: list[tuple[int, int]] = field(default_factory=list)
    feet: list[int] = field(default_factory=list)
    adaptation: Adaptation | None = None


def _check_batch_size(batch_size) -> int:
    if isinstance(batch_size, bool) or not isinstance(batch_size, (int, np.integer)) or batch_size < 1:
        raise InbetweenError(f"batch_size must be a positive integer, got {batch_size!r}")
    return int(batch_size)


class _Clip:
    """A clip being filled: working arrays in the project's frame, its plan and what a re-fill keeps, the windows to
    generate, the predicted contact."""

    def __init__(self, root, q, keys, plan: GapPlan, exact_root, exact_q, only, previous, partial=None, base=None,
                 feet: ClipFeet | None = None):
        self.root, self.q, self.keys, self.plan = root, q, keys, plan
        self.partial = partial or {}  # partial keys {frame: (J,) bool}
        self.base = base  # with partial keys: every joint interpolated between its own known values (root, q)
        self.exact_root, self.exact_q = exact_root, exact_q
        self.only, self.previous = only, previous
        self.contact = np.full(q.shape[:2], np.nan)  # the model's contact channels on generated frames
        self.feet = feet  # what the keys say of the feet, None: no feet found
        self.planted = np.full(q.shape[:2], np.nan)  # the contact each generated gap was locked on (keys: their own)
        self.planted[keys] = np.nan if feet is None else feet.at_keys[keys]
        self.gap_ending: dict[int, tuple[int, int]] = {}  # key b -> the generated key gap (a, b)
        self.weights: dict[tuple[int, int], float] = {}
        self.checks: list[Check] = []
        self.generated: list[tuple[int, int]] = []
        self.todo: list[tuple[int, int]] = []
        self.shares: dict[tuple[int, int], tuple[float, ...]] = {}
        self.backend = None  # test-time adaptation: the clip's own network (None: the runtime's)
        self.adaptation: Adaptation | None = None


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
        settings: the fill's tuned numbers (:class:`~inbetweening.runtime.settings.FillSettings`: the self-check's
            thresholds, foot locking's, a re-fill's tolerance, an :class:`~.ensemble.EnsembleBackend`'s members'
            shares).
    """

    def __init__(self, backend: Backend, *, max_gap: int | None = None, segment: bool = True, foot_lock: bool = True,
                 batch_size: int = 4, self_check: bool = True, settings: FillSettings = DEFAULT_SETTINGS):
        if not isinstance(settings, FillSettings):
            raise InbetweenError(f"settings: expected a FillSettings, got {type(settings).__name__}")
        self.settings = settings
        if hasattr(backend, "share_power"):  # an ensemble: its members' shares are the fill's setting too
            backend.share_power = settings.share_power
        self.backend, self.info = backend, backend.info  # info: ModelInfo
        self.max_gap, self.segment, self.foot_lock = self.check_max_gap(max_gap), bool(segment), bool(foot_lock)
        self.batch_size, self.self_check = _check_batch_size(batch_size), bool(self_check)
        if settings.adapt_steps > 0:
            check_adaptable(backend)

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
             segment: bool | None = None, foot_lock: bool | None = None, self_check: bool | None = None,
             progress: Callable[[int, int], None] | None = None, only=None, previous=None, partial=None) -> Filled:
        """Generate every frame strictly between consecutive ``keys`` (sorted indices into the arrays); values of
        those frames are never read (NaN is fine).  ``progress(done, total)`` is called after each window.

        ``partial``: partial keys, ``{frame: joints}`` (a ``(J,)`` bool mask, joint indices or names) between the
        first and the last key: those joints' values at that frame are kept and constrain the fill, the frame's other
        joints are generated (:mod:`.partial`).

        A re-fill (module docstring): ``only``, the key gaps ``(key, next key)`` whose own inputs changed since an
        earlier fill (a key of theirs, or a context frame before the first key); ``previous``, the earlier fill's
        :attr:`Filled.shares` (a number per gap of one window will do); the frames of the other gaps hold the earlier
        fill's output, and come back exactly unless the gap is generated (:attr:`Filled.generated`)."""
        return self.fill_many([(root, local_q, keys, only, previous, partial)], file_frame=file_frame, max_gap=max_gap,
                              segment=segment, foot_lock=foot_lock, self_check=self_check, progress=progress)[0]

    def fill_rig(self, retarget, local_q, local_p, keys: Sequence[int], **kw) -> RigFilled:
        """Fill a humanoid rig that is not the model's skeleton through ``retarget`` (a rig <-> model
        :class:`~inbetweening.runtime.retarget.Retarget`): the keys onto the model's skeleton, :meth:`fill` there, the
        fill back onto the rig; :func:`.rig_fill.fill_rig` holds the road and its options."""
        return rig_fill.fill_rig(self, retarget, local_q, local_p, keys, **kw)

    def fill_many(self, clips, *, file_frame: bool = False, max_gap: int | None = None, segment: bool | None = None,
                  foot_lock: bool | None = None, self_check: bool | None = None, batch_size: int | None = None,
                  progress: Callable[[int, int], None] | None = None) -> list[Filled]:
        """:meth:`fill` of many ``(root, local_q, keys)`` (or ``(root, local_q, keys, only, previous[, partial])``)
        at once: the k-th window of every clip is generated together, ``batch_size`` windows of one length per backend
        call (windows within a clip still left to right).  The same numbers as clip by clip, up to float rounding of
        the batched network.  Every clip is checked first.  ``foot_lock``, ``self_check``: this call's, default the
        runtime's."""
        limit = self.max_gap if max_gap is None else self.check_max_gap(max_gap)
        size = self.batch_size if batch_size is None else _check_batch_size(batch_size)
        seg = self.segment if segment is None else bool(segment)
        work = [self._prepare(*clip, limit=limit, seg=seg, file_frame=file_frame) for clip in clips]
        self._weigh(work, size, self.self_check if self_check is None else bool(self_check))
        for c in work:
            self._choose(c)
        total, done = sum(len(c.todo) for c in work), 0
        lock = self.foot_lock if foot_lock is None else bool(foot_lock)
        for step in range(max((len(c.todo) for c in work), default=0)):
            groups: dict[int, list] = {}
            for c in work:
                if step < len(c.todo):
                    a, b = c.todo[step]
                    groups.setdefault((b - a, id(c.backend)), []).append((c, a, b))
            for items in groups.values():
                for i in range(0, len(items), size):
                    self._generate(items[i : i + size])
                    for c, _, b in items[i : i + size]:
                        if b in c.gap_ending:  # a key gap done: its feet, before the next gap takes it as context
                            self._feet(c, *c.gap_ending[b], lock)
                    done += len(items[i : i + size])
                    if progress is not None:
                        progress(done, total)
        return [self._finish(c, lock, file_frame) for c in work]

    # ------------------------------------------------------------------ stages
    def _prepare(self, root, local_q, keys, only=None, previous=None, partial=None, *, limit: int, seg: bool,
                 file_frame: bool) -> _Clip:
        """Check one clip, convert it to the project's frame and lay out its plan."""
        info = self.info
        exact_root = np.array(root, dtype=np.float64)
        exact_q = np.array(local_q, dtype=np.float64)
        j = info.skeleton.num_joints
        if exact_root.ndim != 2 or exact_root.shape[1] != 3 or exact_q.shape != (exact_root.shape[0], j, 4):
            raise InbetweenError(f"fill: expected root (F, 3) and local_q (F, {j}, 4) of the model's skeleton, "
                                 f"got {exact_root.shape} and {exact_q.shape}")
        keys, partial = check_clip("fill", len(exact_root), keys, partial, info.skeleton.names, [exact_q], exact_root)
        only, previous = check_refill(keys, only, previous)
        r, q = exact_root.copy(), exact_q.copy()
        if file_frame and not info.convention.is_project:
            r, q = info.convention.to_project(r, q)
        first = keys[0]
        bad = ~(np.isfinite(r[:first]).all(-1) & np.isfinite(q[:first]).all((-1, -2)))
        r[:first][bad], q[:first][bad] = r[first], q[first]  # no usable context there: the first key's pose
        feet = clip_feet(info.contact, info.skeleton, info.fps, r, q, keys, self.settings)  # on the keys as given
        q[: keys[-1] + 1] = qnormalize(q[: keys[-1] + 1])
        plan = plan_gaps(keys, limit, seg, info.trained_gap)
        base = None
        if partial:
            base = interpolate_known(r, q, known_values(partial, keys, len(r), j))
            for t in partial:  # what the windows show: the keyed joints, the others interpolated
                r[t], q[t] = base[0][t], base[1][t]
        return _Clip(r, q, keys, plan, exact_root, exact_q, only, previous, partial, base, feet)

    def windows(self, roots: Sequence[np.ndarray], qs: Sequence[np.ndarray], spans: Sequence[tuple[int, int]],
                partials: Sequence[dict] | None = None):
        """The context windows of gaps ``(a, b)`` of one length, one per clip ``roots[i] (F, 3)``, ``qs[i] (F, J, 4)``:
        ``root (B, T, 3), local_q (B, T, J, 4)`` (frames ``a - n_past + 1 .. a``, the gap holding frame ``a``'s values,
        never read, but at the frames of ``partials[i]`` (partial keys) their own, then ``b``), sign-continuous along
        time."""
        p = self.info.n_past
        wr, wq = [], []
        for i, (root, q, (a, b)) in enumerate(zip(roots, qs, spans)):
            gap = np.arange(a + 1, b)
            inside = np.isin(gap, list(partials[i])) if partials else np.zeros(len(gap), dtype=bool)
            idx = np.concatenate([np.clip(np.arange(a - p + 1, a + 1), 0, None), np.where(inside, gap, a), [b]])
            wr.append(root[idx])
            wq.append(remove_discontinuities(q[idx], axis=0))
        return np.stack(wr), np.stack(wq)

    def known_mask(self, batch: int, gap: int, starts: Sequence[int] | None = None,
                   partials: Sequence[dict] | None = None) -> np.ndarray:
        """``known (B, T, J)``: ``n_past`` context frames, ``gap`` unknown frames, the target; with ``partials[i]``
        (partial keys of window ``i``, whose gap starts after frame ``starts[i]``) their joints known there."""
        p, j = self.info.n_past, self.info.skeleton.num_joints
        known = np.zeros((batch, p + gap + 1, j), dtype=bool)
        known[:, :p] = True
        known[:, -1] = True
        for i, part in enumerate(partials or []):
            for t, mask in part.items():
                if 0 < t - starts[i] <= gap:
                    known[i, p + t - starts[i] - 1] = mask
        return known

    def canonical_windows(self, wr: np.ndarray, wq: np.ndarray, known: np.ndarray):
        """Windows in the clip's frame -> ``(root, local_q, (centre, rotation))`` in their canonical frame (decided by
        the known frames), as the backend takes them."""
        info = self.info
        centre, rot = canonical.canonical_frame(wr, wq, info.forward_axis, info.n_past - 1, known[..., 0],
                                                centre_at_frame=info.centre == "last")
        croot, cq = canonical.canonicalise(wr, wq, centre, rot)
        return croot, cq, (centre, rot)

    def predict_windows(self, wr: np.ndarray, wq: np.ndarray, known: np.ndarray | None = None,
                        backend=None, contacts: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Windows in the clip's frame -> the network's prediction of the gap (no blend): ``root (B, n, 3), local_q
        (B, n, J, 4)`` (unit), contact ``(B, n, J)`` or ``None``: canonical frame, backend, back.  ``known``: the
        windows' mask (default :meth:`known_mask` without partial keys); ``backend``: another network than the
        runtime's (a clip's adapted one); ``contacts=False``: the contact is not wanted (the backend may skip work for it
        and return ``None``)."""
        b, t = wr.shape[:2]
        p = self.info.n_past
        n = t - p - 1
        known = self.known_mask(b, n) if known is None else known
        croot, cq, (centre, rot) = self.canonical_windows(wr, wq, known)
        pr, pq, pc = (backend or self.backend).predict(croot, cq, known, None, contacts=contacts)
        pr, pq = canonical.uncanonicalise(np.asarray(pr, np.float64), np.asarray(pq, np.float64), centre, rot)
        pr, pq = pr[:, p : p + n], pq[:, p : p + n]
        pq = pq / np.linalg.norm(pq, axis=-1, keepdims=True)  # exactly unit
        pc = None if pc is None else np.asarray(pc, np.float64)[:, p : p + n]
        return pr, pq, pc

    def _weigh(self, work: list[_Clip], size: int, check: bool) -> None:
        """The do-no-harm weight of every window of every clip (:func:`.trust.gap_weights`): the self-checks first
        (``size`` windows of one length per backend call; context: the keys' interpolation)."""
        todo, bases = [], {}
        for c in work:
            if check:
                c.checks = checks_of(c.keys, self.info.trained_gap)
                known = [t for t in range(c.keys[0])] + list(c.keys)
                base = bases[id(c)] = interpolate_keyframes(c.root, c.q, known)
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
                pr, pq, _ = self.predict_windows(wr, wq, contacts=False)
                for j, (c, base, i) in enumerate(part):
                    ch = c.checks[i]
                    t = ch.key - ch.a - 1
                    c.checks[i] = scored(ch, self.info.skeleton, base[0], base[1], pr[j, t], pq[j, t])
        for c in work:
            if check and self.settings.adapt_steps > 0:
                c.backend, c.adaptation = adapt_clip(self, bases[id(c)], c.checks)
            weights = gap_weights(c.plan.segments, c.keys, c.checks, self.info.blend_weight, self.settings,
                                  self.info.trained_gap)
            c.weights = {k: w for k, (w, _) in weights.items()}

    def _choose(self, c: _Clip) -> None:
        """The key gaps to generate (:func:`.plan.chosen_gaps`), their windows in order, their pseudo-keyframes
        interpolated."""
        windows = gap_windows(c.keys, c.plan.segments)
        c.shares = {g: tuple(c.weights.get(w, 1.0) for w in ws) for g, ws in windows.items()}
        finite = np.isfinite(c.exact_root).all(-1) & np.isfinite(c.exact_q).all((-1, -2))
        c.generated = chosen_gaps(c.keys, c.shares, c.only, c.previous, self.info.n_past,
                                  lambda a, b: bool(finite[a + 1 : b].all()), self.settings.share_tolerance)
        c.todo = [w for g in c.generated for w in windows[g]]
        c.gap_ending = {b: (a, b) for a, b in c.generated}
        chosen = set(c.generated)
        for a, b, points in c.plan.pseudo:
            if (a, b) in chosen and c.base is not None:  # each joint between its own known values
                c.root[points], c.q[points] = c.base[0][points], c.base[1][points]
            elif (a, b) in chosen:
                w = (np.array(points) - a) / (b - a)
                c.root[points], c.q[points] = interpolate_pose(c.root[a], c.q[a], c.root[b], c.q[b], w)

    def _generate(self, items) -> None:
        """Fill frames ``a+1 .. b-1`` of each ``(clip, a, b)`` in place (gaps of one length, one backend call): the
        network's prediction blended with the interpolation by the window's weight."""
        spans = [(a, b) for _, a, b in items]
        parts = [{t: m for t, m in c.partial.items() if a < t < b} for c, a, b in items]
        wr, wq = self.windows([c.root for c, _, _ in items], [c.q for c, _, _ in items], spans, parts)
        known = self.known_mask(len(items), spans[0][1] - spans[0][0] - 1, [a for a, _ in spans], parts)
        pr, pq, pc = self.predict_windows(wr, wq, known, backend=items[0][0].backend)
        for i, (c, a, b) in enumerate(items):
            w = c.weights.get((a, b), 1.0)
            r, q = pr[i], pq[i]
            if w < 1.0:
                if parts[i]:  # the fall-back: each joint between its own known values
                    ir, iq = c.base[0][a + 1 : b], c.base[1][a + 1 : b]
                else:
                    ir, iq = interpolate_pose(c.root[a], c.q[a], c.root[b], c.q[b], (np.arange(a + 1, b) - a) / (b - a))
                r, q = blend(ir, iq, r, q, w)
            for t, mask in parts[i].items():  # partial keys exactly as keyed
                q[t - a - 1, mask] = c.q[t, mask]
                if mask[0]:
                    r[t - a - 1] = c.root[t]
            c.root[a + 1 : b] = r
            c.q[a + 1 : b] = remove_discontinuities(np.concatenate([c.q[a : a + 1], q]), axis=0)[1:]
            if pc is not None:
                c.contact[a + 1 : b] = pc[i]

    def _feet(self, c: _Clip, a: int, b: int, lock: bool) -> None:
        """The contact of the generated key gap ``(a, b)`` (:func:`.foot_lock.gap_contacts`), and with ``lock`` its feet
        locked in place, between its two keys (never moved, nor the partial keys: their keyed joints stay exact)."""
        if c.feet is None:
            return
        pc = c.contact[a + 1 : b] if self.info.has_contacts and not np.isnan(c.contact[a + 1 : b]).any() else None
        c.planted[a + 1 : b] = gap_contacts(self.info.skeleton, c.feet, self.info.fps, c.root, c.q, a, b, pc,
                                            share=gap_share(c.shares, (a, b)), settings=self.settings)
        if lock:
            c.root[a + 1 : b], c.q[a + 1 : b] = lock_gap(self.info.skeleton, c.feet, c.root, c.q, c.planted, a, b,
                                                         [t for t in c.partial if a < t < b], self.settings)

    def _finish(self, c: _Clip, lock: bool, file_frame: bool) -> Filled:
        """Keys exact, back to the file's frame; keys, outside frames and the frames of gaps not generated exactly the
        input; the contact: the keys' own on keys, what each generated gap was locked on, the rule on kept gaps as they
        are."""
        info = self.info
        keys = c.keys
        if file_frame and not info.convention.is_project:
            exact_r, exact_q = info.convention.to_project(c.exact_root[keys], c.exact_q[keys])
        else:
            exact_r, exact_q = c.exact_root[keys], c.exact_q[keys]
        root, q = c.root.copy(), c.q.copy()
        root[keys], q[keys] = exact_r, exact_q
        kept = np.zeros(len(root), dtype=bool)
        contact, feet = None, []
        if c.feet is not None:
            feet, contact = list(c.feet.feet), c.planted.copy()
        gaps, lo, hi = sorted(set(key_gaps(keys)) - set(c.generated)), keys[0], keys[-1] + 1
        gp = info.skeleton.pose(root[lo:hi], q[lo:hi])[1] if gaps and c.feet is not None else None  # one FK for all
        for a, b in gaps:
            kept[a + 1 : b] = True
            if gp is not None:
                contact[a + 1 : b] = gap_contacts(info.skeleton, c.feet, info.fps, root, q, a, b,
                                                  positions=gp[a - lo : b - lo + 1], share=gap_share(c.shares, (a, b)),
                                                  settings=self.settings)
        locked = lock and c.feet is not None
        if file_frame and not info.convention.is_project:
            root, q = info.convention.to_file(root, q)
        outside = np.ones(len(root), dtype=bool)
        outside[keys[0] + 1 : keys[-1]] = False
        outside[keys] = True
        outside |= kept
        root[outside], q[outside] = c.exact_root[outside], c.exact_q[outside]
        for t, mask in c.partial.items():  # partial keys: the keyed joints exactly as given
            q[t, mask] = c.exact_q[t, mask]
            if mask[0]:
                root[t] = c.exact_root[t]
        segments = [(a, b, c.weights.get((a, b), 1.0)) for a, b in c.plan.segments]
        return Filled(root, q, contact, c.plan.pseudo_keyframes, segments, locked, c.checks, c.shares,
                      list(c.generated), feet, c.adaptation)
