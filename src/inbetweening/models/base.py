"""Common contract of every in-betweening model of the zoo, written once.

A model subclasses :class:`InbetweenModel` and implements only its network:

* ``network(x, known, interp) -> raw (B, T, J, F)``;
* ``check_settings(checks)`` (classmethod): rules of its own constructor settings (ValueError naming the setting);
* ``OUTPUT_HEAD``: the parameter(s) / module(s) zeroed when ``residual_to_interpolation`` (so it starts at the
  interpolation);
* ``TINY``: small sizes for tests (every contract test builds every registered model with them).

Everything else is here: the common constructor arguments and their defaults (:meth:`InbetweenModel.__init__`, the
one place they are written: a subclass takes them as ``**common`` and passes them on, stating only a default of its
own, e.g. ``dropout: float = 0.1``) and their checks, running the checks of every setting before anything is built
(the same checks validate a config: :meth:`InbetweenModel.check_config`), the output head's zero initialisation, and
``forward`` = input checks -> ``network`` -> ``interp + raw`` (residual) -> :meth:`finalize`.
"""
from __future__ import annotations

import inspect
import numbers
from collections.abc import Iterable, Mapping
from typing import Any, ClassVar

import torch
from torch import Tensor, nn

from inbetweening.geometry.quaternion import quat_to_rot6d
from inbetweening.representation import DEFAULT_REPRESENTATION, representation_class

from .blocks import ACTIVATIONS, check_length

# the feature layout is the representation's (inbetweening.representation); a network is built with its plain
# values (``layout``), by default the default representation's
DEFAULT_LAYOUT: dict = representation_class(DEFAULT_REPRESENTATION).layout()
FEATURE_DIM = DEFAULT_LAYOUT["features"]
SKELETON_ARGS = ("num_joints", "adjacency", "layout")  # given by the skeleton and the representation, not the config
VELOCITY_SCALE = 10.0  # derived velocity inputs: frame-to-frame change of the z-scored positions x 10 (about unit
# scale on Bandai-Namco-2 at 30 fps)


def rot6d_input(x: Tensor, pos: slice, quat: slice) -> Tensor:
    """6-D rotation of each joint's (masked) quaternion.  ``(B, T, J, F) -> (B, T, J, 6)``."""
    return quat_to_rot6d(x[..., quat])


def velocity_input(x: Tensor, pos: slice, quat: slice) -> Tensor:
    """Frame-to-frame change of the (masked) positions, 0 on the first frame, x :data:`VELOCITY_SCALE`.
    ``(B, T, J, F) -> (B, T, J, 3)``.  Computed from the masked input, so unknown frames never leak into it."""
    p = x[..., pos]
    return torch.cat([torch.zeros_like(p[:, :1]), p[:, 1:] - p[:, :-1]], dim=1) * VELOCITY_SCALE


# extra input channels a model may be given (``inputs`` setting): name -> (channels per joint, function of the masked
# input).  They are derived from the masked input features inside ``forward``: nothing changes outside the network
INPUTS: dict[str, tuple[int, Any]] = {"rot6d": (6, rot6d_input), "velocity": (3, velocity_input)}


class Checks:
    """Checks of named settings ``values``; the first failure raises ``ValueError("{prefix}{key}: ...")``.

    ``prefix`` is ``""`` in a constructor (the class name is put in front) and ``"model."`` for a config, so the
    message names the key the user typed; settings mentioned in a message carry the prefix too.
    """

    def __init__(self, values: Mapping[str, Any], prefix: str = ""):
        self.values, self.prefix = values, prefix

    def fail(self, key: str, detail: str) -> None:
        raise ValueError(f"{self.prefix}{key}: {detail}")

    def integer(self, *keys: str, minimum: int = 1, optional: bool = False) -> None:
        """Each setting is an integer ``>= minimum`` (``None`` allowed when ``optional``: a derived default)."""
        for k in keys:
            v = self.values[k]
            if v is None and optional:
                continue
            if isinstance(v, bool) or not isinstance(v, numbers.Integral) or v < minimum:
                self.fail(k, f"must be an integer >= {minimum}, got {v!r}")

    def divides(self, key: str, total: str) -> None:
        """Setting ``key`` divides setting ``total`` (both already checked as positive integers)."""
        v, t = self.values[key], self.values[total]
        if t % v:
            self.fail(key, f"{v} must divide {self.prefix}{total}={t}")

    def one_of(self, key: str, choices: Iterable[str]) -> None:
        choices = list(choices)
        if self.values[key] not in choices:
            self.fail(key, f"must be one of {choices}, got {self.values[key]!r}")

    def fraction(self, key: str) -> None:
        """``0 <= value < 1`` (a dropout probability)."""
        v = self.values[key]
        if isinstance(v, bool) or not isinstance(v, numbers.Real) or not 0.0 <= v < 1.0:
            self.fail(key, f"must be in [0, 1), got {v}")

    def activation(self, key: str = "activation") -> None:
        self.one_of(key, sorted(ACTIVATIONS))

    def names(self, key: str, choices: Iterable[str]) -> None:
        """A list of distinct names, each one of ``choices`` (empty allowed)."""
        v, choices = self.values[key], list(choices)
        if isinstance(v, str) or not isinstance(v, Iterable):
            self.fail(key, f"must be a list of names from {choices}, got {v!r}")
        v = list(v)
        bad = [n for n in v if n not in choices]
        if bad:
            self.fail(key, f"unknown input(s) {bad}; choose from {choices}")
        if len(set(v)) != len(v):
            self.fail(key, f"names must be distinct, got {v}")


