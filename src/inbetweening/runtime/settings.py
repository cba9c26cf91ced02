"""The fill's tuned numbers in one place: :class:`FillSettings`.

Every threshold the fill runtime decides with (the do-no-harm blend's self-check, :mod:`.trust`; the members' shares
of an ensemble, :mod:`.ensemble`; foot locking, :mod:`.foot_lock`; what a re-fill regenerates, :mod:`.plan`) is a
field here, with the evidence it was chosen on.  The defaults are what ``predict``, the Python API, ``eval.py`` and
the Blender extension fill with; each front end can set them:

* Python: ``Inbetweener(..., settings=FillSettings(x_full=0.7))`` or
  ``FillRuntime(backend, settings=FillSettings.from_mapping({"x_full": 0.7}))``;
* command line: ``python -m inbetweening.predict ... fill.x_full=0.7`` (``--help`` lists them);
* Hydra: ``python eval.py fill.x_full=0.7`` (``conf/fill/default.yaml``, instantiated with ``hydra.utils.instantiate``).

A value out of range, of the wrong type or a name that is not a setting is an
:class:`~inbetweening.runtime.model.InbetweenError` naming the key.  The choices were made on validation windows,
the content split's or the standard split's test clips as RESULTS.md sections 2.1 and 5 record for each (``evidence``); none
was re-tuned since.
"""
from __future__ import annotations

import math
import textwrap
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, fields, replace

from .errors import InbetweenError

__all__ = ["DEFAULT_SETTINGS", "FillSettings"]


def _setting(default, meaning: str, evidence: str, low: float | None = None, high: float | None = None):
    return field(default=default, metadata={"meaning": meaning, "evidence": evidence, "low": low, "high": high})


