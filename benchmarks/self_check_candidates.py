"""The do-no-harm candidates measured against each other (RESULTS.md section 12.1): per gap of whole test clips filled
from keys alone, the raw network's error for a blend weight 0, 0.1, ..., 1 (the weight applied after the fill, so a
gap's context is the raw network's: an approximation of the runtime's left-to-right fill), and the self-check at every
interior key (the key hidden, the window from the key before to the key after, context from the raw fill).  Then each
rule's per-clip ratio to interpolation: the calibrated weight per gap length (the blend before), the oracle weight
per gap and per clip (the best possible with the truth), the self-check's projection ``w*`` and its error ratio ``x``
(what the runtime keeps: :mod:`inbetweening.runtime.trust`) with and without a limit on the check's window.

    python benchmarks/self_check_candidates.py collect <checkpoint> <split> <clips> <out.pkl>
    python benchmarks/self_check_candidates.py table <out.pkl>
"""

import sys

if sys.argv[1] == "collect":
    sys.argv = sys.argv[1:]
    import dataclasses
    import pickle
    import sys

    import numpy as np
    import torch

    from inbetweening.data.datasets import load_dataset
    from inbetweening.geometry.interp import interpolate_keyframes, interpolate_pose
    from inbetweening.geometry.quaternion import remove_discontinuities
    from inbetweening.runtime import FillRuntime
    from inbetweening.runtime.torch_backend import TorchBackend

    torch.set_num_threads(1)
    model, split, nclips, out = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
    data = load_dataset("bandai_namco", split=split)
    be = TorchBackend.from_checkpoint(model)
    rt = FillRuntime(be, foot_lock=False, self_check=False)
    prior = rt.info
    rt.info = dataclasses.replace(rt.info, blend=None)
    sk = data.skeleton
    clips = data.test
    idx = np.linspace(0, len(clips) - 1, min(nclips, len(clips))).round().astype(int)
    W = np.linspace(0, 1, 11)
    rows = []
    for K in (5, 15, 30, 45):
        for ci in idx:
            c = clips[ci]
            F = len(c.root_pos)
            keys = list(range(0, F, K))
            if len(keys) < 3:
                continue
            n = keys[-1] + 1
            T = (np.asarray(c.root_pos[:n], float), np.asarray(c.local_q[:n], float))
            rin, qin = T[0].copy(), T[1].copy()
            gen = np.ones(n, bool)
            gen[keys] = False
            rin[gen], qin[gen] = np.nan, np.nan
            I = interpolate_keyframes(rin, qin, keys)
            N = rt.fill(rin, qin, keys)
            Tp = sk.pose(*T)[1]
            # per gap errors for each weight (post-hoc)
            gaps = []
            for a, b in zip(keys, keys[1:]):
                s = slice(a + 1, b)
                errs = []
                for w in W:
                    r, q = interpolate_pose(
                        I[0][s], I[1][s], N.root[s], remove_discontinuities(N.local_q[s]), np.full(b - a - 1, w)
                    )
                    errs.append(np.linalg.norm(sk.pose(r, q)[1] - Tp[s], axis=-1).sum())
                gaps.append((a, b, np.array(errs), prior.blend_weight(b - a - 1)))
            # self-check at each interior key, context from the raw fill
            checks = []
            for j in range(1, len(keys) - 1):
                a, m, b = keys[j - 1], keys[j], keys[j + 1]
                base_r, base_q = N.root.copy(), N.local_q.copy()
                wr, wq = rt.windows([base_r], [base_q], [(a, b)])
                pr, pq, _ = rt.predict_windows(wr, wq)
                P = (pr[0][m - a - 1], pq[0][m - a - 1])
                Ii = interpolate_pose(T[0][a], T[1][a], T[0][b], T[1][b], np.array((m - a) / (b - a)))
                pp, ip, tp = sk.pose(*P)[1], sk.pose(*Ii)[1], Tp[m]
                checks.append(
                    (
                        m,
                        np.linalg.norm(pp - tp, axis=-1).mean(),
                        np.linalg.norm(ip - tp, axis=-1).mean(),
                        float(((tp - ip) * (pp - ip)).sum()),
                        float(((pp - ip) ** 2).sum()),
                    )
                )
            rows.append(dict(K=K, clip=c.name, gaps=gaps, checks=checks))
        print(K, len(rows), flush=True)
    pickle.dump(rows, open(out, "wb"))
