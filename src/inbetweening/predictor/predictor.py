"""The predictor: one object from (root, local quaternion) windows to predicted transitions.

It owns the skeleton, the training statistics, the feature representation, the mask, the centring mode, the
context length, the forward axis and the network, and is the only path from windows to predictions used by
training, validation/test, ``eval.py``, the TensorBoard figure, the animator tool and export.  It is built
from plain values (:meth:`Predictor.from_hparams` / :meth:`Predictor.hparams`), so a checkpoint's
hyper-parameters and state dict restore it without Hydra or Lightning
(:func:`inbetweening.predictor.checkpoint.load_predictor`).

Shapes: windows ``root (B, T, 3)``, ``local_q (B, T, J, 4)``; features ``(B, T, J, F)``; ``known (B, T, J)`` bool.
"""
from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import torch
from torch import nn

from inbetweening.data.contacts import FootContact
from inbetweening.data.convention import FileConvention
from inbetweening.geometry import canonical
from inbetweening.geometry.interp import lerp, slerp
from inbetweening.geometry.quaternion import qrot
from inbetweening.geometry.skeleton import Skeleton
from inbetweening.predictor.masks import MASK_NAMES, apply_mask, gap_lengths, transition_known
from inbetweening.predictor.settings import PredictorSettings
from inbetweening.representation import DEFAULT_REPRESENTATION, build_representation, representation_class

CENTRES = ("known", "last", "window")
LEGACY_CENTRE = "window"  # what checkpoints made before the ``centre`` option record (see Predictor.canonical_frame)
_DEFAULT = PredictorSettings.defaults()  # the constructor's defaults are the persisted settings' (one owner)


def check_centre(centre: str) -> str:
    """``centre`` itself, or ValueError naming the allowed modes."""
    if centre not in CENTRES:
        raise ValueError(f"centre must be one of {list(CENTRES)}, got {centre!r}")
    return centre


def check_blend(blend) -> tuple[float, ...] | None:
    """``blend`` as a tuple of floats (``None`` stays ``None``), or ValueError naming ``blend``: a non-empty list of
    numbers in [0, 1], one per gap length 1, 2, ... (:meth:`Predictor.blend_weights`)."""
    if blend is None:
        return None
    try:
        w = tuple(float(v) for v in blend)
    except (TypeError, ValueError):
        raise ValueError(f"blend: must be a list of weights in [0, 1] (one per gap length), got {blend!r}") from None
    if not w or not all(0.0 <= v <= 1.0 for v in w):  # (NaN fails the comparison too)
        raise ValueError(f"blend: must be a non-empty list of weights in [0, 1] (one per gap length), got {list(w)}")
    return w


def upgrade_hparams(hp: dict) -> dict:
    """Hyper-parameters of an older checkpoint in today's form: a missing ``centre`` is ``window`` (what those
    checkpoints record), a missing ``representation`` the original one.  Returns a new dict."""
    hp = dict(hp)
    hp.setdefault("centre", LEGACY_CENTRE)
    hp.setdefault("representation", DEFAULT_REPRESENTATION)
    return hp


class WindowPrediction(NamedTuple):
    """What :meth:`Predictor.predict_windows` returns.  ``root``/``local_q`` and ``interp_root``/``interp_q``: the
    prediction and the interpolation in the input's frame, float64, known values copied bit-exactly from the input;
    ``feats``/``pred``: the input's and the predicted features in the canonical frame (unknown input values NaN);
    ``frame``: that frame."""

    root: torch.Tensor
    local_q: torch.Tensor
    interp_root: torch.Tensor
    interp_q: torch.Tensor
    feats: torch.Tensor
    pred: torch.Tensor
    frame: tuple  # (centre (B, 1, 3), rotation (B, 1, 4)): the canonical frame (Predictor.canonical_frame)


