"""The gate lab (RESULTS.md section 12.9): how much of the network's correction each generated window should keep,
judged offline against the ground truth, for the trust candidates the fill could use.

    python benchmarks/gate_lab.py collect <ckpt[,ckpt2]> <split> <clips> <out.npz>
    python benchmarks/gate_lab.py report <dir with loco_<content>.npz, content.npz, standard.npz>

``collect`` fills ``clips`` test clips of the split (evenly spaced) on the six keys-only schedules through the fill
runtime with its defaults but the feet unlocked, then takes every generated window again from the fill's own output
(the context the network saw) and records: the gap length, the calibrated weight ``prior``, the weight used
``weight``, the self-check's pooled error ratio ``x`` (NaN: no check within reach), the members' disagreement ``dis``
and the network's correction ``corr`` (mean joint distance, cm), the window's pose features (``feat``: the last
context frame and the target key in the canonical frame, quaternions and root height, and the root's move and
velocity) and ``err[i]``: the window's summed joint error against the ground truth when the correction is kept at
weight ``i / 10``.  ``report`` scores weights per window offline: pooled ratio to interpolation / share of clips worse
than it by more than 5 %, per schedule, for the fill's weights, a novelty trust (the kNN distance of the window's
pose features to those of windows of the contents the model was trained on, in a whitened PCA space), a learned gate
(the weight times a logistic function of the window's signals, fitted leave-one-content-out on the leave-one-content-
out windows) and the oracle (each window's best weight).  Leave-one-content-out files come from the models of
``benchmarks/loco_train.sh`` (``<v1 dir>/<c>/checkpoints/calibrated.ckpt,<v2 dir>/<c>/...`` on ``holdout-<c>``).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from inbetweening.data.specs import BN_CONTENTS
from inbetweening.data.specs import BN_TEST_CONTENTS as CONTENT_TEST
from inbetweening.evaluation.keyframes import WORSE

SCHEDULES = ["5", "15", "30", "45", "random", "extremes"]
GRID = np.linspace(0.0, 1.0, 11)


def collect(ckpts: str, split: str, n_clips: int, out: str) -> None:
    import torch

    from inbetweening.data.datasets import load_dataset
    from inbetweening.evaluation.schedules import schedule_keyframes
    from inbetweening.geometry import canonical
    from inbetweening.geometry.interp import interpolate_pose
    from inbetweening.runtime import FillRuntime
    from inbetweening.runtime.ensemble import EnsembleBackend
    from inbetweening.runtime.torch_backend import TorchBackend
    from inbetweening.runtime.trust import gap_weights

    torch.set_num_threads(1)
    data = load_dataset("bandai_namco", split=split)
    sk = data.skeleton
    members = [TorchBackend.from_checkpoint(p) for p in ckpts.split(",")]
    backend = EnsembleBackend(members) if len(members) > 1 else members[0]
    rt = FillRuntime(backend, foot_lock=False)
    alone = [FillRuntime(m, foot_lock=False) for m in members] if len(members) > 1 else []
    info, p = rt.info, rt.info.n_past
    clips = data.test
    if n_clips < len(clips):
        clips = [clips[i] for i in np.linspace(0, len(clips) - 1, n_clips).round().astype(int)]
    rows = []
    for s in SCHEDULES:
        sched = int(s) if s.isdigit() else s
        for ci, clip in enumerate(clips):
            gt_r, gt_q = np.asarray(clip.root_pos, np.float64), np.asarray(clip.local_q, np.float64)
            keys = schedule_keyframes(sched, len(gt_r), np.random.default_rng([0, ci]), sk.pose(gt_r, gt_q)[1])
            if not keys:
                continue
            n = keys[-1] + 1
            r_in, q_in = gt_r[:n].copy(), gt_q[:n].copy()
            gen = np.ones(n, bool)
            gen[keys] = False
            r_in[gen], q_in[gen] = np.nan, np.nan
            filled = rt.fill(r_in, q_in, keys)
            xs = gap_weights([(a, b) for a, b, _ in filled.segments], keys, filled.checks, lambda g: None)
            for a, b, weight in filled.segments:
                g = b - a - 1
                wr, wq = rt.windows([filled.root], [filled.local_q], [(a, b)])
                pr, pq, _ = rt.predict_windows(wr, wq)
                ir, iq = interpolate_pose(filled.root[a], filled.local_q[a], filled.root[b], filled.local_q[b],
                                          (np.arange(a + 1, b) - a) / (b - a))
                truth = sk.pose(gt_r[a + 1 : b], gt_q[a + 1 : b])[1]
                err = [np.linalg.norm(sk.pose(*interpolate_pose(ir, iq, pr[0], pq[0], np.full(g, w)))[1] - truth,
                                      axis=-1).mean(-1).sum() for w in GRID]
                npos, ipos = sk.pose(pr[0], pq[0])[1], sk.pose(ir, iq)[1]
                dis = np.nan
                if alone:
                    mp = [sk.pose(*m.predict_windows(wr, wq)[:2])[1][0] for m in alone]
                    dis = float(np.mean([np.linalg.norm(x - npos, axis=-1).mean() for x in mp]))
                known = rt.known_mask(1, g)
                centre, rot = canonical.canonical_frame(wr, wq, info.forward_axis, p - 1, known[..., 0],
                                                        centre_at_frame=info.centre == "last")
                cr, cq = canonical.canonicalise(wr, wq, centre, rot)
                cr, cq = cr[0], np.where(cq[0][..., :1] < 0, -cq[0], cq[0])
                pose = np.concatenate([cq.reshape(len(cq), -1), cr[:, 1:2] / 100.0], axis=-1)
                feat = np.concatenate([pose[p - 1], pose[-1], (cr[-1] - cr[p - 1]) / 100.0,
                                       (cr[p - 1] - cr[p - 2]) * info.fps / 100.0])
                prior = info.blend_weight(g)
                x = xs[(a, b)][1]
                rows.append(dict(clip=getattr(clip, "name", str(ci)), sched=s, g=g,
                                 prior=1.0 if prior is None else prior, weight=weight,
                                 x=np.nan if x is None else x, dis=dis,
                                 corr=float(np.linalg.norm(npos - ipos, axis=-1).mean()), err=np.array(err),
                                 feat=feat))
        print(f"{s}: {len(rows)} windows", flush=True)
    np.savez_compressed(out, **{k: np.array([r[k] for r in rows]) for k in rows[0]})


# ---------------------------------------------------------------------------------------------------- report
def content_of(name: str) -> str:
    return max((c for c in BN_CONTENTS if f"_{c}_" in str(name)), key=len)


def load(paths) -> dict:
    ds = [dict(np.load(p)) for p in paths]
    for p, d in zip(paths, ds):
        d["src"] = np.array([Path(p).stem] * len(d["g"]))
    return {k: np.concatenate([d[k] for d in ds]) for k in ds[0]}


def err_at(err: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Each window's error at weight ``w`` (linear between the grid's points)."""
    w = np.clip(w, 0, 1) * (len(GRID) - 1)
    lo = np.floor(w).astype(int).clip(0, len(GRID) - 2)
    f, i = w - lo, np.arange(len(err))
    return err[i, lo] * (1 - f) + err[i, lo + 1] * f


