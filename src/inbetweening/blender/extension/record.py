"""What the last fill wrote, kept on the action, and what the animator changed since: the extension's memory between
fills (hand edits kept, only the changed gaps re-filled).

**The record.**  After a fill, the action holds an ID property (:data:`RECORD`, one entry per action slot, so it is
saved with the .blend and restored by undo): every generated key of the channels the fill writes (frame and value,
as stored on the F-curve), the generated keys it turned into keys because the animator edited them (*edits*), the
gaps filled with what the model did there (network share, planted feet: :mod:`.loop` shows it), a digest of the
pose the fill read at every key and at the context frames before the first key, and a digest of the fill's settings.

**Hand edits.**  A generated key (Blender's key type *Generated*; *Breakdown* before Blender 4.2) whose value differs
from the recorded one by more than :data:`TOLERANCE`, or that sits where the fill wrote none (moved), was edited by
hand: the next fill sets its type to *Keyframe* and fills around it as around any key.  A generated key whose type the
animator changed is theirs like any key they made.  With *Discard Edits* the edits go back to *Generated* and are
replaced with the rest.

**What is re-filled** (:meth:`Past.plan`).  The record names the gaps whose own inputs changed: the gap is new (a key
added inside it, one of its keys moved or deleted), the pose at one of its two keys changed, a generated key inside
it was deleted, or a key or a frame before the first key among its ``n_past - 1`` context frames changed; a change of
the settings (model, Lock Feet, the channels written, the curves above the model's root) or Discard Edits re-fills
every gap.  The fill runtime is handed every key, the other gaps' frames as they are, those gaps (``only``) and the
network shares the record holds (``previous``), and adds what only it knows (:func:`inbetweening.runtime.plan.
chosen_gaps`): the gaps whose share changed (the self-check on the keys reaches three gap lengths either side of a
changed key, left of it too) and the gaps whose context it generated now (each gap sees the end of the gap before it:
a re-fill runs on to the right until ``n_past - 1`` consecutive keys stop it).  The gaps it did not generate are
never rewritten.
"""
from __future__ import annotations

import hashlib
import json
import os

import numpy as np

from .rig import GENERATED, _enum_index, bone_of

RECORD = "inbetween_fill"
TOLERANCE = 1e-6
VERSION = 1


def holder(obj):
    """``(action, key)``: where the record of the armature's animation lives (its action, one entry per slot)."""
    ad = obj.animation_data
    if ad is None or ad.action is None:
        return None, None
    slot = getattr(ad, "action_slot", None)
    return ad.action, (f"slot{slot.handle}" if slot is not None else "action")


def load(obj) -> tuple[dict | None, dict]:
    """The stored record of the armature's animation: ``(meta, arrays)``, ``(None, {})`` when there is none."""
    action, key = holder(obj)
    group = action.get(RECORD) if action is not None else None
    if group is None or key not in group:
        return None, {}
    entry = group[key]
    try:
        meta = json.loads(entry["meta"])
    except (KeyError, ValueError):
        return None, {}
    if meta.get("version") != VERSION:
        return None, {}
    arrays = {k: np.asarray(entry[k]) for k in ("gen_counts", "gen_frames", "gen_values") if k in entry}
    return meta, arrays


def store(obj, meta: dict, arrays: dict) -> None:
    action, key = holder(obj)
    if action.get(RECORD) is None:
        action[RECORD] = {}
    group = action[RECORD]
    if key in group:
        del group[key]  # a fresh group: assigning into an existing ID property array keeps its old length
    group[key] = {"meta": json.dumps(meta, separators=(",", ":")), **arrays}


def digest(*parts) -> str:
    h = hashlib.blake2b(digest_size=8)
    for p in parts:
        h.update(p if isinstance(p, bytes) else np.ascontiguousarray(p).tobytes())
    return h.hexdigest()