def adjacency_tensor(adjacency: Any, num_joints: int) -> Tensor:
    """``J x J`` nested list -> float32 ``(J, J)``; ValueError naming ``adjacency`` unless finite and ``J x J``."""
    try:
        adj = torch.as_tensor(adjacency, dtype=torch.float32)
    except (TypeError, ValueError) as e:
        raise ValueError(f"adjacency: must be a J x J nested list of numbers ({e})") from e
    if tuple(adj.shape) != (num_joints, num_joints):
        raise ValueError(f"adjacency: must have shape ({num_joints}, {num_joints}), got {tuple(adj.shape)}")
    if not bool(torch.isfinite(adj).all()):
        raise ValueError("adjacency: must be finite")
    return adj


def _named_parameters(init) -> dict[str, Any]:
    """A constructor's named arguments (name -> default, ``inspect.Parameter.empty`` when required), ``self`` left
    out."""
    params = inspect.signature(init).parameters
    return {k: p.default for k, p in params.items() if k != "self"
            and p.kind in (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)}


class _Contract(type):
    """Metaclass of the zoo: ``Model(...)`` checks every setting before the constructor runs (ValueError
    ``"Model: key: ..."``), then zeroes the output head when ``residual_to_interpolation``."""

    def __call__(cls, *args: Any, **kwargs: Any):
        signature = inspect.signature(cls.__init__)
        bound = signature.bind(None, *args, **kwargs)  # TypeError for unknown arguments, as a plain constructor
        bound.apply_defaults()
        known = {*cls.settings(), *SKELETON_ARGS}
        values = {}
        for k, v in list(bound.arguments.items())[1:]:
            if signature.parameters[k].kind is not inspect.Parameter.VAR_KEYWORD:
                values[k] = v
                continue
            unknown = sorted(set(v) - known)  # the common arguments arrive as **common
            if unknown and not cls.accepts_any_setting():
                raise TypeError(f"{cls.__name__}.__init__() got an unexpected keyword argument {unknown[0]!r}")
            values.update({n: x for n, x in v.items() if n in known})
        try:
            Checks({"num_joints": values["num_joints"]}).integer("num_joints")
            if values.get("adjacency") is not None:  # models that do not use it still check it (skeleton mismatch)
                adjacency_tensor(values["adjacency"], values["num_joints"])
            cls.check_config({k: v for k, v in values.items() if k not in SKELETON_ARGS})
        except ValueError as e:
            raise ValueError(f"{cls.__name__}: {e}") from None
        model = super().__call__(*args, **kwargs)
        model._init_output_head()
        return model