class Predictor(nn.Module):
    """Windows -> canonical frame -> features -> mask -> network -> predicted windows.

    Args:
        net: the network, ``net(x, known, interp) -> (B, T, J, F)`` (:mod:`inbetweening.models`).
        skeleton: the training data's skeleton.
        pos_mean, pos_std: training statistics of global positions, ``J*3`` floats each.
        mask: ``zero`` | ``lerp`` | ``joints`` (what the network sees in place of unknown values).
        centre: where the canonical frame's origin is (:meth:`canonical_frame`): ``known`` (the known frames' mean
            root XZ), ``last`` (the last context frame's root XZ) or ``window`` (checkpoints made before the option:
            the same as ``known``); required.
        n_past: context frames before a transition.
        forward_axis: the root's forward direction in its local frame (the canonical frame faces it to +X).
        representation: name of the feature representation (:mod:`inbetweening.representation`).
        model: the network's config (recorded, for :meth:`hparams`); fps, train_window, dataset: data conventions.
        contact: the training data's feet and foot-contact rule (:class:`~inbetweening.data.contacts.FootContact`).
        convention: the training files' up axis and length unit (:class:`~inbetweening.data.convention.
            FileConvention`): the tools turn a user's file into the model's frame (Y up, cm) and back with it.
        blend: the do-no-harm blend, one weight in [0, 1] per gap length ``1, 2, ...`` (longer gaps take the last):
            every prediction is ``interpolation + weight x (network - interpolation)`` (positions linearly,
            rotations by slerp), the weight chosen by the gap the frame lies in; fitted after training on held-out
            windows (:func:`inbetweening.predictor.calibration.fit_blend`); ``None``: the network as it is.
    """

    def __init__(self, net: nn.Module, skeleton: Skeleton, pos_mean, pos_std, *, mask: str, centre: str,
                 n_past: int = _DEFAULT["n_past"], forward_axis: Sequence[float] = _DEFAULT["forward_axis"],
                 representation: str = _DEFAULT["representation"], model: dict | None = None,
                 fps: float = _DEFAULT["fps"], train_window: int = _DEFAULT["train_window"],
                 dataset: str = _DEFAULT["dataset"], contact: dict | None = None, convention: dict | None = None,
                 blend: Sequence[float] | None = None):
        super().__init__()
        if mask not in MASK_NAMES:
            raise ValueError(f"mask must be one of {list(MASK_NAMES)}, got {mask!r}")
        self.net = net
        self.skeleton = skeleton
        self.mean = np.asarray(pos_mean, dtype=np.float64)
        self.std = np.asarray(pos_std, dtype=np.float64)
        self.mask_name = mask
        self.centre = check_centre(centre)
        self.n_past = int(n_past)
        self.forward_axis = tuple(float(a) for a in forward_axis)
        self.model_cfg = dict(model or {})
        self.fps, self.train_window, self.dataset = float(fps), int(train_window), str(dataset)
        self.contact = FootContact.from_dict(contact)
        self.convention = FileConvention.from_dict(convention)
        self.blend = check_blend(blend)
        self.representation = build_representation(representation, skeleton, self.mean, self.std,
                                                   contact=self.contact, fps=self.fps)

    # ------------------------------------------------------------------ plain values
    @classmethod
    def from_hparams(cls, hp: dict) -> Predictor:
        """Build the predictor (and a freshly initialised network) from plain values (the
        :class:`~inbetweening.predictor.settings.PredictorSettings` among ``hp``; ``model``, ``skeleton``,
        ``pos_mean``, ``pos_std``, ``centre`` required)."""
        if "centre" not in hp:
            raise ValueError(f"centre: required, one of {list(CENTRES)} (older checkpoints: see upgrade_hparams)")
        return cls.from_settings(PredictorSettings.from_hparams(hp))

    @classmethod
    def from_settings(cls, settings: PredictorSettings) -> Predictor:
        """The predictor of ``settings``, with a freshly initialised network."""
        from inbetweening.models import build_network

        skeleton = Skeleton.from_dict(settings.skeleton)
        layout = representation_class(settings.representation).layout()
        return cls(build_network(settings.model, skeleton, layout), skeleton, settings.pos_mean, settings.pos_std,
                   **settings.predictor_kwargs())

    def settings(self) -> PredictorSettings:
        """This predictor's persisted settings, as plain values."""
        return PredictorSettings(
            model=dict(self.model_cfg), skeleton=self.skeleton.to_dict(), pos_mean=self.mean.tolist(),
            pos_std=self.std.tolist(), mask=self.mask_name, centre=self.centre, n_past=self.n_past,
            forward_axis=list(self.forward_axis), representation=self.representation.name, fps=self.fps,
            train_window=self.train_window, dataset=self.dataset, contact=self.contact.to_dict(),
            convention=self.convention.to_dict(), blend=None if self.blend is None else list(self.blend))

    def hparams(self) -> dict:
        """Plain values that rebuild this predictor with :meth:`from_hparams` (weights: ``state_dict()``)."""
        return self.settings().hparams()

    @property
    def device(self) -> torch.device:
        return next((p.device for p in self.net.parameters()), torch.device("cpu"))

    @property
    def max_frames(self) -> int | None:
        """Longest window the network accepts (``None``: any)."""
        m = getattr(self.net, "max_frames", None)
        return int(m) if m else None

    # ------------------------------------------------------------------ the one centring stage
    def canonical_frame(self, root, local_q, known):
        """The canonical frame of windows, decided by their known values only: ``(centre (B, 1, 3), rotation
        (B, 1, 4))``, numpy for numpy windows, torch otherwise (float64).

        The rotation turns the root's ``forward_axis`` at the last context frame (the last frame before the first
        frame with an unknown root value; the first known frame when the window starts unknown) to +X about +Y; the
        centre is the known frames' mean root XZ (``centre="known"``, and ``"window"``) or the root XZ at that frame
        (``"last"``), Y = 0.  Done once, in world space, for every caller (training batches, the benchmark's
        windows, the animator's): a yaw and a translation are rigid motions, so the same step serves every
        representation (a feature-space shift could only translate, and only z-scored positions).  Unknown values
        are never read (NaN is fine).  ``root (B, T, 3)``, ``local_q (B, T, J, 4)``, ``known (B, T, J)`` bool."""
        is_np = not isinstance(root, torch.Tensor)
        k = np.asarray(known.cpu() if isinstance(known, torch.Tensor) else known)[..., 0] if is_np else known[..., 0]
        t = k.shape[1]
        if is_np:
            idx = np.arange(t)[None, :]
            first_unknown = np.where(~k, idx, t).min(axis=1)
            first_known = np.where(k, idx, t).min(axis=1)
            frame = np.minimum(np.where(first_unknown > 0, first_unknown - 1, first_known), t - 1)
        else:
            idx = torch.arange(t, device=k.device)[None, :]
            first_unknown = torch.where(~k, idx, t).min(dim=1).values
            first_known = torch.where(k, idx, t).min(dim=1).values
            frame = torch.where(first_unknown > 0, first_unknown - 1, first_known).clamp(max=t - 1)
        return canonical.canonical_frame(root, local_q, self.forward_axis, frame, k,
                                         centre_at_frame=self.centre == "last")

    def canonical_features(self, root, local_q, known: torch.Tensor):
        """Windows (any frame, numpy or torch) -> ``(features (B, T, J, F) in the canonical frame on the network's
        device, (centre, rotation))``."""
        on_cpu = all(not isinstance(a, torch.Tensor) or a.device.type == "cpu" for a in (root, local_q))
        if on_cpu:  # CPU tensors take the numpy path: the same numbers, about twice as fast (batched numpy FK)
            root, local_q = (a.numpy() if isinstance(a, torch.Tensor) else a for a in (root, local_q))
        if isinstance(root, torch.Tensor) or isinstance(local_q, torch.Tensor):
            root = torch.as_tensor(root, dtype=torch.float64)
            local_q = torch.as_tensor(local_q, dtype=torch.float64, device=root.device)
            known = known.to(root.device)
        else:
            root, local_q = np.asarray(root, dtype=np.float64), np.asarray(local_q, dtype=np.float64)
        frame = self.canonical_frame(root, local_q, known)
        croot, cq = canonical.canonicalise(root, local_q, *frame)
        return self.encode(croot, cq, device=self.device), frame

    # ------------------------------------------------------------------ features
    def encode(self, root, local_q, dtype=torch.float32, device=None) -> torch.Tensor:
        """``root (..., T, 3), local_q (..., T, J, 4)`` (numpy or torch) -> features ``(..., T, J, F)``.

        FK runs in float64, the result is cast to ``dtype`` on ``device`` (default: the network's).  NaN frames
        stay NaN (nothing downstream reads unknown values)."""
        return self.representation.encode_windows(root, local_q, dtype, device or self.device)

    def decode(self, feats: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Features -> ``root (..., T, 3), local_q (..., T, J, 4)`` in float64 (unit quaternions)."""
        return self.representation.decode(feats.double())

    def global_positions(self, feats: torch.Tensor) -> torch.Tensor:
        """Global joint positions carried by the features, float64.  ``(..., J, F) -> (..., J, 3)``."""
        return self.representation.global_positions(feats.double())

    def transition_known(self, batch: int, frames: int, n, device=None) -> torch.Tensor:
        """The in-betweening mask ``(B, T, J)``: ``n_past`` context frames, ``n`` unknown, then known frames."""
        return transition_known(batch, frames, self.skeleton.num_joints, self.n_past, n, device=device)

    # ------------------------------------------------------------------ forward / predict
    def forward(self, root, local_q, known: torch.Tensor, net=None, with_raw: bool = False):
        """Training forward (with gradients): ``(pred, interp, target)`` features in the canonical frame, ``target``
        being the input's (the loss compares the two).  ``net``: a callable run in place of ``self.net`` (its compiled
        forward, see :meth:`InbetweenModule.compile_network`).  ``with_raw``: ``(pred, interp, target, raw)``, ``raw``
        being the network's output before the known values are copied back (keyframe-consistency loss)."""
        net = net or self.net
        if with_raw:
            net = functools.partial(net, with_raw=True)
        feats, _ = self.canonical_features(root, local_q, known)
        out, interp = self.network_forward(feats, known.to(feats.device), net, blend=False)  # the network is trained
        return (out[0], interp, feats, out[1]) if with_raw else (out, interp, feats)  # as it is, never blended

    def network_forward(self, feats: torch.Tensor, known: torch.Tensor, net=None, blend: bool = True):
        """Features in the canonical frame -> ``(prediction, interpolation)``: the mask fills the unknown values
        (never read: NaN is fine), the network predicts them, the do-no-harm blend (``blend``, when the predictor
        has one) weighs the prediction against the interpolation; known values come back as given."""
        x, interp = apply_mask(self.mask_name, feats, known, self.representation)
        out = (net or self.net)(x, known, interp)
        if blend and self.blend is not None:
            out = self.blended(out, interp, known)
        return out, interp

    # ------------------------------------------------------------------ the do-no-harm blend
    def blend_weights(self, known: torch.Tensor) -> torch.Tensor:
        """``known (B, T, J)`` -> the blend's weight of each value ``(B, T, J)`` float32: ``blend[L - 1]`` for a value
        in a gap of ``L`` frames (:func:`~inbetweening.predictor.masks.gap_lengths`; gaps longer than the list take
        its last weight), 1 for known values; all 1 without a blend."""
        if self.blend is None:
            return torch.ones(known.shape, device=known.device)
        table = torch.tensor(self.blend, dtype=torch.float32, device=known.device)
        gaps = gap_lengths(known).clamp(1, len(self.blend)) - 1
        return torch.where(known, 1.0, table[gaps])

    def blended(self, pred: torch.Tensor, interp: torch.Tensor, known: torch.Tensor, weights=None) -> torch.Tensor:
        """``interp + w (pred - interp)`` on the position channels and ``slerp(interp, pred, w)`` on the rotation
        channels of features ``(B, T, J, F)``; other channels (contacts) and known values as in ``pred``.
        ``weights``: ``(B, T, J)`` or a number, default :meth:`blend_weights` of ``known``."""
        rep = self.representation
        w = self.blend_weights(known) if weights is None else torch.as_tensor(weights, dtype=pred.dtype,
                                                                              device=pred.device)
        w = w.expand(known.shape).to(pred.dtype)
        out = pred.clone()
        out[..., rep.pos] = lerp(interp[..., rep.pos], pred[..., rep.pos], w[..., None])
        out[..., rep.quat] = slerp(interp[..., rep.quat], pred[..., rep.quat], w)
        return torch.where(known[..., None], pred, out)

    @torch.no_grad()
    def predict_windows(self, root, local_q, known: torch.Tensor) -> WindowPrediction:
        """Predict the unknown values of windows given in any frame (numpy or torch): a :class:`WindowPrediction`, the
        prediction and the interpolation back in the input's frame with the known values copied bit-exactly;
        unknown input values are never read (they may be NaN)."""
        feats, frame = self.canonical_features(root, local_q, known)
        known = known.to(feats.device)
        pred, interp = self.network_forward(feats, known)
        frame = tuple(torch.as_tensor(f, device=feats.device) for f in frame)
        root_in, q_in = (a.to(feats.device, torch.float64) if isinstance(a, torch.Tensor) else  # (numpy: a copy, so
                         torch.tensor(np.asarray(a), dtype=torch.float64, device=feats.device)  # read-only arrays of the
                         for a in (root, local_q))  # dataset cache are fine)
        outs = []
        for f in (pred, interp):
            r, q = canonical.uncanonicalise(*self.decode(f), *frame)
            outs += [torch.where(known[..., :1], root_in, r), torch.where(known[..., None], q_in, q)]
        return WindowPrediction(*outs, feats, pred, frame)

    def world_positions(self, out: WindowPrediction) -> torch.Tensor:
        """The global joint positions the predicted features carry (their position channels, not FK), in the input's
        frame, float64.  ``-> (B, T, J, 3)``."""
        centre, rot = out.frame
        return qrot(rot[:, :, None], self.global_positions(out.pred)) + centre[:, :, None]

    def predict_transitions(self, root, local_q, n: int, device=None, batch_size: int = 256):
        """The benchmark's predictor contract.

        ``root (B, n_past+n+1, 3), local_q (B, n_past+n+1, J, 4)`` (transition frames may be NaN) ->
        predicted ``root (B, n, 3)``, ``local_q (B, n, J, 4)`` as float64 numpy.
        """
        sl = slice(self.n_past, self.n_past + n)
        outs_r, outs_q = [], []
        for s in range(0, len(root), batch_size):
            r, q = root[s : s + batch_size], local_q[s : s + batch_size]
            known = self.transition_known(len(r), np.shape(r)[1], n, device=device or self.device)
            out = self.predict_windows(r, q, known)
            outs_r.append(out.root[:, sl].cpu().numpy())
            outs_q.append(out.local_q[:, sl].cpu().numpy())
        return np.concatenate(outs_r), np.concatenate(outs_q)

    # ------------------------------------------------------------------ export
    def example_inputs(self, batch: int, gap: int, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Random network inputs ``(x, known, interp)`` for ``batch`` windows with a ``gap``-frame transition (CPU)."""
        g = torch.Generator().manual_seed(seed)
        j, t, rep = self.skeleton.num_joints, self.n_past + gap + 1, self.representation
        feats = torch.zeros(batch, t, j, rep.features)
        feats[..., rep.pos] = torch.randn(batch, t, j, rep.pos.stop - rep.pos.start, generator=g)
        quat = torch.randn(batch, t, j, rep.quat.stop - rep.quat.start, generator=g)
        feats[..., rep.quat] = quat / quat.norm(dim=-1, keepdim=True)
        known = transition_known(batch, t, j, self.n_past, gap)
        x, interp = apply_mask(self.mask_name, feats, known, rep)
        return x, known, interp

    def metadata(self, inputs: Sequence[str] = ("x", "known", "interp")) -> dict[str, str]:
        """What a consumer of the bare network needs to prepare its inputs, one JSON string per key
        (:meth:`~inbetweening.predictor.settings.PredictorSettings.metadata`)."""
        return self.settings().metadata(self.max_frames, self.representation.metadata(), inputs)
