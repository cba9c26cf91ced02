"""Animator-facing in-betweening: fill the frames between keyframes of a BVH clip with a trained model.

    from inbetweening import Inbetweener

    ib = Inbetweener.from_checkpoint("run/checkpoints/best.ckpt")
    ib = Inbetweener.from_checkpoint(["a.ckpt", "b.ckpt"])  # an ensemble: the models' mean (runtime.ensemble)
    ib = Inbetweener.from_checkpoint(["a.onnx", "b.onnx"])  # their exported window graphs: no PyTorch needed
    out = ib.fill("clip.bvh", keyframes=[0, 30, 75])    # keep frames 0, 30, 75; generate the rest
    out = ib.fill("keys.bvh", gap=30)                  # every input frame is a key; 30 new frames between each pair
    write_bvh(out, "filled.bvh")

This is the Python API over the fill runtime (:class:`inbetweening.runtime.FillRuntime`): a training checkpoint runs
on the torch backend, its exported window graph (``.onnx``, :func:`~inbetweening.api.export.export_window_onnx`) on
ONNX Runtime without importing PyTorch (what ``predict`` starts with by default).  How a gap is generated (context,
canonical frame, long gaps split at interpolated pseudo-keyframes, the do-no-harm blend, foot locking, keys kept
exactly) is described there, and the CLI, ``eval.py`` and the Blender extension fill through the same runtime.  This
module adds the clip level: a BVH file's joints and frames into the model's skeleton and back.

A clip of the model's skeleton is filled as it is: same joint names in the same order, or one extra top joint
above the model's root (Bandai-Namco's ``joint_Root`` above ``Hips``, still or carrying the locomotion), which is
folded into the root for the model (by composition, :func:`~inbetweening.data.clips.fold_static_root`)
and unfolded again when writing: on a generated frame the top joint moves between its values at the two
surrounding keyframes (position lerp, rotation slerp; copied raw where they agree, so a still top joint keeps its
channels bit for bit) and the root gets the generated global motion expressed under it, so the world motion is the
model's and every channel curve is continuous; keyframe rows are the input's, bit for bit.
A clip of any other humanoid character is retargeted: its bones are matched to the model's joints
(:func:`~inbetweening.runtime.bone_map.detect_bone_map`, or an override file, ``bone_map=``), the keys are carried
onto the model's skeleton, filled there and carried back (:meth:`FillRuntime.fill_rig`), every bone of the
character keyed exactly as given.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from inbetweening.data.bvh import BVH, read_bvh
from inbetweening.data.clips import clip_in_skeleton, motion_in_file
from inbetweening.data.errors import DatasetError
from inbetweening.geometry.interp import interpolate_keyframes
from inbetweening.geometry.skeleton import Skeleton
from inbetweening.runtime import FillRuntime, InbetweenError
from inbetweening.runtime.ensemble import EnsembleBackend
from inbetweening.runtime.partial import check_partial
from inbetweening.runtime.plan import check_keys
from inbetweening.runtime.settings import FillSettings

__all__ = ["FillResult", "InbetweenError", "Inbetweener"]


def _keep_partial_rows(out: BVH, bvh: BVH, part: dict[int, np.ndarray], first: int) -> None:
    """The partial keys' bones in ``out``'s rows as in ``bvh``'s (their raw channel values, bit for bit); ``part``:
    ``{input frame: (J,) bool mask of bvh's bones}``, output row ``frame - first``."""
    ends = np.cumsum([len(ch) for ch in bvh.channels])
    for t, mask in part.items():
        for j in np.flatnonzero(mask):
            cols = slice(ends[j] - len(bvh.channels[j]), ends[j])
            out.motion[t - first, cols] = bvh.motion[t, cols]


def _bone_map(bvh: BVH, bone_map):
    """The character's :class:`~inbetweening.runtime.bone_map.BoneMap`: detected, with ``bone_map`` (a path of an
    override file, or a dict ``rig bone -> slot``) on top; :class:`InbetweenError` (one line) when it cannot be made."""
    from inbetweening.runtime.bone_map import BoneMapError, detect_bone_map, read_override

    try:
        override = read_override(bone_map) if isinstance(bone_map, (str, Path)) else bone_map
        return detect_bone_map(bvh.names, bvh.parents, bvh.offsets, override, where=bvh.source)
    except BoneMapError as e:
        err = InbetweenError(str(e))
        err.template = getattr(e, "template", None)
        raise err from None


@dataclass
class FillResult:
    """What :meth:`Inbetweener.fill_detailed` produced.

    ``root``/``local_q`` are in the model's skeleton (a folded ``joint_Root`` is not part of it);
    ``known_frames`` are the output frames that are keyframes; ``pseudo_keyframes`` the split points of
    gaps longer than ``max_gap`` (interpolated, see the module docstring); ``contact`` the foot contact the lock used
    (the model's prediction, or the contact rule on the fill; keys: their own); ``segments`` ``(a, b, weight)`` per
    generated window of the model's frames (``weight``: the network's share) and ``checks`` the self-checks on the
    keys (:mod:`inbetweening.runtime.trust`).
    """

    bvh: BVH
    root: np.ndarray  # (F, 3)
    local_q: np.ndarray  # (F, J, 4)
    known_frames: list[int]
    skeleton: Skeleton
    pseudo_keyframes: list[int] = field(default_factory=list)
    contact: np.ndarray | None = None  # (F, J) foot contact in [0, 1]; keys: their own; None: no feet
    bone_map: object | None = None  # the character's BoneMap when the clip was retargeted (another skeleton)
    segments: list = field(default_factory=list)
    checks: list = field(default_factory=list)

    @property
    def num_frames(self) -> int:
        return int(self.root.shape[0])

    def global_positions(self) -> np.ndarray:
        """``(F, J, 3)`` global joint positions of the result (model skeleton, its bone offsets)."""
        return self.skeleton.pose(np.asarray(self.root, np.float64), np.asarray(self.local_q, np.float64))[1]

    def interpolation(self) -> tuple[np.ndarray, np.ndarray]:
        """The same keyframes filled by linear root / slerp rotation interpolation: ``(F, 3), (F, J, 4)``."""
        return interpolate_keyframes(self.root, self.local_q, self.known_frames)


def _is_backend(model) -> bool:
    """Whether ``model`` is already a runtime backend (``info`` and ``predict``), not a torch model to wrap."""
    return hasattr(model, "info") and callable(getattr(model, "predict", None)) and not hasattr(model, "parameters")


def _torch_backend(model, trained_gap):
    from inbetweening.runtime.torch_backend import TorchBackend

    return TorchBackend(model, trained_gap)


class Inbetweener:
    """A trained in-betweening model wrapped for keyframe filling (see the module docstring).

    Args:
        model: a :class:`~inbetweening.predictor.predictor.Predictor` (what :meth:`from_checkpoint` loads from a
            ``.ckpt``), a trained :class:`~inbetweening.training.module.InbetweenModule` (its predictor is used; moved
            to ``eval`` mode) or a runtime backend (:class:`~inbetweening.runtime.model.Backend`, e.g. the
            :class:`~inbetweening.runtime.onnx_backend.OnnxBackend` of an ``.onnx`` file).  A list of them (models of
            one skeleton): their ensemble (:class:`~inbetweening.runtime.ensemble.EnsembleBackend`);
            ``module``/``predictor`` are the first's (``None`` for a backend without PyTorch).
        max_gap: longest transition generated in one window; default ``trained_gap``.  May be raised up to
            ``max_frames - n_past - 1`` of the network (beyond what it was trained on: quality not guaranteed).
        segment: split longer gaps (``True``, default) or raise :class:`InbetweenError`.
        trained_gap: the longest transition the model saw in training; default ``train_window - n_past - 1`` (a list,
            one per model of an ensemble).
        foot_lock: hold the feet where the model predicts contact (:mod:`inbetweening.runtime.foot_lock`; models whose
            representation has contact channels, on data with feet); ``False``: the network's output as it is.
        names: the models' names for error messages (an ensemble's member that does not fit the first), e.g. their
            checkpoint paths.
        self_check: scale the network's share of each gap by how well it predicts the caller's own keys
            (:mod:`inbetweening.runtime.trust`; default on); ``False``: the calibrated weight per gap length alone.
        settings: the fill's tuned numbers, a :class:`~inbetweening.runtime.settings.FillSettings` or a mapping of
            the ones to change (``{"x_full": 0.7}``); default: the shipped ones.
    """

    def __init__(self, model, max_gap: int | None = None, segment: bool = True, trained_gap: int | None = None,
                 foot_lock: bool = True, self_check: bool = True, names=None, settings=None):
        models = list(model) if isinstance(model, (list, tuple)) else [model]
        gaps = list(trained_gap) if isinstance(trained_gap, (list, tuple)) else [trained_gap] * len(models)
        if not models or len(gaps) != len(models):
            raise InbetweenError(f"Inbetweener: {len(models)} models and {len(gaps)} trained gaps")
        members = [m if _is_backend(m) else _torch_backend(m, g) for m, g in zip(models, gaps)]
        self.backend = members[0] if len(members) == 1 else EnsembleBackend(members, names)
        if not isinstance(settings, FillSettings):
            settings = FillSettings.from_mapping(settings)
        self.runtime = FillRuntime(self.backend, max_gap=max_gap, segment=segment, foot_lock=foot_lock,
                                   self_check=self_check, settings=settings)
        self.settings: FillSettings = settings
        self.module = getattr(members[0], "module", None)
        self.predictor = getattr(members[0], "predictor", None)
        info = self.runtime.info
        self.skeleton: Skeleton = info.skeleton
        self.n_past, self.fps = info.n_past, info.fps
        self.trained_gap, self.hard_max_gap = info.trained_gap, info.hard_max_gap

    @classmethod
    def from_checkpoint(cls, path: str | Path | list, device="cpu", threads: int = 1, **kw) -> Inbetweener:
        """Load a training checkpoint's predictor (``CheckpointError`` for missing or wrong files) or, for a path
        ending in ``.onnx``, an exported window graph on ONNX Runtime (``threads``: its intra-op threads; PyTorch is
        not imported; ``ModelError`` for a file that is not one); a list of paths: their ensemble (``ModelError``
        naming the file that does not fit the first one).

        ``kw`` go to the constructor (``max_gap``, ``segment``, ``foot_lock``, ``self_check``, ``settings``);
        ``trained_gap`` defaults to the data module's ``transition_max`` recorded in the checkpoint (in the graph's
        metadata for ``.onnx``).
        """
        paths = [str(p) for p in path] if isinstance(path, (list, tuple)) else [str(path)]
        models, gaps = [], []
        for p in paths:
            if p.lower().endswith(".onnx"):
                from inbetweening.runtime.model import ModelError
                from inbetweening.runtime.onnx_backend import OnnxBackend

                if not Path(p).is_file():
                    raise ModelError(f"ckpt_path: {p} does not exist")
                try:
                    models.append(OnnxBackend(p, threads))
                except ModelError as e:
                    raise ModelError(f"ckpt_path: {e}") from None
                gaps.append(None)
            else:
                from inbetweening.predictor.checkpoint import load_predictor, read_checkpoint, trained_gap

                ckpt = read_checkpoint(p)
                models.append(load_predictor(p, device, ckpt=ckpt))
                gaps.append(trained_gap(ckpt) or None)
        gaps = kw.pop("trained_gap", gaps)
        if len(models) == 1:
            return cls(models[0], trained_gap=gaps[0] if isinstance(gaps, list) else gaps, **kw)
        return cls(models, trained_gap=gaps, names=paths, **kw)

    @property
    def device(self):
        """The first model's ``torch.device`` (``"cpu"`` for a model on ONNX Runtime)."""
        return self.predictor.device if self.predictor is not None else "cpu"

    @property
    def retargets(self) -> bool:
        """Whether the model's joints are the humanoid slots (:data:`~inbetweening.runtime.bone_map.SLOTS`), so a clip
        of another humanoid can be retargeted onto them (the shipped models' skeleton)."""
        from inbetweening.runtime.bone_map import SLOTS

        return set(self.skeleton.names) == set(SLOTS)

    @property
    def max_gap(self) -> int:
        return self.runtime.max_gap

    @property
    def segment(self) -> bool:
        return self.runtime.segment

    @property
    def foot_lock(self) -> bool:
        return self.runtime.foot_lock

    # ------------------------------------------------------------------ array level
    def fill_arrays(self, root, local_q, known_frames, *, max_gap: int | None = None, segment: bool | None = None,
                    foot_lock: bool | None = None, with_contacts: bool = False) -> tuple[np.ndarray, ...]:
        """Generate every frame not in ``known_frames``.

        Args:
            root: ``(F, 3)`` root positions; local_q: ``(F, J, 4)`` local rotations wxyz, in the model's skeleton and
                the project's frame.  Values of unknown frames are never read (they may be NaN).
            known_frames: sorted frame indices, at least 2, the first 0 and the last ``F - 1``.
            max_gap, segment, foot_lock: override the instance's settings (see the class docstring).
            with_contacts: also return the foot contact ``(F, J)`` in [0, 1]: the model's prediction on generated
                frames, the keyframes' own (the data's rule on the keys alone) on known ones; ``None`` when the
                representation has no contact channels.
        Returns:
            ``root (F, 3), local_q (F, J, 4)`` float64 (then ``contact`` with ``with_contacts``); known frames equal
            the input exactly.
        """
        return self.fill_many([(root, local_q, known_frames)], max_gap=max_gap, segment=segment, foot_lock=foot_lock,
                              with_contacts=with_contacts)[0]

    def fill_many(self, clips, *, max_gap: int | None = None, segment: bool | None = None, batch_size: int = 4,
                  foot_lock: bool | None = None, with_contacts: bool = False) -> list[tuple[np.ndarray, ...]]:
        """:meth:`fill_arrays` of many clips at once (:meth:`FillRuntime.fill_many`: the k-th gap of every clip in one
        forward pass per ``batch_size`` gaps of the same length); returns one ``(root, local_q)`` (with
        ``with_contacts``: ``(root, local_q, contact)``) per clip.  Every clip is checked before anything is
        generated."""
        checked = []
        for root, q, known in clips:
            n = np.shape(root)[0]
            known = check_keys(known, n, "known_frames")
            if known[0] != 0 or known[-1] != n - 1:
                raise InbetweenError(f"known_frames must start at frame 0 and end at frame {n - 1} (the whole array "
                                     f"is filled), got {known[0]}..{known[-1]}")
            checked.append((root, q, known))
        out = self.runtime.fill_many(checked, max_gap=max_gap, segment=segment, foot_lock=foot_lock,
                                     batch_size=batch_size)
        return [(f.root, f.local_q, f.contact) if with_contacts else (f.root, f.local_q) for f in out]

    # ------------------------------------------------------------------ BVH level
    def fill(self, bvh: BVH | str | Path, keyframes: list[int] | None = None, gap: int | None = None, *,
             max_gap: int | None = None, segment: bool | None = None, foot_lock: bool | None = None,
             self_check: bool | None = None, bone_map=None, partial=None) -> BVH:
        """In-between a BVH clip; returns a new :class:`~inbetweening.data.bvh.BVH` (write it with ``write_bvh``).

        Give exactly one of:

        * ``keyframes`` (form A): frame indices of ``bvh`` to keep (>= 2, increasing, any spacing).  Every other
          frame between the first and the last keyframe is generated; frames before the first and after the
          last keyframe are dropped, so the output has ``last - first + 1`` frames and input frame ``k`` is
          output frame ``k - first``.
        * ``gap`` (form B): every frame of ``bvh`` is a keyframe; ``gap`` frames are generated between each
          consecutive pair, so ``K`` input frames give ``K + (K - 1) * gap`` output frames.

        The output has the input's hierarchy, channel order and frame time; keyframe rows of ``motion`` are the
        input's rows, bit for bit; generated frames take non-root position channels from the nearest keyframe, and
        a folded ``joint_Root`` moves between its values at the surrounding keyframes (module docstring).  Gaps
        longer than ``max_gap`` are split with interpolated pseudo-keyframes unless ``segment=False`` (then
        :class:`InbetweenError`).  A clip of another humanoid is retargeted (module docstring; ``bone_map``: an
        override file's path or a dict ``rig bone -> slot`` for what detection gets wrong).  ``partial`` (form A
        only): partial keys, ``{frame of bvh: [bone names of bvh]}``: frames strictly between the first and the last
        keyframe where only these bones are keyed; they constrain those bones, the frame's other bones are generated
        (:mod:`inbetweening.runtime.partial`), and the keyed bones' rotations come back exactly.  Errors:
        :class:`InbetweenError` (keyframes, gap, a rig that cannot be mapped), ``BVHError`` (unreadable file).
        """
        return self.fill_detailed(bvh, keyframes, gap, max_gap=max_gap, segment=segment, foot_lock=foot_lock,
                                  self_check=self_check, bone_map=bone_map, partial=partial).bvh

    def fill_detailed(self, bvh: BVH | str | Path, keyframes: list[int] | None = None, gap: int | None = None, *,
                      max_gap: int | None = None, segment: bool | None = None,
                      foot_lock: bool | None = None, self_check: bool | None = None, bone_map=None,
                      partial=None) -> FillResult:
        """:meth:`fill` plus the arrays behind it (for rendering and inspection): a :class:`FillResult`."""
        if not isinstance(bvh, BVH):
            bvh = read_bvh(bvh)
        if (keyframes is None) == (gap is None):
            raise InbetweenError("give exactly one of keyframes (frames of the clip to keep) or gap "
                                 "(frames to generate between consecutive input frames)")
        n_in = bvh.num_frames
        part: dict[int, np.ndarray] = {}
        if keyframes is not None:  # the keys and partial keys checked once, in the file's frames and bones
            src = check_keys(keyframes, n_in, "keyframes")
            part, src = check_partial(partial, src, n_in, list(bvh.names), f"{bvh.source}'s hierarchy")
            out_pos = [k - src[0] for k in src]
        else:
            if isinstance(gap, bool) or not isinstance(gap, (int, np.integer)) or gap < 1:
                raise InbetweenError(f"gap must be an integer >= 1, got {gap!r}")
            if n_in < 2:
                raise InbetweenError(f"gap: the input must hold at least 2 keyframes, it has {n_in} frame(s)")
            src = list(range(n_in))
            out_pos = [i * (int(gap) + 1) for i in range(n_in)]
        kw = {"max_gap": max_gap, "segment": segment, "foot_lock": foot_lock, "self_check": self_check}
        if partial and gap is not None:
            raise InbetweenError("partial: partial keys are frames of the clip between its keyframes (form A, "
                                 "keyframes=[...]); with gap= every input frame is a whole key")
        if self.retargets:  # every character, the model's own skeleton the identity case of the retargeting
            return self._fill_character(bvh, src, out_pos, bone_map, {**kw, "partial": part})
        try:  # a model of another skeleton than the humanoid slots: its own skeleton only
            fold, root_in, q_in = clip_in_skeleton(bvh, self.skeleton)
        except DatasetError as e:
            raise InbetweenError(f"{e} (this model fills its own skeleton only; retargeting another character "
                                 "needs a model of the humanoid slots, such as the shipped ones)") from None
        if bvh.frame_time > 0 and not self.runtime.info.same_rate(1.0 / bvh.frame_time):
            warnings.warn(f"{bvh.source}: {1.0 / bvh.frame_time:.3g} fps, the model was trained at {self.fps:.3g} "
                          f"fps; gaps are counted in the file's frames", stacklevel=2)
        n_out = out_pos[-1] + 1
        root = np.full((n_out, 3), np.nan)
        q = np.full((n_out, self.skeleton.num_joints, 4), np.nan)
        root[out_pos], q[out_pos] = root_in[src], q_in[src]
        model_part = {}
        for t, mask in part.items():  # the file's bones -> the model's joints (a folded top joint: the hips)
            names = [self.skeleton.names[0] if j == 0 and fold else bvh.names[j] for j in np.flatnonzero(mask)]
            missing = [b for b in names if b not in self.skeleton.names]
            if missing:
                raise InbetweenError(f"partial: frame {t}: {', '.join(missing)} not among the model's joints")
            model_part[t - src[0]] = names
            mask = np.isin(self.skeleton.names, names)
            q[t - src[0], mask] = q_in[t, mask]
            if mask[0]:
                root[t - src[0]] = root_in[t]
        filled = self.runtime.fill(root, q, out_pos, file_frame=True, partial=model_part or None, **kw)
        out = self._to_bvh(bvh, fold, filled.root, filled.local_q, src, out_pos)
        _keep_partial_rows(out, bvh, part, src[0])
        convention = self.runtime.info.convention
        root, q = (filled.root, filled.local_q) if convention.is_project else convention.to_project(filled.root,
                                                                                                   filled.local_q)
        return FillResult(out, root, q, out_pos, self.skeleton, filled.pseudo_keyframes, filled.contact,
                          segments=filled.segments, checks=filled.checks)

    def _fill_character(self, bvh: BVH, src: list[int], out_pos: list[int], bone_map, kw) -> FillResult:
        """Another humanoid's clip: retargeted onto the model's skeleton, filled, retargeted back (module docstring)."""
        from inbetweening.runtime.retarget import Retarget

        bm = _bone_map(bvh, bone_map)
        lq_in, lp_in = bvh.local_rotations(), bvh.channel_positions()
        n_out = out_pos[-1] + 1
        lq = np.full((n_out, bvh.num_joints, 4), np.nan)
        lp = np.full((n_out, bvh.num_joints, 3), np.nan)
        lq[out_pos], lp[out_pos] = lq_in[src], lp_in[src]
        part = {}
        for t, mask in kw.pop("partial").items():
            lq[t - src[0], mask], lp[t - src[0], mask] = lq_in[t, mask], lp_in[t, mask]
            part[t - src[0]] = mask
        movers = [j for j, ch in enumerate(bvh.channels) if any(c.lower().endswith("position") for c in ch)]
        retarget = Retarget(bvh.skeleton(), self.skeleton, bm, reference=lq_in[src[0]], where=f"rig '{bvh.source}'",
                            poses=lq_in[src], ends=bvh.end_sites, translations=lp_in[src])
        fps = 1.0 / bvh.frame_time if bvh.frame_time > 0 else None
        out = self.runtime.fill_rig(retarget, lq, lp, out_pos, movers=movers, fps=fps, partial=part or None, **kw)
        clip = bvh.with_motion(out.local_q, out.local_p)
        clip.motion[out_pos] = bvh.motion[np.asarray(src)]
        _keep_partial_rows(clip, bvh, {src[0] + t: m for t, m in part.items()}, src[0])
        m = out.model
        span = np.arange(out_pos[-1] + 1)
        root, q = retarget.to_model(out.local_q[span], out.local_p[span])  # the character's fill, on the model's
        contact = m.contact if m.contact is not None and len(m.contact) == len(span) else None  # (not resampled)
        return FillResult(clip, root, q, out_pos, self.skeleton, m.pseudo_keyframes, contact, bm, m.segments, m.checks)

    @staticmethod
    def _to_bvh(bvh: BVH, fold: bool, root: np.ndarray, q: np.ndarray, src: list[int], out_pos: list[int]) -> BVH:
        """The output clip (``root``, ``q`` in the file's frame): generated frames written into the file's hierarchy
        (non-root position channels from the nearest keyframe; a folded top joint between the surrounding keyframes'
        values, :func:`~inbetweening.data.clips.motion_in_file`), the keyframes' rows copied unchanged."""
        t = np.arange(root.shape[0])
        keys = np.asarray(out_pos)
        src = np.asarray(src)
        nearest = np.abs(t[:, None] - keys[None, :]).argmin(axis=1)  # ties -> the earlier keyframe
        before = np.clip(np.searchsorted(keys, t, side="right") - 1, 0, len(keys) - 1)  # the key at or before t
        after = np.minimum(before + 1, len(keys) - 1)
        span = keys[after] - keys[before]
        w = np.where(span > 0, (t - keys[before]) / np.maximum(span, 1), 0.0)
        out = motion_in_file(bvh, fold, root, q, src[nearest], top_from=(src[before], src[after], w))
        out.motion[keys] = bvh.motion[src]
        return out
