"""Step 2 of the detection: the structural fallback (slots from the hierarchy and the rest pose alone) and its
merge with the slots the names give."""
from __future__ import annotations

from itertools import combinations

import numpy as np

from .names import _END_WORDS
from .rig import _consistent, _Rig, _violations
from .slots import SLOTS


# --------------------------------------------------------------------------------------------
# Step 2: structure
# --------------------------------------------------------------------------------------------
def _unit(v: np.ndarray) -> np.ndarray | None:
    n = float(np.linalg.norm(v))
    return v / n if n > 1e-12 else None


class _Shape:
    """Geometry helpers over the rest pose, with end markers (leaves named ``*_end``, ``*Nub``...) left out."""

    def __init__(self, rig: _Rig):
        self.rig = rig
        ends = {j for j in range(rig.J) if not rig.children[j] and _END_WORDS & set(rig.canon[j].tokens)}
        self.children = [[c for c in ch if c not in ends] for ch in rig.children]
        self.sub = [rig.subtree(j) for j in range(rig.J)]
        ext = rig.pos.max(0) - rig.pos.min(0) if rig.J else np.zeros(3)
        self.size = float(np.linalg.norm(ext))

    def reach(self, c: int, p: int) -> float:
        """How far the subtree of ``c`` gets from joint ``p``."""
        return float(np.linalg.norm(self.rig.pos[self.sub[c]] - self.rig.pos[p], axis=1).max())

    def twist_like(self, j: int, c: int, main: int) -> bool:
        """Whether child ``c`` of ``j`` lies along the segment from ``j`` to its main child (a twist/helper bone)."""
        P = self.rig.pos
        seg = P[main] - P[j]
        length = float(np.linalg.norm(seg))
        if length < 1e-9:
            return False
        rel = P[self.sub[c]] - P[j]
        t = rel @ seg / length**2
        perp = np.linalg.norm(rel - t[:, None] * seg, axis=1)
        return bool(np.all((t > 0.02) & (t < 0.9) & (perp < 0.15 * length)))

    def main_child(self, j: int) -> int | None:
        ch = self.children[j]
        return max(ch, key=lambda c: (self.reach(c, j), -c)) if ch else None

    def real_children(self, j: int) -> list[int]:
        main = self.main_child(j)
        return [c for c in self.children[j] if c == main or not self.twist_like(j, c, main)]

    def chain(self, j: int) -> list[int]:
        """``j`` and its main children down to a leaf or a joint with two or more real children (a hand, a head)."""
        out = [j]
        while True:
            real = self.real_children(out[-1])
            if len(real) != 1:
                return out
            out.append(real[0])


def _arc(P: np.ndarray, chain: list[int]) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P[chain], axis=0), axis=1))])


def _nearest_fraction(P, chain: list[int], a: int, b: int, target: float) -> int | None:
    """The joint strictly between positions ``a`` and ``b`` of ``chain`` whose arc fraction is nearest ``target``."""
    arc = _arc(P, chain[a:b + 1])
    if arc[-1] <= 0:
        return None
    best, err = None, None
    for i in range(1, len(arc) - 1):
        f = arc[i] / arc[-1]
        if f < 0.05 or f > 0.95:
            continue
        if err is None or abs(f - target) < err:
            best, err = chain[a + i], abs(f - target)
    return best


def _structure(rig: _Rig) -> dict[str, int]:
    """Slots from the hierarchy and the rest pose alone; ``{}`` when the rig does not look like a humanoid."""
    if rig.J < 10:
        return {}
    sh = _Shape(rig)
    if sh.size <= 0:
        return {}
    # mirrored pairs of big branches: sibling subtrees of one size that reach as far
    pairs = []
    for p in range(rig.J):
        for a, b in combinations(sh.children[p], 2):
            if len(sh.sub[a]) != len(sh.sub[b]):
                continue
            ra, rb = sh.reach(a, p), sh.reach(b, p)
            if min(ra, rb) > 0.15 * sh.size and abs(ra - rb) <= 0.25 * max(ra, rb):
                pairs.append((ra + rb, p, a, b))
    combos = []
    for (r1, p1, a1, b1), (r2, p2, a2, b2) in combinations(sorted(pairs, reverse=True), 2):
        inside = set(sh.sub[a1]) | set(sh.sub[b1]) | set(sh.sub[a2]) | set(sh.sub[b2])
        if p1 in inside or p2 in inside:
            continue
        hips = rig.lca(p1, p2)
        if hips < 0:
            continue
        legs, arms = ((p1, a1, b1), (p2, a2, b2))
        if rig.depth[p2] - rig.depth[hips] < rig.depth[p1] - rig.depth[hips]:
            legs, arms = arms, legs
        combos.append((r1 + r2, hips, legs, arms))
    for _, hips, legs, arms in sorted(combos, key=lambda c: -c[0])[:12]:  # the biggest pairs that make a humanoid
        out = _humanoid(rig, sh, hips, legs, arms)
        if out:
            return out
    return {}


