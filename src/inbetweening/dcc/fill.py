"""The whole "fill this action" flow of a front end (:func:`fill_action`), through the rig interface
(:mod:`.host`).

1. The animator's keys: per frame the bones keyed (:meth:`~.edits.Past.keyed_bones`: their own keys and the generated
   keys they edited since the last fill), split into whole and partial keys (:func:`~.keys.split_keys`); the gaps run
   between whole keys.
2. The pose read at the keys, the partial keys and the context frames before the first key (:class:`Reader`); the
   rig prepared from it (:meth:`Rig.plan <inbetweening.dcc.host.Rig.plan>`: the retargeting of a mapped rig).
3. What to re-fill (:mod:`.record`): nothing when nothing changed; else the runtime is handed every key, the kept
   gaps' frames as the last fill left them, the changed gaps and the recorded shares, and generates what changed.
4. The generated frames written as keys tagged as the fill's (:func:`~.keys.channel_keys`), the hand edits tagged as
   the animator's, every key of the animator kept exactly, and the new record stored.

Every check that can fail (the rig, the keys, the model, the fill's values) runs before anything is changed.
"""
from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from inbetweening.runtime import FillRuntime, InbetweenError
from inbetweening.runtime.plan import key_gaps

from .edits import Past
from .host import Rig, RigError
from .keys import channel_keys, fill_span, runs, split_keys
from .record import digest, model_key, settings_digest
from .report import gap_info

__all__ = ["Reader", "fill_action"]


class Reader:
    """A rig's poses read frame by frame (:meth:`Rig.read <inbetweening.dcc.host.Rig.read>`), kept so each frame is
    read once."""

    def __init__(self, rig: Rig):
        self.rig = rig
        self.a: dict[int, np.ndarray] = {}
        self.b: dict[int, np.ndarray] = {}
        self.raw: dict[int, list] = {}

    def read(self, frames) -> tuple[np.ndarray, np.ndarray, list]:
        todo = [f for f in dict.fromkeys(frames) if f not in self.a]
        if todo:
            a, b, raw = self.rig.read(todo)
            for t, f in enumerate(todo):
                self.a[f], self.b[f], self.raw[f] = a[t], b[t], raw[t]
        return (np.stack([self.a[f] for f in frames]), np.stack([self.b[f] for f in frames]),
                [self.raw[f] for f in frames])

    def digests(self, frames, masks: dict | None = None) -> dict[str, str]:
        """A digest of the pose read at each of ``frames``; at a partial key (``masks``: ``{frame: (J,) bool}``) of
        its keyed joints only (the others are the fill's)."""
        def keyed(x, m):
            return x[m] if x.shape[:1] == m.shape else (x if m[0] else x[:0])

        masks = masks or {}
        return {str(f): digest(*((keyed(self.a[f], masks[f]), keyed(self.b[f], masks[f])) if f in masks
                                 else (self.a[f], self.b[f]))) for f in frames}


