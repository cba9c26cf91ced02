"""Step 1 of the detection: the slots the bone names give, under the preset that fits the rig best."""
from __future__ import annotations

from .names import _COMPILED, _KINDS, PRESETS
from .rig import _consistent, _Rig
from .slots import _SIDED, REQUIRED


# --------------------------------------------------------------------------------------------
# Step 1: names
# --------------------------------------------------------------------------------------------
def _matches(rig: _Rig, pats, sided: str | None) -> list[tuple[int, int]]:
    """``(alias index, joint)`` of the bones whose canonical key matches one of ``pats`` on side ``sided``."""
    out = []
    for j, c in enumerate(rig.canon):
        if c.side != sided:
            continue
        for a, pat in enumerate(pats):
            if pat.fullmatch(c.key):
                out.append((a, j))
                break
    return out


def _ordered(rig: _Rig, found: list[tuple[int, int]]) -> list[int]:
    """Candidates best first: deform bones before plain before ORG-/MCH-, then the preset's alias order, depth."""
    return [j for a, j in sorted(found, key=lambda aj: (rig.canon[aj[1]].priority, aj[0], rig.depth[aj[1]], aj[1]))]


def _by_preset(rig: _Rig, preset: str) -> tuple[dict[str, int], int]:
    """The slots ``preset``'s names give on this rig (consistent with the hierarchy), and how many bones it names."""
    pats = _COMPILED[preset]
    cand = {k: _ordered(rig, _matches(rig, pats[k], None)) for k in ("Hips", "spine", "neck", "Head")}
    for s in "LR":
        for kind in _SIDED:
            cand[f"{kind}_{s}"] = _ordered(rig, _matches(rig, pats[kind], s))
    used: set[int] = set()

    def pick(key, under=None, above=None):
        for j in cand[key]:
            if j in used or (under is not None and not rig.is_below(j, under)):
                continue
            if above is not None and not rig.is_below(above, j):
                continue
            return j
        return None

    # the hips: the deepest candidate that holds a spine bone and both legs, else the first one
    hips = None
    for h in sorted(cand["Hips"], key=lambda j: (rig.canon[j].priority, -rig.depth[j])):
        if all(any(rig.is_below(j, h) for j in cand[k]) for k in ("spine", "UpperLeg_L", "UpperLeg_R")):
            hips = h
            break
    if hips is None and cand["Hips"]:
        hips = cand["Hips"][0]
    out: dict[str, int] = {}
    if hips is not None:
        out["Hips"] = hips
        used.add(hips)
    head = pick("Head", under=hips)
    if head is not None:
        out["Head"] = head
        used.add(head)
    necks = [j for j in cand["neck"] if j not in used and (hips is None or rig.is_below(j, hips))
             and (head is None or rig.is_below(head, j))]
    if necks:
        out["Neck"] = min(necks, key=lambda j: (rig.canon[j].priority, rig.depth[j]))
        used.add(out["Neck"])
    for s in "LR":
        top = hips
        for kind in ("UpperLeg", "LowerLeg", "Foot", "Toes"):
            j = pick(f"{kind}_{s}", under=top)
            if j is not None:
                out[f"{kind}_{s}"], top = j, j
                used.add(j)
        top = hips
        for kind in ("UpperArm", "LowerArm", "Hand"):
            j = pick(f"{kind}_{s}", under=top)
            if j is not None:
                out[f"{kind}_{s}"], top = j, j
                used.add(j)
        j = pick(f"Shoulder_{s}", under=hips, above=out.get(f"UpperArm_{s}"))
        if j is not None:
            out[f"Shoulder_{s}"] = j
            used.add(j)
    # the spine chain: below the hips, above the neck/head; Spine the first, Chest the last above neck and arms
    tops = [out[k] for k in ("Neck", "Head") if k in out][:1]
    tops += [out.get(f"Shoulder_{s}", out.get(f"UpperArm_{s}")) for s in "LR"]
    tops = [t for t in tops if t is not None]
    chain = [j for j in cand["spine"] if j not in used and (hips is None or rig.is_below(j, hips))
             and all(rig.is_below(t, j) for t in tops[:1])]
    # one bone per depth (two bones of one chain can share a canonical name only with other prefixes: keep the best)
    best: dict[int, int] = {}
    for j in chain:
        best.setdefault(rig.depth[j], j)
    chain = [best[d] for d in sorted(best)]
    if chain:
        out["Spine"] = chain[0]
        upper = [j for j in chain[1:] if all(rig.is_below(t, j) for t in tops)]
        if upper:
            out["Chest"] = upper[-1]
    out = _consistent(rig, out)
    vocab = list(pats["other"]) + [p for k in _KINDS for p in pats[k]]
    named = sum(1 for c in rig.canon if any(p.fullmatch(c.key) for p in vocab))
    return out, named


def _names_pass(rig: _Rig) -> tuple[dict[str, int], str | None]:
    best, best_score, best_preset = {}, None, None
    for preset in PRESETS:
        slots, named = _by_preset(rig, preset)
        required = sum(s in slots for s in REQUIRED)
        score = (required, 0 if preset == "generic" else named, len(slots))
        if best_score is None or score > best_score:
            best, best_score, best_preset = slots, score, preset
    return best, (best_preset if best else None)
