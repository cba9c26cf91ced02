"""What the animator changed since the last fill: hand edits, kept exactly, and the animator's keys per frame.

**Hand edits.**  A generated key (tagged as the fill's, :attr:`Keys.generated <inbetweening.dcc.host.Keys>`) whose
value differs from the recorded one by more than :data:`~.record.TOLERANCE`, or that sits where the fill wrote none
(moved), was edited by hand: the next fill tags it as the animator's and fills around it as around any key.  A
generated key the animator re-tagged is theirs like any key they made.  With *Discard Edits* the edits go back to the
fill and are replaced with the rest.

**The animator's keys** (:meth:`Past.keyed_bones`): per frame, the bones holding a key of the animator on one of the
rig's key channels (:meth:`Rig.key_channels <inbetweening.dcc.host.Rig.key_channels>`) or an edit on any channel the
fill writes; :func:`~.keys.split_keys` tells whole keys from partial ones.
"""
from __future__ import annotations

import numpy as np

from .record import TOLERANCE, VERSION, Plan, decode, encode, refill_plan

__all__ = ["Past"]


class Past:
    """The last fill's record of a rig's animation (``curves``: :class:`~inbetweening.dcc.host.Curves`) and the hand
    edits since, read before the fill changes anything; :meth:`apply` tags the edited keys, :meth:`commit` stores the
    new record."""

    def __init__(self, curves, discard: bool = False):
        self.curves, self.discard = curves, bool(discard)
        self.meta, arrays = decode(curves.load_record())
        self.promote: dict = {}   # channel -> key indices to become the animator's
        self.demote: dict = {}    # channel -> key indices to go back to the fill (Discard Edits)
        self.edit_keys: dict = {}  # channel -> key indices of the animator's keys made from generated ones
        self.edits: dict = {}     # channel -> their frames
        self.broken: set[int] = set()  # frames where a generated key was deleted
        self.new_edits = 0
        if self.meta is None:
            return
        counts = arrays.get("gen_counts", np.zeros(0, np.int32))
        starts = np.concatenate([[0], np.cumsum(counts)]).astype(int)
        old_edits = {}
        for c, f in self.meta.get("edits", []):
            old_edits.setdefault(c, set()).add(int(f))
        for c, (path, index) in enumerate(self.meta.get("channels", [])):
            keys = curves.keys((path, index))
            if keys is None:
                continue
            rec_f = arrays["gen_frames"][starts[c]:starts[c + 1]].astype(int)
            rec_v = arrays["gen_values"][starts[c]:starts[c + 1]]
            self._channel((path, index), keys, rec_f, rec_v, old_edits.get(c, set()))

    def _channel(self, chan, keys, rec_f, rec_v, old_edits) -> None:
        x, y, gen = keys.frames, keys.values, keys.generated
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
        edited = gen[k] & (np.abs(y[k].astype(np.float64) - rec_v[at >= 0]) > TOLERANCE)
        promote = set(k[edited].tolist())
        xi = np.round(x).astype(int)
        rec = np.sort(rec_f)
        written = rec[np.clip(np.searchsorted(rec, xi), 0, len(rec) - 1)] == xi if len(rec) else np.zeros(len(xi), bool)
        moved = gen & ((np.abs(x - xi) >= 1e-4) | ~written)  # where the fill wrote none
        promote |= set(np.flatnonzero(moved).tolist())
        old = find(sorted(old_edits))
        old = old[old >= 0]
        mine = sorted(promote | set(old[~gen[old]].tolist()))
        if self.discard:
            self.demote[chan] = [i for i in mine if not gen[i]]
            return
        self.new_edits += len(promote)
        self.promote[chan] = sorted(promote)
        if mine:
            self.edit_keys[chan] = mine
            self.edits[chan] = set(xi[mine].tolist())

    # ------------------------------------------------------------------ keys
    def key_frames(self, channels, lo: float, hi: float, selected_only: bool = False) -> set[int]:
        """Frames in ``[lo, hi]`` holding a key of the animator on any of ``channels``: not a generated key, or a
        generated one they edited (on any channel the fill writes); with Discard Edits, not one made from a generated
        key."""
        return set(self.keyed_bones(channels, lo, hi, selected_only))

    def keyed_bones(self, channels, lo: float, hi: float, selected_only: bool = False) -> dict[int, set[str]]:
        """:meth:`key_frames` with, per frame, the bones keyed there (``{frame: {bone name}}``; a bone is keyed at a
        frame where one of its channels holds a key of the animator)."""
        out: dict[int, set[str]] = {}
        channels = list(channels)
        extra = [c for c in self.edit_keys if c not in channels]
        for chan in channels + extra:
            keys = self.curves.keys(chan)
            if keys is None:
                continue
            mine = ~keys.generated
            if chan in extra:
                mine[:] = False
            mine[self.edit_keys.get(chan, [])] = True
            mine[self.demote.get(chan, [])] = False
            if selected_only:
                mine &= keys.selected
            f = np.round(keys.frames[mine]).astype(int)
            bone = self.curves.bone(chan)
            for v in f:
                if lo <= v <= hi:
                    out.setdefault(int(v), set()).add(bone)
        return out

    # ------------------------------------------------------------------ what changed
    def plan(self, keys, gaps, n_past: int, digests: dict, settings: str, inner=()) -> Plan:
        """The gaps whose inputs changed and the recorded shares (:func:`~.record.refill_plan`)."""
        return refill_plan(self.meta, keys, gaps, n_past, digests, settings, self.broken, inner, self.discard)

    # ------------------------------------------------------------------ writing
    def apply(self) -> None:
        """Tag the keys: edited generated keys become the animator's, discarded edits the fill's again."""
        for table, generated in ((self.promote, False), (self.demote, True)):
            for chan, idx in table.items():
                self.curves.set_generated(chan, idx, generated)

    def commit(self, chans, keys, gaps, n_past: int, digests: dict, settings: str, gap_info: dict,
               summary: dict) -> dict:
        """Store the record after a fill of ``keys``/``gaps`` (all of the filled range; ``chans``: the channels
        written, ``[(joint, path, index)]``; ``gap_info``: what the model did in the gaps re-filled now, ``{(a, b):
        {...}}``); returns the stored meta."""
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
            k = self.curves.keys((p, i))
            g = k.generated if k is not None else np.zeros(0, bool)
            counts.append(int(g.sum()))
            frames.append(np.round(k.frames[g]).astype(np.int32) if k is not None else np.zeros(0, np.int32))
            values.append(k.values[g].astype(np.float32) if k is not None else np.zeros(0, np.float32))
        edits = sorted([index[c], f] for c, fs in self.edits.items() if c in index for f in fs)
        out = {"version": VERSION, "settings": settings, "channels": channels, "gaps": [list(g) for g in order],
               "info": [info[g] for g in order], "digests": dig, "edits": edits, "last": summary}
        self.curves.store_record(encode(out, {
            "gen_counts": np.array(counts, np.int32),
            "gen_frames": np.concatenate(frames) if frames else np.zeros(0, np.int32),
            "gen_values": np.concatenate(values) if values else np.zeros(0, np.float32)}))
        self.meta = out
        return out