def score(d: dict, w: np.ndarray) -> list[tuple[float, float]]:
    """Per schedule: pooled ratio to interpolation, % of clips worse than interpolation by more than 5 %."""
    e, e0, out = err_at(d["err"], w), d["err"][:, 0], []
    for s in SCHEDULES:
        m = d["sched"] == s
        _, inv = np.unique(np.char.add(d["src"][m].astype(str), d["clip"][m].astype(str)), return_inverse=True)
        r = np.bincount(inv, e[m]) / np.maximum(np.bincount(inv, e0[m]), 1e-9)
        out.append((e[m].sum() / e0[m].sum(), 100 * float(np.mean(r > WORSE))))
    return out


def trust(v, full, none):
    return np.clip((none - v) / (none - full), 0, 1)


def _pca(ref: np.ndarray, k: int = 24):
    mu = ref.mean(0)
    _, s, vt = np.linalg.svd(ref - mu, full_matrices=False)
    proj = vt[:k].T / (s[:k] / np.sqrt(len(ref)) + 1e-6)
    return mu, proj, (ref - mu) @ proj


def novelty(feat: np.ndarray, ref: np.ndarray, kind: str, nn: int = 5) -> np.ndarray:
    """kNN: the mean distance to the ``nn`` nearest reference windows; gauss: the RMS whitened coordinate."""
    mu, proj, z = _pca(ref)
    q = (feat - mu) @ proj
    if kind == "gauss":
        return np.sqrt((q ** 2).mean(1))
    d2 = (q ** 2).sum(1)[:, None] + (z ** 2).sum(1)[None] - 2 * q @ z.T
    return np.sqrt(np.maximum(np.sort(d2, 1)[:, :nn], 0)).mean(1) / np.sqrt(proj.shape[1])


def novelties(sets: dict, kind: str, cols) -> dict:
    """Each set's windows against windows of the contents its model trained on (the leave-one-content-out windows as
    their stand-in): LOCO, the other nine contents; content split, the eight training contents; standard, every
    content, the same clip left out."""
    loco = sets["loco"]
    lc = np.array([content_of(c) for c in loco["clip"]])
    out = {}
    for name, d in sets.items():
        v = np.zeros(len(d["g"]))
        cont = np.array([content_of(c) for c in d["clip"]])
        if name == "loco":
            groups = [(cont == c, lc != c) for c in np.unique(cont)]
        elif name == "content":
            groups = [(np.ones(len(v), bool), ~np.isin(lc, CONTENT_TEST))]
        else:
            groups = [(d["clip"] == c, loco["clip"] != c) for c in np.unique(d["clip"])]
        for m, ref in groups:
            v[m] = novelty(d["feat"][m][:, cols], loco["feat"][ref][:, cols], kind)
        out[name] = v
    return out