class InbetweenModel(nn.Module, metaclass=_Contract):
    """Base class: ``forward(x, known, interp=None) -> (B, T, J, F)``.

    * ``x``: ``(B, T, J, F)`` masked input features (unknown values zeroed or interpolated by the data pipeline).
    * ``known``: ``(B, T, J)`` bool, ``True`` where the value is given (keyframes / context).
    * ``interp``: ``(B, T, J, F)`` or ``None``: interpolation of the unknown frames (for residual prediction).

    Known values pass through bit-identically and predicted quaternions have unit norm (:meth:`finalize`).

    Common constructor arguments (every subclass takes them as ``**common`` and passes them to ``super().__init__``;
    their defaults are written here only, and ``conf/model/*.yaml`` restates them with the same values, which
    tests/test_models_base.py checks): ``num_joints`` (``J``), ``adjacency`` (``J x J`` joint relation matrix, checked
    even by models that do not use it), ``feature_dim`` (``F >= 7``: pos xyz + quaternion wxyz), ``max_frames``
    (longest window ``T``), ``residual_to_interpolation`` (predict ``interp + network(...)`` when ``interp`` is
    given; output head initialised to 0), ``dropout``, ``layout`` (the representation's feature layout,
    :meth:`inbetweening.representation.base.Representation.layout`: which channels are positions and rotations;
    given by the predictor, default the default representation's), ``inputs`` (extra input channels derived from
    ``x``, names of :data:`INPUTS`: the network reads ``input_dim = F + extras`` channels per joint and still writes
    ``F``), ``gate`` (a learned weight in [0, 1] per joint and frame on the correction; needs
    ``residual_to_interpolation``).
    """

    trainable: ClassVar[bool] = True  # baselines without parameters: False
    ignores_unknown_settings: ClassVar[bool] = False  # baselines: True (a sweep's architecture settings are ignored)
    COMMON_SETTINGS: ClassVar[tuple[str, ...] | None] = None  # the common arguments it takes (None: all of them)
    length_limited: ClassVar[bool] = True  # forward raises ValueError when T > max_frames
    quat_eps: ClassVar[float] = 1e-8
    OUTPUT_HEAD: ClassVar[tuple[str, ...]] = ()  # names of parameters / submodules zeroed when residual
    TINY: ClassVar[dict[str, Any]] = {}  # small settings for tests

    def __init__(
        self,
        num_joints: int,
        adjacency: list[list[float]] | None,
        *,
        feature_dim: int = FEATURE_DIM,
        max_frames: int = 128,
        residual_to_interpolation: bool = True,
        dropout: float = 0.0,
        inputs: Iterable[str] = (),
        layout: Mapping[str, Any] | None = None,
        gate: bool = False,
    ):
        super().__init__()
        layout = dict(layout or DEFAULT_LAYOUT)
        if int(layout["features"]) != feature_dim:
            raise ValueError(f"feature_dim: {feature_dim} differs from the representation's {layout['features']} channels")
        self.pos, self.quat = slice(*layout["position"]), slice(*layout["rotation"])
        self.num_joints, self.feature_dim, self.max_frames = num_joints, feature_dim, max_frames
        self.dropout = dropout
        self.residual_to_interpolation = bool(residual_to_interpolation)
        self.gate = bool(gate)
        self.output_dim = feature_dim + (1 if self.gate else 0)  # the network writes F channels, and the gate's
        self.inputs = tuple(inputs or ())
        self.input_dim = feature_dim + sum(INPUTS[n][0] for n in self.inputs)

    # ------------------------------------------------------------------ settings
    @classmethod
    def common_settings(cls) -> dict[str, Any]:
        """The common constructor arguments and their defaults (:meth:`__init__`'s keyword arguments)."""
        return {k: v for k, v in _named_parameters(InbetweenModel.__init__).items()
                if k not in ("num_joints", "adjacency")}

    @classmethod
    def settings(cls) -> dict[str, Any]:
        """Constructor settings a config may give (name -> default), i.e. all but ``num_joints`` / ``adjacency`` /
        ``layout``: the common ones it takes (:attr:`COMMON_SETTINGS`), then its own (a default of its own wins)."""
        common = {k: v for k, v in cls.common_settings().items()
                  if cls.COMMON_SETTINGS is None or k in cls.COMMON_SETTINGS}
        own = _named_parameters(cls.__init__) if cls.__init__ is not InbetweenModel.__init__ else {}
        return {k: v for k, v in {**common, **own}.items() if k not in SKELETON_ARGS}

    @classmethod
    def accepts_any_setting(cls) -> bool:
        """True if the constructor ignores settings it does not know (baselines ignore a sweep's architecture
        settings)."""
        return cls.ignores_unknown_settings

    @classmethod
    def check_config(cls, settings: Mapping[str, Any], prefix: str = "") -> None:
        """ValueError ``"{prefix}{key}: ..."`` for the first invalid setting; missing settings take the defaults.
        Used by the constructor and by the config validation (``prefix="model."``)."""
        checks = Checks({**cls.settings(), **settings}, prefix)
        checks.integer("feature_dim", minimum=FEATURE_DIM)
        checks.integer("max_frames")
        checks.fraction("dropout")
        gated = "gate" in cls.settings() and checks.values.get("gate")  # baselines ignore an experiment's gate
        if gated and not checks.values.get("residual_to_interpolation"):
            raise ValueError(f"{prefix}gate: the gate weighs the network's correction to the interpolation; it needs "
                             f"{prefix}residual_to_interpolation=true")
        if "inputs" in checks.values:
            checks.names("inputs", INPUTS)
        cls.check_settings(checks)

    @classmethod
    def check_settings(cls, checks: Checks) -> None:
        """The subclass's own rules, on ``checks.values`` (every constructor setting, defaults filled in)."""

    # ------------------------------------------------------------------ output head
    def output_head(self) -> list[nn.Parameter]:
        """The parameters named by ``OUTPUT_HEAD`` (a parameter name, or a submodule: all its parameters)."""
        named = dict(self.named_parameters())
        params = [p for k, p in named.items() if any(k == h or k.startswith(h + ".") for h in self.OUTPUT_HEAD)]
        if self.trainable and not params:
            raise TypeError(f"{type(self).__name__}.OUTPUT_HEAD {self.OUTPUT_HEAD} names no parameter")
        return params

    def init_output_head(self) -> None:
        """Initial values of the output head when not residual (default: as its layers built it)."""

    def _init_output_head(self) -> None:
        if self.residual_to_interpolation:  # start from the interpolation
            with torch.no_grad():
                for p in self.output_head():
                    p.zero_()
        else:
            self.init_output_head()

    # ------------------------------------------------------------------ forward
    def network(self, x: Tensor, known: Tensor, interp: Tensor | None) -> Tensor:  # pragma: no cover
        """``x (B, T, J, input_dim), known (B, T, J) bool, interp (B, T, J, F) | None -> raw (B, T, J, output_dim)``
        (``input_dim == F`` unless the model was given ``inputs``: :meth:`network_input`)."""
        raise NotImplementedError

    def check_input(self, x: Tensor, known: Tensor, interp: Tensor | None) -> None:
        """ValueError unless ``x`` is ``(B, T, J, F)``, ``known`` ``(B, T, J)``, ``interp`` ``None`` or like ``x``,
        and ``T <= max_frames`` (skipped while tracing / compiling, where shapes are symbolic)."""
        if torch.jit.is_tracing() or torch.compiler.is_compiling():
            return
        name, j, f = type(self).__name__, self.num_joints, self.feature_dim
        if x.dim() != 4 or x.shape[-2] != j or x.shape[-1] != f:
            raise ValueError(f"{name}: x must be (B, T, {j}, {f}), got {tuple(x.shape)}")
        if tuple(known.shape) != tuple(x.shape[:3]):
            raise ValueError(f"{name}: known must be (B, T, J) = {tuple(x.shape[:3])}, got {tuple(known.shape)}")
        if interp is not None and tuple(interp.shape) != tuple(x.shape):
            raise ValueError(f"{name}: interp must have the shape of x {tuple(x.shape)}, got {tuple(interp.shape)}")
        if self.length_limited:
            check_length(x.shape[1], self.max_frames)

    def network_input(self, x: Tensor) -> Tensor:
        """``x`` followed by the derived ``inputs`` channels.  ``(B, T, J, F) -> (B, T, J, input_dim)``."""
        if not self.inputs:
            return x
        return torch.cat([x, *(INPUTS[n][1](x, self.pos, self.quat) for n in self.inputs)], dim=-1)

    def forward(self, x: Tensor, known: Tensor, interp: Tensor | None = None, with_raw: bool = False):
        """``x (B, T, J, F), known (B, T, J), interp (B, T, J, F) | None -> (B, T, J, F)``.

        ``with_raw=True``: ``(prediction, raw)``, ``raw`` being the output before the known values are copied back
        (quaternions normalised), for the keyframe-consistency loss."""
        self.check_input(x, known, interp)
        # under autocast (bf16-mixed) the network may return bf16: the residual, the quaternion normalisation and the
        # output stay in the input's dtype (float32), so the contract's unit quaternions hold at float32 precision
        raw = self.network(self.network_input(x), known, interp).to(x.dtype)
        if self.gate:  # do no harm: a learned weight in [0, 1] per joint and frame on the correction
            raw = torch.sigmoid(raw[..., self.feature_dim :]) * raw[..., : self.feature_dim]
        if self.residual_to_interpolation and interp is not None:
            raw = interp + raw
        pred = self.finalize(raw, x, known)
        return (pred, self.normalize_quaternions(raw)) if with_raw else pred

    def normalize_quaternions(self, raw: Tensor) -> Tensor:
        """Scale the rotation channels of ``(..., F)`` to unit norm; other channels unchanged."""
        q = raw[..., self.quat]
        norm = torch.sqrt((q * q).sum(dim=-1, keepdim=True)).clamp_min(self.quat_eps)
        return torch.cat([raw[..., : self.quat.start], q / norm, raw[..., self.quat.stop :]], dim=-1)

    def finalize(self, raw: Tensor, x: Tensor, known: Tensor) -> Tensor:
        """``raw, x (B, T, J, F), known (B, T, J) -> (B, T, J, F)``: unit quaternions, known values copied from ``x``."""
        pred = self.normalize_quaternions(raw)
        return torch.where(known[..., None].to(torch.bool), x, pred)