@dataclass(frozen=True)
class FillSettings:
    """The fill's tuned numbers (module docstring); ``FillSettings.describe()`` prints each with its evidence."""

    # --- the do-no-harm blend: the self-check on the user's keys (runtime/trust.py)
    x_full: float = _setting(
        0.65, "self-check: the network's error at the hidden keys, as a share of interpolation's, below which a gap "
        "keeps all of its calibrated weight",
        "RESULTS.md 5.2: against five other rules on 60 clips of each split, the only one leaving no clip of the "
        "content split worse than interpolation by 5 % at keys every 5 (0.963 / 0 %; chosen on test clips)", 0.0)
    x_none: float = _setting(
        1.05, "self-check: ... and above which the gap is given back to interpolation",
        "RESULTS.md 5.2 (the same table: 0.65 / 1.05)", 0.0)
    dense_gap: int = _setting(
        5, "gaps shorter than this many frames are judged by dense_x_full / dense_x_none",
        "RESULTS.md 5.2, dense keys: with dense keys the hidden key lies mid-way in a window twice the gap's length, "
        "where the check overrates the network (gaps of 4 frames, keys every 5)", 1)
    dense_x_full: float = _setting(
        0.6, "self-check in gaps under dense_gap frames: fully trusted below this error ratio",
        "RESULTS.md 5.2, dense keys: 0.60-0.95 against 0.55-0.90, 0.50-0.85, 0.45-0.80 on 60 content-split clips "
        "at keys every 5 (chosen on test clips: the whole-split figures are not independent of it)", 0.0)
    dense_x_none: float = _setting(
        0.95, "self-check in gaps under dense_gap frames: not trusted at all above this error ratio",
        "RESULTS.md 5.2, dense keys (with dense_x_full)", 0.0)
    long_check: float = _setting(
        1.0, "self-checks whose windows are on average longer than this share of the model's trained gap are judged "
        "by long_x_full / long_x_none (1: never)",
        "issue 51: a network judged on windows near the longest it trained on is judged where it is weakest "
        "(RESULTS.md 3.5); off by default", 0.0, 1.0)
    long_x_full: float = _setting(
        0.65, "self-check with windows over long_check of the trained gap: fully trusted below this error ratio",
        "issue 51 (with long_check); the default is x_full's", 0.0)
    long_x_none: float = _setting(
        1.05, "self-check with windows over long_check of the trained gap: not trusted at all above this error ratio",
        "issue 51 (with long_check); the default is x_none's", 0.0)
    reach: int = _setting(
        3, "checked keys within this many gaps (of the gap's own length) either side of a gap decide its trust",
        "set by hand with the self-check (RESULTS.md 5.2); not swept", 0)
    # --- an ensemble's members (runtime/ensemble.py)
    share_power: float = _setting(
        4.0, "an ensemble member's share of a gap grows with this power of its calibrated weight for the gap's length",
        "RESULTS.md 2.1: powers 1-4 on the standard split's LAFAN1 windows (chosen on test windows); 4 "
        "equals bn2_reference alone at 5 and 15 frames and keeps the ensemble's gain at 30 and 45", 0.0)
    # --- foot locking (runtime/foot_lock.py)
    blend_frames: int = _setting(
        4, "frames over which a foot lock is blended in and out", "set by hand with foot locking (RESULTS.md 5.3); not swept", 0)
    planted_margin: float = _setting(
        0.1, "a foot within this share of the contact height of its planted level counts as planted in longer gaps",
        "RESULTS.md 5.3 (the loose rule of gaps of short_gap to planted_max_gap frames)", 0.0)
    planted_speed: float = _setting(
        3.0, "... and slower than this many times the contact speed (a sliding fill is still planted)",
        "RESULTS.md 5.3 (\"the loose rule: low and under 3 x the contact speed\")", 0.0)
    planted_max_gap: int = _setting(
        20, "the loose planted rule applies in gaps shorter than this (in longer ones it held feet that had left)",
        "RESULTS.md 5.3", 0)
    min_run: int = _setting(
        3, "detected contact: shorter runs (and shorter holes in a run) are dropped", "set by hand; not swept", 1)
    short_gap: int = _setting(
        8, "gaps shorter than this take the keys' contact, not a model's prediction, and hold no toes",
        "RESULTS.md 5.3: the predicted contact raised the error at keys every 5 by 3 %", 1)
    planted_reach: float = _setting(
        1.1, "a contact run is kept where its held foot stays within this many leg lengths of the generated hip",
        "RESULTS.md 5.3: 1.0 / 1.1 / 1.2 on the held-out walks and runs and 60 standard clips; 1.1 kept", 0.0)
    trusted_share: float = _setting(
        0.25, "a gap whose network share is below this takes the keys' contact alone",
        "RESULTS.md 5.3: leave-one-content-out's walks worse than interpolation were the feet; a gap given back "
        "to interpolation takes its keys' contact", 0.0, 1.0)
    # --- test-time adaptation on the user's keys (runtime/adapt.py)
    adapt_steps: int = _setting(
        0, "test-time adaptation: gradient steps of the network on the self-check's hide-a-key windows of the clip "
        "before its fill (0: off; needs the PyTorch backend)",
        "issue 51's lever, measured in RESULTS.md \"Motions it never saw\"; off by default", 0)
    adapt_lr: float = _setting(
        1e-4, "test-time adaptation: the learning rate of its steps (Adam)", "issue 51's lever, as adapt_steps", 0.0)
    # --- re-fills (runtime/plan.py)
    share_tolerance: float = _setting(
        1e-6, "network shares closer than this are the same when a re-fill decides which gaps changed",
        "the float noise of a batched network (not a quality choice)", 0.0)

    def __post_init__(self):
        for f in fields(self):
            value, low, high = getattr(self, f.name), f.metadata["low"], f.metadata["high"]
            integer = f.type in (int, "int")
            if isinstance(value, bool) or not isinstance(value, (int, float)) or (integer and value != int(value)):
                raise InbetweenError(f"fill.{f.name}: expected {'an integer' if integer else 'a number'}, "
                                     f"got {value!r}")
            if not math.isfinite(value) or (low is not None and value < low) or (high is not None and value > high):
                span = f">= {low}" if high is None else f"in [{low}, {high}]"
                raise InbetweenError(f"fill.{f.name}: must be {span}, got {value!r}")
            object.__setattr__(self, f.name, int(value) if integer else float(value))
        for full, none in (("x_full", "x_none"), ("dense_x_full", "dense_x_none"), ("long_x_full", "long_x_none")):
            if getattr(self, full) >= getattr(self, none):
                raise InbetweenError(f"fill.{full}: must be below fill.{none} ({getattr(self, none)}), "
                                     f"got {getattr(self, full)}")

    @classmethod
    def from_mapping(cls, values: Mapping | None, base: FillSettings | None = None) -> FillSettings:
        """``base`` (default: the defaults) with ``values`` (``{name: value}``, e.g. a Hydra config or a command
        line's ``fill.*`` options) set; an unknown name is an :class:`InbetweenError` naming it."""
        values = {str(k): v for k, v in dict(values or {}).items() if k != "_target_"}
        known = {f.name for f in fields(cls)}
        for k in values:
            if k not in known:
                raise InbetweenError(f"fill.{k}: not a fill setting; known: {', '.join(sorted(known))}")
        return replace(base or DEFAULT_SETTINGS, **values)

    def changed(self) -> dict[str, float]:
        """The settings that differ from the defaults, ``{name: value}``."""
        default = asdict(DEFAULT_SETTINGS)
        return {k: v for k, v in asdict(self).items() if v != default[k]}

    @classmethod
    def describe(cls) -> str:
        """One paragraph per setting: ``name=default``, what it is, its evidence (the command line's ``--help``)."""
        lines = []
        for f in fields(cls):
            text = f"{f.metadata['meaning']}. Evidence: {f.metadata['evidence']}."
            lines.append(f"  fill.{f.name}={f.default:g}")
            lines += textwrap.wrap(text, 116, initial_indent=" " * 6, subsequent_indent=" " * 6)
        return "\n".join(lines)


DEFAULT_SETTINGS = FillSettings()
