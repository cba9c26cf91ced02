"""The record of the last fill, kept with the rig's animation (:meth:`Curves.store_record
<inbetweening.dcc.host.Curves.store_record>`), and the re-fill plan it gives: the core's memory between fills.

**The record** (one entry per animation: Blender keeps it on the action, one per action slot, so it is saved with the
file and restored by undo): every generated key of the channels the fill writes (frame and value, as the host stores
them), the keys the animator made from generated ones (*edits*, :mod:`.edits`), the gaps filled with what the model
did there (network share, planted feet: :mod:`.report`), a digest of the pose the fill read at every key and at the
context frames before the first key, and a digest of the fill's settings.  Stored as ``{"meta": JSON, "gen_counts",
"gen_frames", "gen_values"}`` (:func:`encode`, :func:`decode`).

**What is re-filled** (:func:`refill_plan`).  The record names the gaps whose own inputs changed: the gap is new (a key
added inside it, one of its keys moved or deleted), the pose at one of its two keys changed, a partial key inside it
was added, removed or changed, a generated key inside it was deleted, or a key or a frame before the first key among
its ``n_past - 1`` context frames changed; a change of the settings (model, Lock Feet, Self-Check, the channels
written, :meth:`Rig.settings_parts <inbetweening.dcc.host.Rig.settings_parts>`) or Discard Edits re-fills every gap.
The fill runtime is handed every key, the other gaps' frames as they are, those gaps (``only``) and the network shares
the record holds (``previous``), and adds what only it knows (:func:`inbetweening.runtime.plan.chosen_gaps`): the gaps
whose share changed and those whose context it generated now.  The gaps it did not generate are never rewritten.
"""
from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Mapping

import numpy as np

__all__ = ["TOLERANCE", "VERSION", "Plan", "decode", "digest", "encode", "model_key", "refill_plan",
           "settings_digest"]

TOLERANCE = 1e-6  # a generated key further than this from the value the fill wrote was edited by hand
VERSION = 1
ARRAYS = ("gen_counts", "gen_frames", "gen_values")


def digest(*parts) -> str:
    """A short digest of ``parts`` (bytes, or arrays: their bytes)."""
    h = hashlib.blake2b(digest_size=8)
    for p in parts:
        h.update(p if isinstance(p, bytes) else np.ascontiguousarray(p).tobytes())
    return h.hexdigest()


def model_key(model) -> str:
    """The model's identity: an exported model's metadata and file size (not its path: the scene may move to another
    machine); an ensemble's: its members', in order.  A member without a model file (a PyTorch backend): its class and
    :class:`~inbetweening.runtime.model.ModelInfo`."""
    parts = []
    for m in getattr(model, "members", [model]):
        path = getattr(m, "path", None)
        if hasattr(m, "meta") and isinstance(path, str):
            parts += [json.dumps(m.meta, sort_keys=True, default=str).encode(), str(os.path.getsize(path)).encode()]
        else:
            parts += [type(m).__name__.encode(), repr(m.info).encode()]
    return digest(*parts)


def settings_digest(model_key: str, foot_lock: bool, chans, extra=()) -> str:
    """What a change of re-fills every gap: the model (with the fill's options in ``model_key``), Lock Feet, the
    channels written (``chans``: ``[(joint, path, index)]``) and ``extra`` (bytes or arrays:
    :meth:`Rig.settings_parts <inbetweening.dcc.host.Rig.settings_parts>`)."""
    head = f"{model_key}|{bool(foot_lock)}|" + ";".join(f"{p}[{i}]" for _, p, i in chans)
    return digest(head.encode(), *extra)


def decode(entry: Mapping | None) -> tuple[dict | None, dict]:
    """``(meta, arrays)`` of a stored record (:func:`encode`); ``(None, {})`` for none, or one of another version."""
    if entry is None:
        return None, {}
    try:
        meta = json.loads(entry["meta"])
    except (KeyError, ValueError):
        return None, {}
    if meta.get("version") != VERSION:
        return None, {}
    return meta, {k: np.asarray(entry[k]) for k in ARRAYS if k in entry}


def encode(meta: dict, arrays: dict) -> dict:
    """The entry a host stores: the meta as compact JSON, and the arrays."""
    return {"meta": json.dumps(meta, separators=(",", ":")), **arrays}


class Plan:
    """What the record says a fill must re-fill: ``changed``, the gaps whose own inputs changed (the runtime's
    ``only``), and ``previous``, the network shares the record holds per gap (its ``previous``); both ``None`` where
    every gap is re-filled (no record, other settings, Discard Edits)."""

    def __init__(self, changed: set | None, previous: dict | None):
        self.changed, self.previous = changed, previous

    @property
    def nothing(self) -> bool:
        """Whether nothing changed (then no share can have changed either: nothing to fill)."""
        return self.changed is not None and not self.changed


def refill_plan(meta: dict | None, keys, gaps, n_past: int, digests: dict, settings: str, broken=(), inner=(),
                discard: bool = False) -> Plan:
    """The gaps whose inputs changed since the fill ``meta`` records, and the recorded shares (module docstring):
    ``digests`` of the poses read now at the keys, the partial keys (``inner``: frames keyed on some bones, inside
    the gaps) and the context frames before the first key; ``settings``: :func:`settings_digest`; ``broken``: frames
    where a generated key was deleted."""
    if meta is None or meta.get("settings") != settings or discard:
        return Plan(None, None)
    old_gaps = {tuple(g) for g in meta["gaps"]}
    old = meta["digests"]
    keyset = set(keys)
    first = keys[0]

    def changed(f):
        return str(f) not in old or old[str(f)] != digests.get(str(f))

    dirty = {(a, b) for a, b in gaps
             if (a, b) not in old_gaps or changed(a) or changed(b) or any(a < f < b for f in broken)
             or any((f < first or f in keyset) and changed(f) for f in range(a - n_past + 1, a))
             or any(a < f < b and changed(f) for f in inner)
             or any(a < int(f) < b and f not in digests for f in old)}  # a partial key added, changed, removed
    previous = {tuple(g): [w for _, _, w in gi["windows"]] for g, gi in zip(meta["gaps"], meta["info"])
                if gi.get("windows")}
    return Plan(dirty, previous)
