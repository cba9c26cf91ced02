"""Animator-facing in-betweening: fill the frames between keyframes of a BVH clip with a trained model.

    from inbetweening import Inbetweener

    ib = Inbetweener.from_checkpoint("run/checkpoints/best.ckpt")
    out = ib.fill("clip.bvh", keyframes=[0, 30, 75])    # keep frames 0, 30, 75; generate the rest
    out = ib.fill("keys.bvh", gap=30)                  # every input frame is a key; 30 new frames between each pair
    write_bvh(out, "filled.bvh")

How a transition is generated (the same conditions the model was trained under):

* Gaps are filled left to right.  For keyframes ``a < b`` the model sees a window of ``n_past`` (10) known
  context frames ending at ``a`` (taken from the already completed output: earlier keyframes and frames
  generated before; when fewer than ``n_past`` frames exist the first frame is repeated), the ``b - a - 1``
  unknown frames, and the known target ``b``.
* The window is normalised like the training windows: XZ centred on the mean root XZ of the known frames and
  rotated about Y so that the root's forward axis at frame ``a`` points to +X; the predicted root positions and
  root rotations are taken back to the clip's frame afterwards (a root yaw leaves the other joints' local
  rotations unchanged).
* Long gaps: the model only saw transitions of up to ``trained_gap`` frames (the data module's
  ``transition_max`` recorded in the checkpoint, else ``train_window - n_past - 1``).  A longer gap is split
  into ``m = ceil((b - a) / (max_gap + 1))`` equal segments; the poses at the ``m - 1`` split points are
  *pseudo-keyframes* interpolated between ``a`` and ``b`` (root position linearly, every joint rotation by
  slerp), then each segment is generated left to right as above, its context being the end of the previous
  segment.  The true keyframes are never modified.  With ``segment=False`` a gap longer than ``max_gap``
  raises :class:`InbetweenError` instead.

The model's skeleton must match the file's: same joint names in the same order, or the file has one extra
motionless top joint above the model's root (Bandai-Namco's ``joint_Root`` above ``Hips``), which is folded
into the root for the model and unfolded again when writing (its channels are copied from the nearest
keyframe).
"""
from __future__ import annotations

import itertools
import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from inbetweening.data.bvh import BVH, read_bvh
from inbetweening.data.clips import clip_in_skeleton, motion_in_file
from inbetweening.data.errors import DatasetError
from inbetweening.geometry.interp import interpolate_keyframes, interpolate_pose
from inbetweening.geometry.quaternion import qnormalize, remove_discontinuities
from inbetweening.geometry.skeleton import Skeleton
from inbetweening.tools.foot_lock import lock_feet

__all__ = ["FillResult", "InbetweenError", "Inbetweener"]


class InbetweenError(ValueError):
    """Bad keyframes, gap or skeleton for in-betweening; the message says what and where."""


@dataclass
class FillResult:
    """What :meth:`Inbetweener.fill_detailed` produced.

    ``root``/``local_q`` are in the model's skeleton (a folded ``joint_Root`` is not part of it);
    ``known_frames`` are the output frames that are keyframes; ``pseudo_keyframes`` the split points of
    gaps longer than ``max_gap`` (interpolated, see the module docstring); ``contact`` the foot contact the model
    predicted (:meth:`Inbetweener.fill_arrays` ``with_contacts``; ``None`` for a model without contact channels).
    """

    bvh: BVH
    root: np.ndarray  # (F, 3)
    local_q: np.ndarray  # (F, J, 4)
    known_frames: list[int]
    skeleton: Skeleton
    pseudo_keyframes: list[int] = field(default_factory=list)
    contact: np.ndarray | None = None  # (F, J) foot contact in [0, 1]: predicted; keys: their own; None: not predicted

    @property
    def num_frames(self) -> int:
        return int(self.root.shape[0])

    def global_positions(self) -> np.ndarray:
        """``(F, J, 3)`` global joint positions of the result (model skeleton, its bone offsets)."""
        return self.skeleton.pose(np.asarray(self.root, np.float64), np.asarray(self.local_q, np.float64))[1]

    def interpolation(self) -> tuple[np.ndarray, np.ndarray]:
        """The same keyframes filled by linear root / slerp rotation interpolation: ``(F, 3), (F, J, 4)``."""
        return interpolate_keyframes(self.root, self.local_q, self.known_frames)


