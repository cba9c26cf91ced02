"""A fake host for the DCC core (:mod:`inbetweening.dcc`): the worked example of a front end.

A front end for another animation package (Maya, a game engine's editor) writes exactly these two objects, with its
own curves instead of the numpy arrays here, then calls :func:`inbetweening.dcc.fill_action` from its operator:

- :class:`MemoryCurves` (a :class:`~inbetweening.dcc.Curves`): the host's keys.  Per channel ``(path, index)`` its
  keys as numpy arrays (frames and values stored as float32, as Blender stores them), whether the fill generated each
  key (the host's tag: Blender's key type *Generated*) and whether it is selected; evaluated linearly between keys
  (constant outside them); the record of the last fill kept with the animation.
- A rig: :class:`MemoryHumanoid` (a :class:`~inbetweening.dcc.MappedRig`: any humanoid; the bone map and the
  retargeting are the core's) or :class:`MemoryModelRig` (a :class:`~inbetweening.dcc.Rig` of the model's own
  skeleton).  Its pose channels are a quaternion ``("<bone>.rotation", 0..3)`` (wxyz) per bone, relative to the bone's
  rest rotation (the identity here), and a location ``("<bone>.location", 0..2)`` where the bone moves.
"""
from __future__ import annotations

import numpy as np

from inbetweening.dcc import Curves, Keys, MappedRig, Rig

ROTATION, LOCATION = "rotation", "location"


def rotation(bone: str, i: int) -> tuple[str, int]:
    return f"{bone}.{ROTATION}", i


def location(bone: str, i: int) -> tuple[str, int]:
    return f"{bone}.{LOCATION}", i


class MemoryCurves(Curves):
    """Curves in memory: ``curves[(path, index)]`` = ``{"frames", "values"}`` (float32), ``{"generated",
    "selected"}`` (bool), sorted by frame; ``record``: the core's record."""

    def __init__(self):
        self.curves: dict[tuple[str, int], dict[str, np.ndarray]] = {}
        self.record: dict | None = None

    # ---------------------------------------------------------------- what the animator does
    def key(self, channel, frame: int, value: float, generated: bool = False) -> None:
        """Key ``value`` at ``frame`` (replacing a key there), as the animator (or, ``generated``, the fill)."""
        c = self.curves.setdefault(channel, {"frames": np.zeros(0, np.float32), "values": np.zeros(0, np.float32),
                                             "generated": np.zeros(0, bool), "selected": np.zeros(0, bool)})
        keep = np.abs(c["frames"] - frame) >= 1e-4
        self._set(channel, {k: v[keep] for k, v in c.items()},
                  {"frames": [frame], "values": [value], "generated": [generated], "selected": [False]})

    def move(self, src: int, dst: int) -> None:
        """Move the keys at frame ``src`` to ``dst`` on every curve, as a drag in a dope sheet does (it replaces the
        keys at ``dst``)."""
        for c in self.curves.values():
            keep = np.abs(c["frames"] - dst) >= 1e-4
            for k in c:
                c[k] = c[k][keep]
            c["frames"][np.abs(c["frames"] - src) < 1e-4] = dst
            order = np.argsort(c["frames"], kind="stable")
            for k in c:
                c[k] = c[k][order]

    def at(self, channel, frame: int) -> tuple[float, bool]:
        """``(value, generated)`` of the channel's key at ``frame``."""
        c = self.curves[channel]
        i = int(np.flatnonzero(np.abs(c["frames"] - frame) < 1e-4)[0])
        return float(c["values"][i]), bool(c["generated"][i])

    def copy(self) -> dict:
        return {ch: {k: v.copy() for k, v in c.items()} for ch, c in self.curves.items()}

    # ---------------------------------------------------------------- the core's Curves
    def keys(self, channel) -> Keys | None:
        c = self.curves.get(channel)
        if c is None:
            return None
        return Keys(c["frames"].copy(), c["values"].copy(), c["generated"].copy(), c["selected"].copy())

    def evaluate(self, channel, frames) -> np.ndarray:
        c = self.curves.get(channel)
        if c is None or not len(c["frames"]):
            return np.full(len(frames), self.current(channel))
        return np.interp(np.asarray(frames, np.float64), c["frames"].astype(np.float64), c["values"].astype(np.float64))

    def current(self, channel) -> float:
        """A channel's value without a curve: the rest pose."""
        return 1.0 if channel[0].endswith(ROTATION) and channel[1] == 0 else 0.0

    def bone(self, channel) -> str:
        return channel[0].rsplit(".", 1)[0]

    def set_generated(self, channel, indices, generated: bool) -> None:
        self.curves[channel]["generated"][indices] = generated

    def add(self, channel, frame: int) -> None:
        self.key(channel, frame, self.current(channel))

    def write(self, channel, frames, values, spans) -> None:
        c = self.curves[channel]
        x = c["frames"]
        inside = np.zeros(len(x), bool)
        for lo, hi in spans:
            inside |= (x > lo + 1e-4) & (x < hi - 1e-4)
        keep = ~(inside & c["generated"])
        n = len(frames)
        self._set(channel, {k: v[keep] for k, v in c.items()},
                  {"frames": frames, "values": values, "generated": np.ones(n, bool), "selected": np.zeros(n, bool)})

    def load_record(self):
        return self.record

    def store_record(self, entry: dict) -> None:
        self.record = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in entry.items()}

    def _set(self, channel, old: dict, new: dict) -> None:
        both = {"frames": np.concatenate([old["frames"], np.asarray(new["frames"], np.float32)]),
                "values": np.concatenate([old["values"], np.asarray(new["values"], np.float32)]),
                "generated": np.concatenate([old["generated"], np.asarray(new["generated"], bool)]),
                "selected": np.concatenate([old["selected"], np.asarray(new["selected"], bool)])}
        order = np.argsort(both["frames"], kind="stable")
        self.curves[channel] = {k: v[order] for k, v in both.items()}