def fill_action(rig: Rig, model, lo: int, hi: int, *, only_selected: bool = False,
                preview: tuple[int, int] | None = None, foot_lock: bool = True, discard_edits: bool = False,
                self_check: bool = True, progress: Callable[[int, int], None] | None = None) -> dict:
    """Fill the in-betweens of ``rig``'s animation in frames ``[lo, hi]`` with ``model`` (a runtime backend); returns
    a summary dict (``gaps`` re-filled, ``kept``, ``edits`` kept, ``keys``, ``partial_keys``, ``refilled``,
    ``network_share``, ...).  Only what changed since the last fill is re-filled, and generated keys edited by hand
    are kept as keys (``discard_edits``: every gap re-filled, the edits replaced).  ``only_selected``: the span of the
    selected keys (none: ``preview``, the preview range); ``foot_lock``, ``self_check``, ``progress(done, total)``:
    the runtime's (the record names the model by :func:`~.record.model_key`).  Raises :class:`~.host.RigError`, a
    bone map's or the runtime's error before changing anything."""
    info = model.info
    curves = rig.curves
    key_chans = rig.key_channels()
    past = Past(curves, discard_edits)
    lo, hi = fill_span(lo, hi, past.key_frames(key_chans, lo, hi, selected_only=True) if only_selected else None,
                       preview)
    # whole keys (every keyed bone) bound the gaps; a frame keyed on some bones only is a partial key inside one
    all_keys, partial = split_keys(past.keyed_bones(key_chans, lo, hi), whole_only=rig.whole_keys_only)
    all_gaps = key_gaps(all_keys)
    if not all_gaps:
        raise RigError(f"nothing to fill: frames {lo}..{hi} hold {len(all_keys)} key(s) and no gap between two keys")
    rig.check(all_keys[0], all_keys[-1])
    p = info.n_past
    reader = Reader(rig)
    seen = list(range(all_keys[0] - (p - 1), all_keys[0])) + sorted(all_keys + list(partial))
    reader.read(seen)
    rig.plan(reader.a[all_keys[0]], np.stack([reader.a[k] for k in all_keys]), np.stack([reader.b[k] for k in all_keys]))
    chans = rig.channels()
    settings = settings_digest(f"{model_key(model)}|check={bool(self_check)}", foot_lock, chans,
                               rig.settings_parts())
    masks = {f: np.isin(rig.joint_names, sorted(b)) for f, b in partial.items()}
    digests = reader.digests(seen, masks)
    plan = past.plan(all_keys, all_gaps, p, digests, settings, inner=list(partial))
    summary = {"gaps": 0, "kept": len(all_gaps), "edits": past.new_edits, "keys": len(all_keys),
               "range": (all_keys[0], all_keys[-1]), "humanoid": rig.retargeted, "model_seconds": 0.0, "windows": 0,
               "frames": 0, "feet_locked": False, "network_share": [], "refilled": [], "partial_keys": len(partial)}
    if plan.nothing:
        return summary
    # every key, and the frames of the gaps the runtime may keep as they are now (the last fill's output)
    frames = np.arange(all_keys[0] - (p - 1), all_keys[-1] + 1)
    pos = {int(f): i for i, f in enumerate(frames)}
    changed = set(all_gaps) if plan.changed is None else plan.changed
    kept = [f for a, b in all_gaps if (a, b) not in changed for f in range(a + 1, b)]
    read_keys = set(seen)
    read_frames = sorted(read_keys | set(kept))
    only = None if plan.changed is None else {(pos[a], pos[b]) for a, b in plan.changed}
    previous = None if plan.previous is None else {(pos[a], pos[b]): w for (a, b), w in plan.previous.items()
                                                   if a in pos and b in pos}
    rows = [pos[f] for f in read_frames]
    a_k, b_k, raw = reader.read(read_frames)
    a = np.full((len(frames),) + a_k.shape[1:], np.nan)
    b = np.full((len(frames),) + b_k.shape[1:], np.nan)
    a[rows], b[rows] = a_k, b_k
    t0 = time.perf_counter()
    runtime = FillRuntime(model, foot_lock=foot_lock, self_check=self_check)
    filled, out_a, out_b, generated = rig.fill(runtime, a, b, [pos[k] for k in all_keys], progress=progress, only=only,
                                               previous=previous, partial={pos[f]: m for f, m in masks.items()} or None)
    t_model = time.perf_counter() - t0
    gaps = [(int(frames[i]), int(frames[j])) for i, j in generated]
    if not gaps:
        return summary
    gen = np.array([f for g0, g1 in gaps for f in range(g0 + 1, g1)])
    idx = np.array([pos[int(f)] for f in gen])
    raw_prev = {f: raw[t] for t, f in enumerate(read_frames) if f in read_keys}  # Euler continuity from the keys
    values = rig.basis_values([int(f) for f in gen], out_a[idx], out_b[idx], raw_prev)
    if not all(np.isfinite(v).all() for v in values.values()):
        raise InbetweenError(f"the fill of {rig.where} came out with non-finite values; nothing was changed")
    spans = runs(all_gaps, gaps)
    past.apply()
    for j, path, i in chans:
        chan = (path, i)
        keys = curves.keys(chan)
        if keys is None:  # a channel without a curve: created with the animator's key at the first key
            curves.add(chan, gaps[0][0])
            keys = curves.keys(chan)
        free, missing = channel_keys(keys, gen, all_keys, partial, curves.bone(chan), spans)
        fr, val = gen[free].astype(np.float64), values[(j, path, i)][free]
        if missing:  # a key frame this channel has no key at: key its current value
            fr, val = np.concatenate([fr, missing]), np.concatenate([val, curves.evaluate(chan, missing)])
        curves.write(chan, fr, val, spans)
    done = gap_info(frames, gaps, filled, info)
    summary.update(gaps=len(gaps), kept=len(all_gaps) - len(gaps), frames=len(gen), model_seconds=t_model,
                   windows=model.calls, feet_locked=filled.locked, refilled=[list(g) for g in gaps],
                   network_share=[w for g in gaps for _, _, w in done[g]["windows"]])
    past.commit(chans, all_keys, all_gaps, p, digests, settings, done,
                {k: summary[k] for k in ("gaps", "kept", "edits", "refilled", "partial_keys")})
    summary.update(rig.summary())
    return summary