def _humanoid(rig: _Rig, sh: _Shape, hips: int, legs: tuple, arms: tuple) -> dict[str, int]:
    """The slots when ``legs`` and ``arms`` (each ``(branch joint, child a, child b)``) are the legs and the arms of a
    humanoid whose hips is ``hips``; ``{}`` when they are not (a level spine, hands down at the feet...)."""
    P = rig.pos
    (_, la, lb), (ap, aa, ab) = legs, arms

    def leg(a):
        ch = sh.chain(a)
        i = 0
        total = _arc(P, ch)[-1]
        while i < len(ch) - 3 and np.linalg.norm(P[ch[i]] - P[hips]) < 0.03 * total:
            i += 1  # a zero-length hip joint (CMU's LHipJoint)
        return ch, i

    (lch_a, ta), (lch_b, tb) = leg(la), leg(lb)

    def foot_of(ch, t, up):
        """The ankle: the first joint (two or more below the thigh) where the leg turns forward, or its end."""
        for i in range(t + 2, len(ch)):
            nxt = ch[i + 1] if i + 1 < len(ch) else None
            if nxt is None or len(sh.real_children(ch[i])) > 1:
                return i
            d = _unit(P[nxt] - P[ch[i]])
            if d is not None and abs(float(d @ up)) < 0.7:
                return i
        return None

    # up: from the leg ends to the hips, then again from the ankles (the toes lie forward of the hips)
    up = _unit(P[hips] - (P[lch_a[-1]] + P[lch_b[-1]]) / 2)
    feet: dict[str, int | None] = {}
    for _ in range(2):
        if up is None:
            return {}
        feet = {"a": foot_of(lch_a, ta, up), "b": foot_of(lch_b, tb, up)}
        if None in feet.values():
            return {}
        up = _unit(P[hips] - (P[lch_a[feet["a"]]] + P[lch_b[feet["b"]]]) / 2)
    if up is None:
        return {}
    spine_path = []
    j = ap
    while j != hips and j >= 0:
        spine_path.append(j)
        j = rig.parents[j]
    spine_path.reverse()
    if not spine_path:
        return {}
    out: dict[str, int] = {"Hips": hips, "Spine": spine_path[0]}
    if len(spine_path) >= 2:
        out["Chest"] = spine_path[-1]
    # head: the remaining branch of the chest that reaches highest
    others = [c for c in sh.children[ap] if c not in (aa, ab)]
    if not others:
        return {}
    top = max(others, key=lambda c: float((P[sh.sub[c]] @ up).max()))
    nch = sh.chain(top)
    out["Head"] = nch[-1]
    if len(nch) >= 2:
        out["Neck"] = nch[0]

    limbs = {}
    for name, (ch, t) in (("a", (lch_a, ta)), ("b", (lch_b, tb))):
        f = feet[name]
        knee = _nearest_fraction(P, ch, t, f, 0.5)
        toes = ch[f + 1] if f + 1 < len(ch) else None
        if toes is None and sh.real_children(ch[f]):  # several toes: the middle one
            kids = sh.real_children(ch[f])
            mid = P[kids].mean(0)
            toes = min(kids, key=lambda c: (float(np.linalg.norm(P[c] - mid)), c))
        limbs["leg_" + name] = {"UpperLeg": ch[t], "LowerLeg": knee, "Foot": ch[f], "Toes": toes}
    for name, a in (("a", aa), ("b", ab)):
        ch = sh.chain(a)
        if len(ch) < 3:
            return {}
        hand_i = len(ch) - 1
        for i in range(2, len(ch)):
            if len(sh.real_children(ch[i])) > 1:
                hand_i = i
                break
        lateral_start = np.linalg.norm((P[ch[0]] - P[ap]) - ((P[ch[0]] - P[ap]) @ up) * up)
        lateral_hand = np.linalg.norm((P[ch[hand_i]] - P[ap]) - ((P[ch[hand_i]] - P[ap]) @ up) * up)
        seg = np.linalg.norm(np.diff(P[ch], axis=0), axis=1)  # seg[i]: from ch[i] to ch[i + 1]
        if not sh.children[ch[hand_i]] and hand_i >= 3 and seg[hand_i - 1] < 0.5 * seg[hand_i - 2]:
            hand_i -= 1  # a short leaf past the wrist (SMPL's left_hand, a hand end bone)
        u = 0
        if hand_i >= 3 and lateral_start < 0.15 * lateral_hand:
            u = 1  # a clavicle: it starts near the middle of the body
            while u < hand_i - 2 and (seg[u - 1] < 1e-9 or seg[u] < 0.3 * seg[u + 1]):
                u += 1  # a zero-length clavicle start, or a short shoulder bone before the upper arm
        elbow = _nearest_fraction(P, ch, u, hand_i, 0.53)
        limbs["arm_" + name] = {"Shoulder": ch[0] if u else None, "UpperArm": ch[u], "LowerArm": elbow,
                                "Hand": ch[hand_i]}
    # a humanoid: the spine goes up, the hands hang well above the feet
    feet = [limbs[f"leg_{n}"]["Foot"] for n in "ab"]
    hands = [limbs[f"arm_{n}"]["Hand"] for n in "ab"]
    floor = min(float(P[f] @ up) for f in feet)
    height = float(P[out["Head"]] @ up) - floor
    spine_dir = _unit(P[out["Head"]] - P[hips])
    if height <= 0 or spine_dir is None or float(spine_dir @ up) < 0.7:
        return {}
    if min(float(P[h] @ up) for h in hands) - floor < 0.25 * height:
        return {}
    # left and right: forward from the toes (else the usual facing of a Y-up or Z-up file), left = up x forward
    fwd = np.zeros(3)
    for n in "ab":
        leg_ = limbs[f"leg_{n}"]
        if leg_["Toes"] is not None:
            v = P[leg_["Toes"]] - P[leg_["Foot"]]
            fwd += v - (v @ up) * up
    fwd = _unit(fwd)
    if fwd is None:
        fwd = np.array([0.0, 0.0, 1.0]) if abs(up[1]) >= abs(up[2]) else np.array([0.0, -1.0, 0.0])
        fwd = _unit(fwd - (fwd @ up) * up)
        if fwd is None:
            return {}
    left = np.cross(up, fwd)
    side_leg = {n: "L" if float((P[limbs[f"leg_{n}"]["UpperLeg"]] - P[hips]) @ left) > 0 else "R" for n in "ab"}
    side_arm = {n: "L" if float((P[limbs[f"arm_{n}"]["Hand"]] - P[ap]) @ left) > 0 else "R" for n in "ab"}
    if side_leg["a"] == side_leg["b"] or side_arm["a"] == side_arm["b"]:
        return {}
    for n in "ab":
        for kind, j in limbs[f"leg_{n}"].items():
            if j is not None:
                out[f"{kind}_{side_leg[n]}"] = j
        for kind, j in limbs[f"arm_{n}"].items():
            if j is not None:
                out[f"{kind}_{side_arm[n]}"] = j
    return _consistent(rig, out)


def _merge(rig: _Rig, named: dict[str, int], shaped: dict[str, int]) -> dict[str, int]:
    """``named`` with the slots it lacks taken from ``shaped`` where they fit (left/right turned to agree)."""
    agree = disagree = 0
    for s, j in shaped.items():
        if s[-2:] in ("_L", "_R"):
            for t, k in named.items():
                if k == j and t[-2:] in ("_L", "_R"):
                    agree += t[-1] == s[-1]
                    disagree += t[-1] != s[-1]
    if disagree > agree:
        flip = {"L": "R", "R": "L"}
        shaped = {(s[:-1] + flip[s[-1]] if s[-2:] in ("_L", "_R") else s): j for s, j in shaped.items()}
    out = dict(named)
    for s in SLOTS:
        if s in out or s not in shaped or shaped[s] in out.values():
            continue
        trial = {**out, s: shaped[s]}
        if not _violations(rig, trial):
            out = trial
    return out