def _check_frames(frames, length: int, what: str) -> list[int]:
    """Validate a list of frame indices: ints, at least 2, strictly increasing, inside ``[0, length)``."""
    if frames is None or isinstance(frames, (str, bytes)):
        raise InbetweenError(f"{what} must be a list of frame indices, got {frames!r}")
    out = []
    for k in list(frames):
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)):
            raise InbetweenError(f"{what}: {k!r} is not an integer frame index")
        out.append(int(k))
    if len(out) < 2:
        raise InbetweenError(f"{what}: need at least 2 keyframes, got {len(out)} ({out})")
    for k in out:
        if not 0 <= k < length:
            raise InbetweenError(
                f"{what}: frame {k} is out of range for a clip of {length} frames (valid: 0..{length - 1})")
    for i in range(1, len(out)):
        if out[i] == out[i - 1]:
            raise InbetweenError(f"{what}: frame {out[i]} is listed twice")
        if out[i] < out[i - 1]:
            raise InbetweenError(f"{what}: must be sorted in increasing order ({out[i - 1]} comes before {out[i]})")
    return out


class Inbetweener:
    """A trained in-betweening model wrapped for keyframe filling (see the module docstring).

    Args:
        model: a :class:`~inbetweening.predictor.predictor.Predictor` (what :meth:`from_checkpoint` loads) or a
            trained :class:`~inbetweening.training.module.InbetweenModule` (its predictor is used); moved to
            ``eval`` mode.
        max_gap: longest transition generated in one window; default ``trained_gap``.  May be raised up to
            ``max_frames - n_past - 1`` of the network (beyond what it was trained on: quality not guaranteed).
        segment: split longer gaps (``True``, default) or raise :class:`InbetweenError`.
        trained_gap: the longest transition the model saw in training; default
            ``train_window - n_past - 1``.
        foot_lock: hold the feet where the model predicts contact (:mod:`inbetweening.tools.foot_lock`; models whose
            representation has contact channels, on data with feet); ``False``: the network's output as it is.
    """

    def __init__(self, model, max_gap: int | None = None, segment: bool = True, trained_gap: int | None = None,
                 foot_lock: bool = True):
        self.module = model.eval()
        self.predictor = getattr(model, "predictor", model)
        self.skeleton: Skeleton = self.predictor.skeleton
        self.n_past = int(self.predictor.n_past)
        self.fps = float(self.predictor.fps)
        window = int(self.predictor.train_window)
        self.hard_max_gap = (self.predictor.max_frames or 10**9) - self.n_past - 1
        default = window - self.n_past - 1
        self.trained_gap = min(int(trained_gap) if trained_gap else default, default, self.hard_max_gap)
        if self.trained_gap < 1:
            raise InbetweenError(f"the model's window ({window} frames, n_past={self.n_past}) leaves no room for a gap")
        self.max_gap = self._check_max_gap(max_gap)
        self.segment = bool(segment)
        self.foot_lock = bool(foot_lock)

    @classmethod
    def from_checkpoint(cls, path: str | Path, device: str | torch.device = "cpu", **kw) -> Inbetweener:
        """Load a training checkpoint's predictor (``CheckpointError`` for missing or wrong files).

        ``kw`` go to the constructor (``max_gap``, ``segment``); ``trained_gap`` defaults to the data module's
        ``transition_max`` recorded in the checkpoint.
        """
        from inbetweening.predictor.checkpoint import load_predictor, read_checkpoint, trained_gap

        ckpt = read_checkpoint(str(path))
        if "trained_gap" not in kw and trained_gap(ckpt):
            kw["trained_gap"] = trained_gap(ckpt)
        return cls(load_predictor(str(path), device, ckpt=ckpt), **kw)

    @property
    def device(self) -> torch.device:
        return self.predictor.device

    def _check_max_gap(self, max_gap: int | None) -> int:
        if max_gap is None:
            return self.trained_gap
        if isinstance(max_gap, bool) or not isinstance(max_gap, (int, np.integer)) or max_gap < 1:
            raise InbetweenError(f"max_gap must be a positive integer, got {max_gap!r}")
        if max_gap > self.hard_max_gap:
            raise InbetweenError(f"max_gap={max_gap} exceeds what the network supports "
                                 f"({self.hard_max_gap} = max_frames - {self.n_past} context - 1 target)")
        return int(max_gap)

    # ------------------------------------------------------------------ array level
    def fill_arrays(self, root, local_q, known_frames, *, max_gap: int | None = None, segment: bool | None = None,
                    foot_lock: bool | None = None, with_contacts: bool = False,
                    _pseudo: list[int] | None = None) -> tuple[np.ndarray, ...]:
        """Generate every frame not in ``known_frames``.

        Args:
            root: ``(F, 3)`` root positions; local_q: ``(F, J, 4)`` local rotations wxyz, in the model's skeleton.
                Values of unknown frames are never read (they may be NaN).
            known_frames: sorted frame indices, at least 2, the first 0 and the last ``F - 1``.
            max_gap, segment, foot_lock: override the instance's settings (see the class docstring).
            with_contacts: also return the foot contact ``(F, J)`` in [0, 1]: the model's prediction on generated
                frames, the keyframes' own (the representation's rule on the keys alone) on known ones (the feet's
                columns are the ones that mean something); ``None`` when the representation has no contact channels.
        Returns:
            ``root (F, 3), local_q (F, J, 4)`` float64 (then ``contact`` with ``with_contacts``); known frames equal
            the input exactly.
        """
        return self.fill_many([(root, local_q, known_frames)], max_gap=max_gap, segment=segment, foot_lock=foot_lock,
                              with_contacts=with_contacts, _pseudo=None if _pseudo is None else [_pseudo])[0]

    def fill_many(self, clips, *, max_gap: int | None = None, segment: bool | None = None, batch_size: int = 4,
                  foot_lock: bool | None = None, with_contacts: bool = False,
                  _pseudo: list[list[int]] | None = None) -> list[tuple[np.ndarray, ...]]:
        """:meth:`fill_arrays` of many clips at once: ``clips`` is a sequence of ``(root, local_q, known_frames)``;
        returns one ``(root, local_q)`` (with ``with_contacts``: ``(root, local_q, contact)``) per clip, the same
        numbers as :meth:`fill_arrays` clip by clip (up to float rounding of the batched network).

        Gaps are still filled left to right within a clip (a gap's context is the previous gap's output), but the
        k-th gap of every clip is generated together: one :meth:`Predictor.fill_windows` forward pass per
        ``batch_size`` gaps of the same length (default 4: on the 2-core CPU it was measured on, batches of about 4
        windows run fastest per transition and much larger ones fall out of the cache; BENCHMARKS.md, "Inference
        latency").  Every clip is checked before anything is generated.
        """
        if isinstance(batch_size, bool) or not isinstance(batch_size, (int, np.integer)) or batch_size < 1:
            raise InbetweenError(f"batch_size must be a positive integer, got {batch_size!r}")
        limit = self._check_max_gap(max_gap) if max_gap is not None else self.max_gap
        seg = self.segment if segment is None else bool(segment)
        plans = [self._plan(r, q, k, limit, seg, None if _pseudo is None else _pseudo[i])
                 for i, (r, q, k) in enumerate(clips)]
        for step in range(max((len(p[2]) for p in plans), default=0)):
            groups: dict[int, list] = {}
            for plan in plans:
                if step < len(plan[2]):
                    a, b = plan[2][step]
                    groups.setdefault(b - a, []).append((plan, a, b))
            for items in groups.values():
                for i in range(0, len(items), batch_size):
                    self._generate(items[i : i + batch_size])
        lock = self.foot_lock if foot_lock is None else bool(foot_lock)
        feet = self.predictor.contact.indices(self.skeleton.names, "the model's feet") if lock else ()
        out = []
        for root, q, _, known, exact_r, exact_q, contact in plans:
            root[known], q[known] = exact_r, exact_q
            predicted = not np.isnan(contact).all()
            if predicted and (feet or with_contacts):
                contact = self._with_key_contacts(root, q, known, contact)
            if feet and predicted:
                q = lock_feet(self.skeleton, root, q, known, contact, feet)
            out.append((root, q, contact if predicted else None) if with_contacts else (root, q))
        return out

    def _with_key_contacts(self, root, q, known, contact) -> np.ndarray:
        """The generated frames' predicted contact ``(F, J)`` with the keyframes' own next to it (the
        representation's rule on the keys alone), as :func:`~inbetweening.tools.foot_lock.lock_feet` reads it."""
        rep = self.predictor.representation
        keys_only = np.full_like(root, np.nan), np.full_like(q, np.nan)
        keys_only[0][known], keys_only[1][known] = root[known], q[known]
        labels = rep.contacts(rep.encode_windows(*keys_only, dtype=torch.float64)).numpy()
        return np.where(np.isnan(contact), labels, contact)

    def _plan(self, root, local_q, known_frames, limit: int, seg: bool, pseudo: list[int] | None):
        """Check one clip and lay out its segments: ``(root, q, [(a, b), ...], known, exact root, exact q)``;
        pseudo-keyframes of long gaps are interpolated into ``root``/``q`` here."""
        root = np.array(root, dtype=np.float64)
        q = np.array(local_q, dtype=np.float64)
        j = self.skeleton.num_joints
        if root.ndim != 2 or root.shape[1] != 3 or q.shape != (root.shape[0], j, 4):
            raise InbetweenError(f"fill_arrays: expected root (F, 3) and local_q (F, {j}, 4), "
                                 f"got {root.shape} and {q.shape}")
        n = root.shape[0]
        known = _check_frames(known_frames, n, "known_frames")
        if known[0] != 0 or known[-1] != n - 1:
            raise InbetweenError(f"known_frames must start at frame 0 and end at frame {n - 1} (the whole array "
                                 f"is filled), got {known[0]}..{known[-1]}")
        if not (np.isfinite(root[known]).all() and np.isfinite(q[known]).all()):
            raise InbetweenError("fill_arrays: known frames contain NaN or infinite values")
        exact_r, exact_q = root[known].copy(), q[known].copy()
        contact = np.full((n, j), np.nan)  # predicted foot contact of the generated frames
        q[known] = qnormalize(q[known])
        segments = []
        for a, b in itertools.pairwise(known):
            gap = b - a - 1
            if gap == 0:
                continue
            if gap > limit and not seg:
                raise InbetweenError(
                    f"the gap between keyframes {a} and {b} is {gap} frames, longer than max_gap={limit} "
                    f"(the model was trained on gaps up to {self.trained_gap}); enable segmentation or add keyframes")
            m = math.ceil((b - a) / (limit + 1))
            points = [a + round(i * (b - a) / m) for i in range(m + 1)]
            if m > 1:
                w = (np.array(points[1:-1]) - a) / (b - a)
                root[points[1:-1]], q[points[1:-1]] = interpolate_pose(root[a], q[a], root[b], q[b], w)
                if pseudo is not None:
                    pseudo.extend(points[1:-1])
            segments += [(s, e) for s, e in itertools.pairwise(points) if e - s > 1]
        return root, q, segments, known, exact_r, exact_q, contact

    def _generate(self, items) -> None:
        """Fill frames ``a+1 .. b-1`` of each ``(plan, a, b)`` in place (all gaps of one length, one forward pass)
        from context ending at ``a`` and target ``b``."""
        wr, wq = [], []
        for (root, q, *_), a, b in items:
            n, p = b - a - 1, self.n_past
            ctx = np.clip(np.arange(a - p + 1, a + 1), 0, None)
            idx = np.concatenate([ctx, np.full(n, a), [b]])  # unknown frames hold frame a (never read by the model)
            wr.append(root[idx])
            wq.append(_continuous(q[idx]))
        prs, pqs, cs = self.predictor.fill_windows(np.stack(wr), np.stack(wq), with_contacts=True)
        for i, ((root, q, *_, contact), a, b) in enumerate(items):
            # sign-continuous with frame a (cosmetic: every frame is written as Euler angles anyway)
            root[a + 1 : b], q[a + 1 : b] = prs[i], _continuous(np.concatenate([q[a : a + 1], pqs[i]]))[1:]
            if cs is not None:
                contact[a + 1 : b] = cs[i]

    # ------------------------------------------------------------------ BVH level
    def fill(self, bvh: BVH | str | Path, keyframes: list[int] | None = None, gap: int | None = None, *,
             max_gap: int | None = None, segment: bool | None = None, foot_lock: bool | None = None) -> BVH:
        """In-between a BVH clip; returns a new :class:`~inbetweening.data.bvh.BVH` (write it with ``write_bvh``).

        Give exactly one of:

        * ``keyframes`` (form A): frame indices of ``bvh`` to keep (>= 2, increasing, any spacing).  Every other
          frame between the first and the last keyframe is generated; frames before the first and after the
          last keyframe are dropped, so the output has ``last - first + 1`` frames and input frame ``k`` is
          output frame ``k - first``.
        * ``gap`` (form B): every frame of ``bvh`` is a keyframe; ``gap`` frames are generated between each
          consecutive pair, so ``K`` input frames give ``K + (K - 1) * gap`` output frames.

        The output has the input's hierarchy, channel order and frame time; keyframe rows of ``motion`` are the
        input's rows, bit for bit; generated frames take non-root position channels (and a folded
        ``joint_Root``'s channels) from the nearest keyframe.  Gaps longer than ``max_gap`` are split with
        interpolated pseudo-keyframes unless ``segment=False`` (then :class:`InbetweenError`); see the module
        docstring.  Errors: :class:`InbetweenError` (keyframes, gap, skeleton), ``BVHError`` (unreadable file).
        """
        return self.fill_detailed(bvh, keyframes, gap, max_gap=max_gap, segment=segment, foot_lock=foot_lock).bvh

    def fill_detailed(self, bvh: BVH | str | Path, keyframes: list[int] | None = None, gap: int | None = None, *,
                      max_gap: int | None = None, segment: bool | None = None,
                      foot_lock: bool | None = None) -> FillResult:
        """:meth:`fill` plus the arrays behind it (for rendering and inspection): a :class:`FillResult`."""
        if not isinstance(bvh, BVH):
            bvh = read_bvh(bvh)
        if (keyframes is None) == (gap is None):
            raise InbetweenError("give exactly one of keyframes (frames of the clip to keep) or gap "
                                 "(frames to generate between consecutive input frames)")
        n_in = bvh.num_frames
        if keyframes is not None:
            src = _check_frames(keyframes, n_in, "keyframes")
            out_pos = [k - src[0] for k in src]
        else:
            if isinstance(gap, bool) or not isinstance(gap, (int, np.integer)) or gap < 1:
                raise InbetweenError(f"gap must be an integer >= 1, got {gap!r}")
            if n_in < 2:
                raise InbetweenError(f"gap: the input must hold at least 2 keyframes, it has {n_in} frame(s)")
            src = list(range(n_in))
            out_pos = [i * (int(gap) + 1) for i in range(n_in)]
        if bvh.frame_time > 0 and abs(1.0 / bvh.frame_time - self.fps) > 0.5:
            warnings.warn(f"{bvh.source}: {1.0 / bvh.frame_time:.3g} fps, the model was trained at {self.fps:.3g} "
                          f"fps; gaps are counted in the file's frames", stacklevel=2)
        fold, root_in, q_in = self._model_space(bvh)
        n_out = out_pos[-1] + 1
        root = np.full((n_out, 3), np.nan)
        q = np.full((n_out, self.skeleton.num_joints, 4), np.nan)
        root[out_pos], q[out_pos] = root_in[src], q_in[src]
        pseudo: list[int] = []
        root, q, contact = self.fill_arrays(root, q, out_pos, max_gap=max_gap, segment=segment, foot_lock=foot_lock,
                                            with_contacts=True, _pseudo=pseudo)
        out = self._to_bvh(bvh, fold, root, q, src, out_pos)
        return FillResult(out, root, q, out_pos, self.skeleton, sorted(pseudo), contact)

    def _model_space(self, bvh: BVH) -> tuple[bool, np.ndarray, np.ndarray]:
        """``(folded?, root (F, 3), local_q (F, J, 4))`` of a clip in the model's skeleton and frame (the file's up
        axis and unit turned into the model's by the training files' convention, which the checkpoint records)."""
        try:
            fold, root, q = clip_in_skeleton(bvh, self.skeleton)
        except DatasetError as e:
            raise InbetweenError(str(e)) from None
        return (fold, root, q) if self.predictor.convention.is_project else (fold, *self.predictor.convention.to_project(root, q))

    def _to_bvh(self, bvh: BVH, fold: bool, root: np.ndarray, q: np.ndarray, src: list[int], out_pos: list[int]):
        """The output clip: generated frames written into the file's hierarchy (a folded top joint takes the nearest
        keyframe's values), the keyframes' rows copied unchanged."""
        t = np.arange(root.shape[0])
        keys = np.asarray(out_pos)
        nearest = np.abs(t[:, None] - keys[None, :]).argmin(axis=1)  # ties -> the earlier keyframe
        if not self.predictor.convention.is_project:
            root, q = self.predictor.convention.to_file(root, q)
        out = motion_in_file(bvh, fold, root, q, np.asarray(src)[nearest])
        out.motion[keys] = bvh.motion[np.asarray(src)]
        return out


def _continuous(q: np.ndarray) -> np.ndarray:
    """Flip signs along axis 0 so consecutive quaternions have non-negative dot products."""
    return remove_discontinuities(q, axis=0)