def learned_gate(d: dict, nov: np.ndarray, train: np.ndarray, steps: int = 400) -> np.ndarray:
    """The fill's weight times sigmoid(theta . signals), theta fitted on the windows ``train`` to minimise their
    summed error (Adam on the piecewise-linear error), applied to every window."""
    import torch

    x = np.nan_to_num(d["x"], nan=0.8)
    r = np.minimum(d["dis"] / np.maximum(d["corr"], 1e-6), 4)
    f = np.stack([np.log(d["g"]), x, np.isnan(d["x"]), np.nan_to_num(r), nov, d["prior"]], 1)
    f = (f - f[train].mean(0)) / (f[train].std(0) + 1e-9)
    f = torch.tensor(np.concatenate([np.ones((len(f), 1)), f], 1))
    e, base = torch.tensor(d["err"]), torch.tensor(d["weight"])
    th = torch.zeros(f.shape[1], dtype=torch.float64)
    th[0] = 3.0
    th.requires_grad_(True)
    opt = torch.optim.Adam([th], lr=0.05)
    m = torch.tensor(train)
    idx = torch.arange(int(m.sum()))
    for _ in range(steps):
        w = base[m] * torch.sigmoid(f[m] @ th) * (len(GRID) - 1)
        lo = w.detach().floor().clamp(0, len(GRID) - 2).long()
        loss = (e[m][idx, lo] * (1 - (w - lo)) + e[m][idx, lo + 1] * (w - lo)).sum() / e[m][:, 0].sum()
        opt.zero_grad()
        loss.backward()
        opt.step()
    return (base * torch.sigmoid(f @ th)).detach().numpy()


def report(folder: str) -> None:
    f = Path(folder)
    sets = {"loco": load(sorted(f.glob("loco_*.npz"))), "content": load([f / "content.npz"]),
            "standard": load([f / "standard.npz"])}
    n_pose = (sets["loco"]["feat"].shape[1] - 6) // 2
    variants = {"full": slice(None), "pose": np.r_[0 : 2 * n_pose]}
    print("| windows | weights | " + " | ".join(f"keys {s}" for s in SCHEDULES) + " |")
    print("|---|---|" + "---:|" * len(SCHEDULES))

    def row(name, label, w):
        cells = " | ".join(f"{a:.3f} ({b:.1f} %)" for a, b in score(sets[name], w))
        print(f"| {name} | {label} | {cells} |")

    loco = sets["loco"]
    lc = np.array([content_of(c) for c in loco["clip"]])
    nov_loco = novelties(sets, "knn", variants["pose"])
    for name, d in sets.items():
        row(name, "the fill's (self-check)", d["weight"])
        row(name, "oracle (each window's best)", GRID[np.argmin(d["err"], 1)])
    for kind in ("knn", "gauss"):
        for feats, cols in variants.items():
            nov = novelties(sets, kind, cols)
            scale = np.median(nov["standard"])
            for name, d in sets.items():
                for full, none in ((1.5, 4.0), (2.5, 6.0)):
                    row(name, f"novelty {kind} {feats} {full}-{none}",
                        d["weight"] * trust(nov[name] / scale, full, none))
    w = np.zeros(len(loco["g"]))
    for c in np.unique(lc):  # fitted on the other contents' windows, applied to this one's
        w[lc == c] = learned_gate(loco, nov_loco["loco"], lc != c)[lc == c]
    row("loco", "learned gate (fitted leave-one-content-out)", w)
    for name in ("content", "standard"):
        d = sets[name]
        both = {k: np.concatenate([loco[k], d[k]]) for k in loco if k != "src"}
        both["src"] = np.concatenate([loco["src"], d["src"]])
        keep = np.concatenate([~np.isin(lc, CONTENT_TEST) if name == "content" else np.ones(len(lc), bool),
                               np.zeros(len(d["g"]), bool)])
        gate = learned_gate(both, np.concatenate([nov_loco["loco"], nov_loco[name]]), keep)
        row(name, "learned gate (fitted on the LOCO windows)", gate[len(lc):])


if __name__ == "__main__":
    if len(sys.argv) == 6 and sys.argv[1] == "collect":
        collect(sys.argv[2], sys.argv[3], int(sys.argv[4]), sys.argv[5])
    elif len(sys.argv) == 3 and sys.argv[1] == "report":
        report(sys.argv[2])
    else:
        sys.exit(__doc__)