else:
    sys.argv = sys.argv[1:]
    import pickle
    import sys

    import numpy as np

    rows = pickle.load(open(sys.argv[1], "rb"))
    W = np.linspace(0, 1, 11)

    def wi(w):
        return int(round(w * 10))

    def evaluate(rule):
        out = {}
        for K in sorted({r["K"] for r in rows}):
            rs = [r for r in rows if r["K"] == K]
            ratios, tm, ti = [], 0, 0
            for r in rs:
                m = i = 0
                ws = rule(r)
                for (_a, _b, errs, _p), w in zip(r["gaps"], ws):
                    m += errs[wi(w)]
                    i += errs[0]
                ratios.append(m / i)
                tm += m
                ti += i
            ratios = np.array(ratios)
            out[K] = (tm / ti, (ratios > 1.05).mean(), ratios.max())
        return out

    def show(name, rule):
        print(f"{name:28s}", "  ".join(f"K{K}: {a:.3f} {b * 100:4.1f}% max {c:.2f}" for K, (a, b, c) in evaluate(rule).items()))

    show("interp", lambda r: [0.0] * len(r["gaps"]))
    show("raw", lambda r: [1.0] * len(r["gaps"]))
    show("prior", lambda r: [g[3] for g in r["gaps"]])
    show("oracle per gap", lambda r: [W[np.argmin(g[2])] for g in r["gaps"]])

    def oracle_clip(r):
        tot = sum(g[2] for g in r["gaps"])
        return [W[np.argmin(tot)]] * len(r["gaps"])

    show("oracle per clip", oracle_clip)

    def selfclip(r, shrink=1.0, local=None):
        ch = r["checks"]
        out = []
        for a, b, _errs, p in r["gaps"]:
            use = [c for c in ch if local is None or abs(c[0] - a) <= local or abs(c[0] - b) <= local]
            if not use:
                out.append(p)
                continue
            num = sum(c[3] for c in use)
            den = sum(c[4] for c in use)
            wstar = np.clip(num / den, 0, 1) if den > 0 else 1
            out.append(min(p, shrink * wstar))
        return out

    show("min(prior, w*clip)", selfclip)
    for L in (1, 2, 3):
        show(f"min(prior, w*local{L}K)", lambda r, L=L: selfclip(r, local=L * (r["gaps"][0][1] - r["gaps"][0][0])))

    def errtest(r, margin=1.0):
        ch = r["checks"]
        en = sum(c[1] for c in ch)
        ei = sum(c[2] for c in ch)
        return [g[3] if en <= margin * ei else 0.0 for g in r["gaps"]]

    show("prior if net<=interp at keys", errtest)

    def ratio_w(r):
        ch = r["checks"]
        en = sum(c[1] for c in ch)
        ei = sum(c[2] for c in ch)
        x = en / ei
        f = np.clip((1.1 - x) / 0.3, 0, 1)
        return [g[3] * f for g in r["gaps"]]

    show("prior*clip((1.1-x)/.3)", ratio_w)
    print()
    for K in (5, 15):
        rs = [r for r in rows if r["K"] == K]
        xs, ows, wst = [], [], []
        for r in rs:
            ch = r["checks"]
            x = sum(c[1] for c in ch) / sum(c[2] for c in ch)
            tot = sum(g[2] for g in r["gaps"])
            ows.append(W[np.argmin(tot)])
            xs.append(x)
            wst.append(np.clip(sum(c[3] for c in ch) / sum(c[4] for c in ch), 0, 1))
        print(K, "corr x~oracle", np.corrcoef(xs, ows)[0, 1], "corr w*~oracle", np.corrcoef(wst, ows)[0, 1])
        o = np.argsort(xs)
        print(" ".join(f"{xs[i]:.2f}/{ows[i]:.1f}" for i in o))

    def gen(t1, width, only_short=None):
        def rule(r):
            L = r["gaps"][0][1] - r["gaps"][0][0]
            if only_short and 2 * L - 1 > only_short:
                return [g[3] for g in r["gaps"]]
            ch = r["checks"]
            x = sum(c[1] for c in ch) / sum(c[2] for c in ch)
            f = np.clip((t1 - x) / width, 0, 1)
            return [g[3] * f for g in r["gaps"]]

        return rule

    for t1 in (0.9, 1.0, 1.1):
        for wd in (0.2, 0.4):
            show(f"x t1={t1} w={wd} short", gen(t1, wd, 54))

    def gen(t1, wd, local=3, limit=54):
        def rule(r):
            L = r["gaps"][0][1] - r["gaps"][0][0]
            if 2 * L - 1 > limit:
                return [g[3] for g in r["gaps"]]
            out = []
            for a, b, _errs, p in r["gaps"]:
                ch = [c for c in r["checks"] if (a - local * L <= c[0] <= b + local * L)]
                x = sum(c[1] for c in ch) / sum(c[2] for c in ch)
                out.append(p * np.clip((t1 - x) / wd, 0, 1))
            return out

        return rule

    for t1, wd in ((1.05, 0.4), (1.2, 0.4), (1.3, 0.5)):
        show(f"t1={t1} w={wd} all K", gen(t1, wd, limit=200))
    show("x: runtime/trust.py", gen(1.05, 0.4, limit=54))  # FillSettings x_full 0.65, x_none 1.05, checks within the trained gap