def model_key(model) -> str:
    """The model's identity: its metadata and file size (not its path: the .blend may move to another machine); an
    ensemble's: its members', in order."""
    return digest(*[x for m in getattr(model, "members", [model])
                    for x in (json.dumps(m.meta, sort_keys=True, default=str).encode(), str(os.path.getsize(m.path)).encode())])


def settings_digest(model_key: str, foot_lock: bool, chans, fcurves, ancestors) -> str:
    """What a change of re-fills every gap: the model, Lock Feet, the channels written and the key points of the
    curves of the bones above the model's root (they place it on every frame)."""
    parts = [f"{model_key}|{bool(foot_lock)}|" + ";".join(f"{p}[{i}]" for _, p, i in chans)]
    for pb in ancestors:
        for fc in fcurves.fcurves:
            if fc.data_path.startswith(f'pose.bones["{pb.name}"]'):
                co = np.zeros(2 * len(fc.keyframe_points), np.float32)
                fc.keyframe_points.foreach_get("co", co)
                parts += [fc.data_path.encode(), co]
    return digest(*[p.encode() if isinstance(p, str) else p for p in parts])


def inside(frames: np.ndarray, spans) -> np.ndarray:
    """Which of ``frames`` lie strictly inside one of ``spans`` ``[(lo, hi)]``."""
    out = np.zeros(len(frames), dtype=bool)
    for lo, hi in spans:
        out |= (frames > lo) & (frames < hi)
    return out


def scan(fc) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A curve's keys: ``frame, value, type, selected``."""
    kp = fc.keyframe_points
    n = len(kp)
    co = np.zeros(2 * n, np.float32)
    typ = np.zeros(n, np.int32)
    sel = np.zeros(n, np.int32)
    if n:
        kp.foreach_get("co", co)
        kp.foreach_get("type", typ)
        kp.foreach_get("select_control_point", sel)
    return co[0::2], co[1::2], typ, sel.astype(bool)


class Reader:
    """A rig's poses read frame by frame (``Rig.read`` / ``HumanoidRig.read``), kept so each frame is read once."""

    def __init__(self, rig):
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


def runs(gaps, filled) -> list[list[int]]:
    """``[[lo, hi], ...]``: the runs of consecutive ``gaps`` (in order) that are in ``filled``."""
    out: list[list[int]] = []
    filled = set(filled)
    for i, (a, b) in enumerate(gaps):
        if (a, b) not in filled:
            continue
        if out and i > 0 and gaps[i - 1] in filled:
            out[-1][1] = b
        else:
            out.append([a, b])
    return out


def split_keys(by_frame: dict[int, set[str]], whole_only: bool = False) -> tuple[list[int], dict[int, set[str]]]:
    """The whole keys and the partial keys of ``{frame: bones keyed there}`` (:meth:`Past.keyed_bones`): a frame is a
    whole key when every bone keyed anywhere is keyed there, a partial key (constraining its bones only) when it lies
    between two whole keys; frames outside them, and every frame when fewer than two are whole (or ``whole_only``),
    are whole keys, each channel not keyed there keyed at its current value as before partial keys existed."""
    frames = sorted(by_frame)
    every = set().union(*by_frame.values()) if by_frame else set()
    whole = [f for f in frames if by_frame[f] >= every]
    if whole_only or len(whole) < 2:
        return frames, {}
    partial = {f: by_frame[f] for f in frames if whole[0] < f < whole[-1] and f not in whole}
    return sorted(set(frames) - set(partial)), partial


