"""BVH variants of a real clip, written without the project's code: a parser, forward kinematics and a writer of this
file's own, with SciPy's rotations.  Each variant moves every joint the original has exactly as the original does
(world positions equal up to the unit and the world's turn), or says what it changes:

* :func:`rename` (other bone names), :func:`write` with any Euler order per joint and position channels on any subset
  of joints (3 or 6 channels), :func:`scale` (cm / m / inches), :func:`turn` (Y up -> Z up or any turn of the world);
* :func:`insert_bone` (a second spine bone), :func:`add_leaf` (twist bones, fingers: a motion of their own),
  :func:`add_top` (a static or moving bone above the hips), :func:`drop` (no toes, no hands: their children lost);
* :func:`rest` (another rest pose: each joint's bone frame turned by ``B_j`` at rest; the rest pose then differs,
  the motion does not), :func:`proportions` (bones longer or shorter: another character playing the rotations);
* :func:`resample` (another frame rate: rotations slerped, translations linear).

A test of the project's BVH reading, conventions or retargeting against these is not a test of that code against
itself.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation as R
from scipy.spatial.transform import Slerp


@dataclass
class Clip:
    names: list[str]
    parents: list[int]
    offsets: np.ndarray  # (J, 3)
    ends: dict[int, np.ndarray]  # joint -> end-site offset
    rot: list[R]  # per joint: F rotations (local)
    trans: np.ndarray  # (F, J, 3) local translations (offset, or the position channels)
    frame_time: float
    movers: set[int] = field(default_factory=set)  # joints whose translation is animated
    orders: dict[str, str] = field(default_factory=dict)  # per joint its file's Euler order

    @property
    def frames(self) -> int:
        return self.trans.shape[0]

    def index(self, name: str) -> int:
        return self.names.index(name)

    def children(self, j: int) -> list[int]:
        return [k for k, p in enumerate(self.parents) if p == j]


def read(path) -> Clip:
    head, motion = open(path).read().split("MOTION")
    toks = head.split()
    names, parents, offsets, chans, ends = [], [], [], [], {}
    stack, cur, i = [], None, 0
    while i < len(toks):
        t = toks[i]
        if t in ("ROOT", "JOINT"):
            names.append(toks[i + 1])
            parents.append(stack[-1] if stack else -1)
            offsets.append(None)
            chans.append([])
            cur = len(names) - 1
            i += 2
        elif t == "End":
            cur = ("end", stack[-1])
            i += 2
        elif t == "{":
            stack.append(cur)
            i += 1
        elif t == "}":
            stack.pop()
            i += 1
        elif t == "OFFSET":
            off = np.array([float(v) for v in toks[i + 1 : i + 4]])
            if isinstance(cur, tuple):
                ends[cur[1]] = off
            else:
                offsets[cur] = off
            i += 4
        elif t == "CHANNELS":
            n = int(toks[i + 1])
            chans[cur] = toks[i + 2 : i + 2 + n]
            i += 2 + n
        else:
            i += 1
    lines = [ln for ln in motion.strip().splitlines() if ln.strip()]
    n = int(lines[0].split()[1])
    ft = float(lines[1].split()[-1])
    data = np.array([[float(v) for v in ln.split()] for ln in lines[2 : 2 + n]])
    col, rot, trans, movers, orders = 0, [], np.zeros((n, len(names), 3)), set(), {}
    for j, ch in enumerate(chans):
        block = data[:, col : col + len(ch)]
        col += len(ch)
        trans[:, j] = offsets[j]
        for c in ch:
            if c.lower().endswith("position"):
                trans[:, j, "xyz".index(c[0].lower())] = block[:, ch.index(c)]
                movers.add(j)
        rc = [c for c in ch if c.lower().endswith("rotation")]
        if rc:
            order = "".join(c[0].upper() for c in rc)
            orders[names[j]] = order
            rot.append(R.from_euler(order, np.stack([block[:, ch.index(c)] for c in rc], 1), degrees=True))
        else:
            rot.append(R.identity(n))
    return Clip(names, parents, np.array(offsets), ends, rot, trans, ft, movers, orders)


def positions(c: Clip) -> np.ndarray:
    """World positions ``(F, J, 3)``."""
    g, p = [], []
    for j, par in enumerate(c.parents):
        if par < 0:
            g.append(c.rot[j])
            p.append(c.trans[:, j])
        else:
            g.append(g[par] * c.rot[j])
            p.append(p[par] + g[par].apply(c.trans[:, j]))
    return np.stack(p, 1)


def write(c: Clip, path, orders=None, six=(), movers=None, decimals: int = 6) -> None:
    """``orders``: per joint name an Euler order (default the clip's own, else ``XYZ``; a str for every joint);
    ``six``: joints written with six channels (their translation, constant or not); ``movers``: joints whose
    translation is written (default the clip's animated ones)."""
    movers = c.movers if movers is None else {c.index(m) if isinstance(m, str) else m for m in movers}
    six = {c.index(m) if isinstance(m, str) else m for m in six}
    lines, cols = ["HIERARCHY"], []
    fmt = f"%.{decimals}f"

    def emit(j, d):
        ind = "\t" * d
        order = orders if isinstance(orders, str) else (orders or c.orders).get(c.names[j], "XYZ")
        lines.append(f"{ind}{'ROOT' if c.parents[j] < 0 else 'JOINT'} {c.names[j]}")
        lines.append(ind + "{")
        lines.append(f"{ind}\tOFFSET {' '.join(fmt % v for v in c.offsets[j])}")
        pos = j in movers or j in six
        ch = (["Xposition", "Yposition", "Zposition"] if pos else []) + [f"{a}rotation" for a in order]
        lines.append(f"{ind}\tCHANNELS {len(ch)} {' '.join(ch)}")
        if pos:
            cols.append(c.trans[:, j])
        cols.append(c.rot[j].as_euler(order, degrees=True))
        for k in c.children(j):
            emit(k, d + 1)
        if j in c.ends:
            lines.extend([f"{ind}\tEnd Site", ind + "\t{", f"{ind}\t\tOFFSET {' '.join(fmt % v for v in c.ends[j])}",
                          ind + "\t}"])
        lines.append(ind + "}")

    emit(0, 0)
    m = np.concatenate(cols, 1)
    lines += ["MOTION", f"Frames: {len(m)}", f"Frame Time: {c.frame_time:.7f}"]
    lines += [" ".join(fmt % v for v in row) for row in m]
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


# ---------------------------------------------------------------------------------------------------- variants
def rename(c: Clip, mapping: dict[str, str]) -> Clip:
    out = copy.deepcopy(c)
    out.names = [mapping.get(n, n) for n in c.names]
    return out


def scale(c: Clip, k: float) -> Clip:
    """Lengths times ``k`` (cm -> m: 0.01; cm -> inches: 1 / 2.54)."""
    out = copy.deepcopy(c)
    out.offsets = c.offsets * k
    out.trans = c.trans * k
    out.ends = {j: e * k for j, e in c.ends.items()}
    return out


def turn(c: Clip, w: R) -> Clip:
    """The whole world turned by ``w`` (Y up -> Z up: +90 degrees about X): offsets turned, rotations conjugated."""
    out = copy.deepcopy(c)
    out.offsets = w.apply(c.offsets)
    out.trans = w.apply(c.trans.reshape(-1, 3)).reshape(c.trans.shape)
    out.ends = {j: w.apply(e) for j, e in c.ends.items()}
    out.rot = [w * r * w.inv() for r in c.rot]
    return out


def rest(c: Clip, frames: dict[str, R]) -> Clip:
    """Another rest pose: joint ``j``'s bone frame is ``B_j`` (``frames[name]``, default the identity) where the
    original's is the identity; world positions unchanged: ``L'_j = B_p^-1 L_j B_j``, offsets ``B_p^-1 o_j``."""
    out = copy.deepcopy(c)
    b = [frames.get(n, R.identity()) for n in c.names]
    for j, p in enumerate(c.parents):
        bp = b[p] if p >= 0 else R.identity()
        out.rot[j] = bp.inv() * c.rot[j] * b[j]
        out.offsets[j] = bp.inv().apply(c.offsets[j])
        out.trans[:, j] = bp.inv().apply(c.trans[:, j])
        if j in c.ends:
            out.ends[j] = b[j].inv().apply(c.ends[j])
    return out


def aim_frames(c: Clip, directions: dict[str, np.ndarray], roll: dict[str, float] | None = None,
               frame: int | None = None) -> dict[str, R]:
    """Bone frames ``B_j`` for :func:`rest` that put bone ``j`` (from it to its first child, or its end site) along
    ``directions[name]`` in the new rest pose, rolled about it by ``roll[name]`` degrees, each after its parent's:
    with every bone of a chain listed, the rest pose is the listed one (a T-pose, an A-pose, bent limbs).
    ``frame``: where a joint is not listed, its frame at that frame of the motion (default: the identity)."""
    roll = roll or {}
    g = {}  # world rotation of each joint's original frame in the new rest pose
    out = {}
    for j, p in enumerate(c.parents):
        gp = g[p] if p >= 0 else R.identity()
        n = c.names[j]
        kids = c.children(j)
        bone = c.offsets[kids[0]] if kids else c.ends.get(j, np.zeros(3))
        if n in directions and np.linalg.norm(bone) > 0:
            want = np.asarray(directions[n], float)
            # the new rest's world rotation of the joint's original frame turns the bone (in that frame) onto `want`
            a = bone / np.linalg.norm(bone)
            bdir = want / np.linalg.norm(want)
            rot, _ = R.align_vectors([bdir], [a])
            gj = R.from_rotvec(np.radians(roll.get(n, 0.0)) * bdir) * rot
        elif frame is not None:
            gj = gp * c.rot[j][frame]
        else:
            gj = gp
        g[j] = gj
        # the rest pose has every local rotation the identity: the joint's rest world frame is the world, so the
        # original frame sits at gj = B_j^-1 in it
        out[n] = gj.inv()
    return out


def insert_bone(c: Clip, child: str, name: str, frac: float = 0.5) -> Clip:
    """A bone ``name`` inserted above ``child`` at ``frac`` of its offset, without a motion of its own."""
    j = c.index(child)
    out = copy.deepcopy(c)
    p = c.parents[j]
    new = len(c.names)
    out.names.append(name)
    out.parents.append(p)
    out.parents[j] = new
    out.offsets = np.vstack([c.offsets, frac * c.offsets[j]])
    out.offsets[j] = (1 - frac) * c.offsets[j]
    out.trans = np.concatenate([c.trans, frac * c.trans[:, j : j + 1]], 1)
    out.trans[:, j] = (1 - frac) * c.trans[:, j]
    out.rot.append(R.identity(c.frames))
    return _reorder(out)


def add_leaf(c: Clip, parent: str, name: str, offset, seed: int = 0, amplitude: float = 40.0) -> Clip:
    """A bone ``name`` under ``parent`` turning on its own (a twist bone, a finger)."""
    rng = np.random.default_rng(seed)
    out = copy.deepcopy(c)
    out.names.append(name)
    out.parents.append(c.index(parent))
    out.offsets = np.vstack([c.offsets, offset])
    out.trans = np.concatenate([c.trans, np.broadcast_to(np.asarray(offset, float), (c.frames, 1, 3))], 1)
    t = np.arange(c.frames) / 30.0
    ang = amplitude * np.stack([np.sin(t * f + ph) for f, ph in rng.uniform(0.5, 3, (3, 2))], 1)
    out.rot.append(R.from_euler("XYZ", ang, degrees=True))
    out.ends[len(c.names)] = 0.3 * np.asarray(offset, float)
    return _reorder(out)


def add_top(c: Clip, name: str, moving: bool) -> Clip:
    """A bone ``name`` above the root: static at the origin, or moving (sliding and turning about the up axis Y) with
    the old root's local values compensating, so the world motion is unchanged."""
    n = c.frames
    out = copy.deepcopy(c)
    if moving:
        t = np.arange(n) / 30.0
        top_p = np.stack([20 * np.sin(t), 0 * t, 15 * t], 1)
        top_r = R.from_euler("Y", 25 * np.sin(0.7 * t)[:, None], degrees=True)
    else:
        top_p, top_r = np.zeros((n, 3)), R.identity(n)
    out.names = [name] + c.names
    out.parents = [-1] + [p + 1 for p in c.parents]
    out.offsets = np.vstack([np.zeros(3), c.offsets])
    root_p = top_r.inv().apply(c.trans[:, 0] - top_p)
    out.trans = np.concatenate([top_p[:, None], c.trans], 1)
    out.trans[:, 1] = root_p
    out.rot = [top_r, top_r.inv() * c.rot[0]] + c.rot[1:]
    out.ends = {j + 1: e for j, e in c.ends.items()}
    out.movers = {0} | {m + 1 for m in c.movers} if moving else {m + 1 for m in c.movers}
    return out


def drop(c: Clip, names) -> Clip:
    """The joints ``names`` and everything below them removed (their parents become leaves with an end site)."""
    gone = set()
    for j, p in enumerate(c.parents):
        if c.names[j] in names or p in gone:
            gone.add(j)
    keep = [j for j in range(len(c.names)) if j not in gone]
    out = _take(c, keep)
    for i, j in enumerate(keep):
        if j not in c.ends and i not in out.parents:  # a new leaf: its end site where its child was
            out.ends[i] = next(c.offsets[k] for k in range(len(c.names)) if c.parents[k] == j)
    return out


def proportions(c: Clip, factors: dict[str, float]) -> Clip:
    """Bones scaled: the offset of each child of joint ``name`` (and its end site) times ``factors[name]``; the root's
    translation scaled by the legs' mean factor (the character's stride).  Another character: its own truth."""
    out = copy.deepcopy(c)
    for j, p in enumerate(c.parents):
        if p >= 0 and c.names[p] in factors:
            out.offsets[j] = c.offsets[j] * factors[c.names[p]]
            out.trans[:, j] = c.trans[:, j] * factors[c.names[p]]
    for j, e in c.ends.items():
        out.ends[j] = e * factors.get(c.names[j], 1.0)
    legs = [v for k, v in factors.items() if "Leg" in k or "Foot" in k or "thigh" in k or "calf" in k]
    if legs:
        for m in c.movers:
            out.trans[:, m] = c.trans[:, m] * float(np.mean(legs))
    return out


def resample(c: Clip, fps: float) -> Clip:
    """The clip at ``fps``: frames at their time, rotations slerped, translations linear."""
    n = c.frames
    t = np.arange(n) * c.frame_time
    new_t = np.minimum(np.arange(int(round(t[-1] * fps)) + 1) / fps, t[-1])
    out = copy.deepcopy(c)
    out.frame_time = 1.0 / fps
    out.rot = [Slerp(t, r)(new_t) for r in c.rot]
    out.trans = np.stack([np.stack([np.interp(new_t, t, c.trans[:, j, a]) for a in range(3)], 1)
                          for j in range(len(c.names))], 1)
    return out


def trim(c: Clip, start: int, stop: int) -> Clip:
    """Frames ``start .. stop - 1``."""
    out = copy.deepcopy(c)
    out.rot = [r[start:stop] for r in c.rot]
    out.trans = c.trans[start:stop]
    return out


def interpolate(c: Clip, keys) -> Clip:
    """The clip's frames ``keys[0] .. keys[-1]`` interpolated between ``keys``: local rotations slerped, translations
    linear (what a DCC's linear keys give)."""
    t = np.arange(keys[0], keys[-1] + 1)
    out = copy.deepcopy(c)
    out.rot = [Slerp(keys, r[keys])(t) for r in c.rot]
    out.trans = np.stack([np.stack([np.interp(t, keys, c.trans[keys, j, a]) for a in range(3)], 1)
                          for j in range(len(c.names))], 1)
    return out


def _reorder(c: Clip) -> Clip:
    """Joints in depth-first order (parents before children, as a file writes them)."""
    order = []

    def visit(j):
        order.append(j)
        for k in c.children(j):
            visit(k)

    visit(c.parents.index(-1))
    return _take(c, order)


def _take(c: Clip, joints: list[int]) -> Clip:
    """The clip of ``joints`` only, in that order (each one's parent among them or none)."""
    new = {j: i for i, j in enumerate(joints)}
    out = copy.deepcopy(c)
    out.names = [c.names[j] for j in joints]
    out.parents = [new[c.parents[j]] if c.parents[j] >= 0 else -1 for j in joints]
    out.offsets = c.offsets[joints]
    out.trans = c.trans[:, joints]
    out.rot = [c.rot[j] for j in joints]
    out.ends = {new[j]: e for j, e in c.ends.items() if j in new}
    out.movers = {new[m] for m in c.movers if m in new}
    return out