def _continuous(q: np.ndarray, frames, raw_prev: dict, k: int) -> np.ndarray:
    """Quaternions ``q (F, 4)`` at ``frames``, each sign-continuous with the frame before (``raw_prev``: the raw values
    read at the frame before each run of frames)."""
    out, prev = q.copy(), None
    for t, fr in enumerate(frames):
        if fr - 1 in raw_prev:
            prev = raw_prev[fr - 1][k]
        if prev is not None and np.dot(out[t], prev) < 0:
            out[t] = -out[t]
        prev = out[t]
    return out


class MemoryHumanoid(MappedRig):
    """A humanoid rig in memory: ``names``, ``parents``, ``offsets`` (the BVH convention: every rest rotation the
    identity), its channels in ``curves`` (:class:`MemoryCurves`).  The bone map, the retargeting and the bones the
    fill writes are :class:`~inbetweening.dcc.MappedRig`'s."""

    def __init__(self, curves: MemoryCurves, model, names, parents, offsets, override=None):
        super().__init__(curves, model, "the rig 'memory'", list(names), list(parents), np.asarray(offsets, float),
                         override)

    def key_channels(self) -> list:
        mapped = set(self.map.slots.values())
        return [ch for ch in self.curves.curves if self.curves.bone(ch) in mapped]

    def has_location(self, j: int) -> bool:
        return any(location(self.names[j], i) in self.curves.curves for i in range(3))

    def read(self, frames):
        ev = self.curves.evaluate
        qb = np.stack([np.stack([ev(rotation(b, i), frames) for i in range(4)], -1) for b in self.names], 1)
        loc = np.stack([np.stack([ev(location(b, i), frames) for i in range(3)], -1) for b in self.names], 1)
        lq, lp = self.to_local(qb, loc)
        return lq, lp, list(qb)

    def channels(self):
        return ([(j, *rotation(self.names[j], i)) for j in self.rot_bones for i in range(4)]
                + [(j, *location(self.names[j], i)) for j in self.movers for i in range(3)])

    def basis_values(self, frames, local_q, local_p, raw_prev):
        qb, loc = self.to_basis(local_q, local_p)
        out = {}
        for j in self.rot_bones:
            q = _continuous(qb[:, j], frames, raw_prev, j)
            out.update({(j, *rotation(self.names[j], i)): q[:, i] for i in range(4)})
        for j in self.movers:
            out.update({(j, *location(self.names[j], i)): loc[:, j, i] for i in range(3)})
        return out


class MemoryModelRig(Rig):
    """A rig of the model's own skeleton in memory: its joints the model's, a quaternion per joint and the root's
    location; the fill runs on its poses directly."""

    def __init__(self, curves: MemoryCurves, model):
        self.curves, self.model, self.where = curves, model, "the rig 'memory'"
        self.names = list(model.skeleton.names)

    @property
    def joint_names(self) -> list[str]:
        return self.names

    def key_channels(self) -> list:
        return [(p, i) for _, p, i in self.channels() if (p, i) in self.curves.curves]

    def read(self, frames):
        ev = self.curves.evaluate
        q = np.stack([np.stack([ev(rotation(b, i), frames) for i in range(4)], -1) for b in self.names], 1)
        root = np.stack([ev(location(self.names[0], i), frames) for i in range(3)], -1)
        return root, q / np.linalg.norm(q, axis=-1, keepdims=True), list(q)

    def channels(self):
        return ([(j, *rotation(b, i)) for j, b in enumerate(self.names) for i in range(4)]
                + [(0, *location(self.names[0], i)) for i in range(3)])

    def basis_values(self, frames, root, local_q, raw_prev):
        out = {}
        for j, b in enumerate(self.names):
            q = _continuous(local_q[:, j], frames, raw_prev, j)
            out.update({(j, *rotation(b, i)): q[:, i] for i in range(4)})
        out.update({(0, *location(self.names[0], i)): root[:, i] for i in range(3)})
        return out


def key_motion(curves: MemoryCurves, names, local_q, frames, movers=(), locations=None, bones=None) -> None:
    """Key the motion ``local_q (F, J, 4)`` (and the ``movers``' ``locations (F, J, 3)``) at ``frames`` on the bones
    ``bones`` (default all), as an animator keys poses."""
    for j, b in enumerate(names):
        if bones is not None and b not in bones:
            continue
        for f in frames:
            for i in range(4):
                curves.key(rotation(b, i), f, local_q[f, j, i])
            if j in movers:
                for i in range(3):
                    curves.key(location(b, i), f, locations[f, j, i])