class Past:
    """The last fill's record of an armature and the hand edits since (read before the fill changes anything;
    :meth:`apply` sets the key types, :meth:`commit` stores the new record)."""

    def __init__(self, obj, fcurves, discard: bool = False):
        self.obj, self.fcurves, self.discard = obj, fcurves, bool(discard)
        self.meta, arrays = load(obj)
        self.gen = _enum_index("type", GENERATED)
        self.key = _enum_index("type", "KEYFRAME")
        self.promote: dict = {}   # curve -> key indices to become the animator's (KEYFRAME)
        self.demote: dict = {}    # curve -> key indices to go back to generated (Discard Edits)
        self.edit_keys: dict = {}  # curve -> key indices of the animator's keys made from generated ones
        self.edits: dict = {}     # (path, index) -> their frames
        self.broken: set[int] = set()  # frames where a generated key was deleted
        self.new_edits = 0
        if self.meta is None or fcurves is None:
            return
        counts = arrays.get("gen_counts", np.zeros(0, np.int32))
        starts = np.concatenate([[0], np.cumsum(counts)]).astype(int)
        old_edits = {}
        for c, f in self.meta.get("edits", []):
            old_edits.setdefault(c, set()).add(int(f))
        for c, (path, index) in enumerate(self.meta.get("channels", [])):
            fc = fcurves.fcurves.find(path, index=index)
            if fc is None:
                continue
            rec_f = arrays["gen_frames"][starts[c]:starts[c + 1]].astype(int)
            rec_v = arrays["gen_values"][starts[c]:starts[c + 1]]
            self._channel(fc, (path, index), rec_f, rec_v, old_edits.get(c, set()))

    def _channel(self, fc, chan, rec_f, rec_v, old_edits) -> None:
        x, y, typ, _ = scan(fc)
        order = np.argsort(x, kind="stable")

        def find(frames):
            """The key index at each of ``frames``, -1 where there is none."""
            frames = np.asarray(frames, np.float64)
            if len(x) == 0:
                return np.full(len(frames), -1)
            i = np.clip(np.searchsorted(x[order], frames - 1e-4), 0, len(x) - 1)
            return np.where(np.abs(x[order][i] - frames) < 1e-4, order[i], -1)

        at = find(rec_f)
        self.broken.update(rec_f[at < 0].tolist())
        k = at[at >= 0]
        edited = (typ[k] == self.gen) & (np.abs(y[k].astype(np.float64) - rec_v[at >= 0]) > TOLERANCE)
        promote = set(k[edited].tolist())
        xi = np.round(x).astype(int)
        moved = (typ == self.gen) & ((np.abs(x - xi) >= 1e-4) | ~np.isin(xi, rec_f))  # where the fill wrote none
        promote |= set(np.flatnonzero(moved).tolist())
        old = find(sorted(old_edits))
        old = old[old >= 0]
        mine = sorted(promote | set(old[typ[old] != self.gen].tolist()))
        if self.discard:
            self.demote[fc] = [i for i in mine if typ[i] != self.gen]
            return
        self.new_edits += len(promote)
        self.promote[fc] = sorted(promote)
        if mine:
            self.edit_keys[fc] = mine
            self.edits[chan] = set(xi[mine].tolist())

    # ------------------------------------------------------------------ keys
    def key_frames(self, curves, lo: float, hi: float, selected_only: bool = False) -> set[int]:
        """Frames in ``[lo, hi]`` holding a key of the animator on any of ``curves``: not a generated key, or a
        generated one they edited (on any channel the fill writes); with Discard Edits, not one made from a generated
        key."""
        return set(self.keyed_bones(curves, lo, hi, selected_only))

    def keyed_bones(self, curves, lo: float, hi: float, selected_only: bool = False) -> dict[int, set[str]]:
        """:meth:`key_frames` with, per frame, the bones keyed there (``{frame: {bone name}}``; a bone is keyed at a
        frame where one of its curves holds a key of the animator)."""
        out: dict[int, set[str]] = {}
        extra = [fc for fc in self.edit_keys if fc not in curves]
        for fc in list(curves) + extra:
            x, _, typ, sel = scan(fc)
            mine = typ != self.gen
            if fc in extra:
                mine[:] = False
            mine[self.edit_keys.get(fc, [])] = True
            mine[self.demote.get(fc, [])] = False
            if selected_only:
                mine &= sel
            f = np.round(x[mine]).astype(int)
            bone = bone_of(fc.data_path)
            for v in f:
                if lo <= v <= hi:
                    out.setdefault(int(v), set()).add(bone)
        return out

    # ------------------------------------------------------------------ what changed
    def plan(self, keys, gaps, n_past: int, digests: dict, settings: str, inner=()) -> Plan:
        """The gaps whose inputs changed and the recorded shares (module docstring): ``digests`` of the poses read now
        at the keys, the partial keys (``inner``: frames keyed on some bones, inside the gaps) and the context frames
        before the first key; ``settings``: :func:`settings_digest`."""
        meta = self.meta
        if meta is None or meta.get("settings") != settings or self.discard:
            return Plan(None, None)
        old_gaps = {tuple(g) for g in meta["gaps"]}
        old = meta["digests"]
        keyset = set(keys)
        first = keys[0]

        def changed(f):
            return str(f) not in old or old[str(f)] != digests.get(str(f))

        dirty = {(a, b) for a, b in gaps
                 if (a, b) not in old_gaps or changed(a) or changed(b) or any(a < f < b for f in self.broken)
                 or any((f < first or f in keyset) and changed(f) for f in range(a - n_past + 1, a))
                 or any(a < f < b and changed(f) for f in inner)
                 or any(a < int(f) < b and f not in digests for f in old)}  # a partial key added, changed, removed
        previous = {tuple(g): [w for _, _, w in gi["windows"]] for g, gi in zip(meta["gaps"], meta["info"])
                    if gi.get("windows")}
        return Plan(dirty, previous)

    # ------------------------------------------------------------------ writing
    def apply(self) -> None:
        """Set the key types: edited generated keys become *Keyframe*, discarded edits *Generated* again."""
        for table, value in ((self.promote, self.key), (self.demote, self.gen)):
            for fc, idx in table.items():
                typ = np.zeros(len(fc.keyframe_points), np.int32)
                fc.keyframe_points.foreach_get("type", typ)
                typ[idx] = value
                fc.keyframe_points.foreach_set("type", typ)

    def commit(self, fcurves, chans, keys, gaps, n_past: int, digests: dict, settings: str, gap_info: dict,
               summary: dict) -> dict:
        """Store the record after a fill of ``keys``/``gaps`` (all of the filled range; ``gap_info``: what the model
        did in the gaps re-filled now, ``{(a, b): {...}}``); returns the stored meta."""
        meta = self.meta if self.meta is not None and self.meta.get("settings") == settings else None
        lo, hi = keys[0], keys[-1]
        info = {}
        if meta is not None:  # gaps outside this fill's range, and the range's gaps kept, keep what was known
            for g, gi in zip(meta["gaps"], meta["info"]):
                if g[1] <= lo or g[0] >= hi or tuple(g) in set(gaps):
                    info[tuple(g)] = gi
        for g in gaps:
            info[g] = gap_info.get(g) or info.get(g) or {}
        order = sorted(info)
        old_dig = meta["digests"] if meta is not None else {}
        dig = {f: d for f, d in old_dig.items() if not lo - n_past < int(f) <= hi}
        dig.update(digests)
        channels = [[p, i] for _, p, i in chans]
        counts, frames, values = [], [], []
        index = {(p, i): c for c, (p, i) in enumerate(channels)}
        for p, i in channels:
            fc = fcurves.fcurves.find(p, index=i)
            x, y, typ, _ = scan(fc) if fc is not None else (np.zeros(0),) * 4
            g = typ == self.gen
            counts.append(int(g.sum()))
            frames.append(np.round(x[g]).astype(np.int32))
            values.append(y[g].astype(np.float32))
        edits = sorted([index[c], f] for c, fs in self.edits.items() if c in index for f in fs)
        out = {"version": VERSION, "settings": settings, "channels": channels, "gaps": [list(g) for g in order],
               "info": [info[g] for g in order], "digests": dig, "edits": edits, "last": summary}
        store(self.obj, out, {"gen_counts": np.array(counts, np.int32),
                              "gen_frames": np.concatenate(frames) if frames else np.zeros(0, np.int32),
                              "gen_values": np.concatenate(values) if values else np.zeros(0, np.float32)})
        self.meta = out
        return out
