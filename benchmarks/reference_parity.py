"""Parity of this project's LAFAN1 benchmark with the official reference code (Harvey et al. 2020).

    python benchmarks/reference_parity.py --reference PATH [--data DIR] [--tol 1e-6]

``--reference`` is a checkout of https://github.com/ubisoft/ubisoft-laforge-animation-dataset that you
supply; nothing from it is copied here.  Its ``lafan1`` package is imported from that path only, and its
own functions are called.  ``--data`` is a flat folder of LAFAN-format ``<name>_subjectN.bvh`` files (the
official reader lists only the top level and splits the name on its single ``_``).  Without ``--data``,
the project's synthetic dataset (:func:`inbetweening.data.synthetic.generate_dataset`) is written to a
temporary folder and used.

Both sides run the LAFAN1 protocol (subject1-4 train, windows 50/20, subject5 test, windows 65/40,
root forward = local +Y, which the official ``utils.rotate_at_frame`` hard-codes):

* official: the call sequence of its top-level script ``evaluate.py``:
  ``extract.get_train_stats`` -> ``extract.get_lafan1_set(..., window=65, offset=40)`` ->
  ``benchmarks.benchmark_interpolation``;
* project: ``inbetweening.data.datasets.load_dataset("lafan1", path=DIR, use_cache=False)`` (whose
  ``prepare`` calls ``data.windows.prepare_windows`` and ``data.windows.position_stats``), then
  ``benchmark.evaluate_transitions`` with ``benchmark.zero_velocity`` and ``benchmark.interpolation``.

Compared: (a) the training statistics x_mean / x_std (66 values each), (b) L2Q, L2P and NPSS of both
baselines at transition lengths 5/15/30/45, and, as a diagnostic, the normalised test windows
themselves.  The exit status is 1 if any difference exceeds ``--tol`` or the window counts differ.
"""
from __future__ import annotations

import argparse
import contextlib
import importlib
import io
import os
import subprocess
import sys
import tempfile
import types
from pathlib import Path

import numpy as np

from inbetweening.data import windows as W
from inbetweening.data.datasets import load_dataset
from inbetweening.data.synthetic import generate_dataset
from inbetweening.evaluation import benchmark as B

TRAIN_ACTORS = ["subject1", "subject2", "subject3", "subject4"]  # as in the official evaluate.py
TEST_ACTORS = ["subject5"]
# official result keys -> this project's metric names
BASELINES = {"zerov": "zero_velocity", "interp": "interpolation"}
METRICS = {"quat": "l2q", "pos": "l2p", "npss": "npss"}


def import_reference(ref: Path) -> tuple[types.ModuleType, types.ModuleType, types.ModuleType, str]:
    """Import ``lafan1.extract/utils/benchmarks`` from ``ref`` (and nowhere else); return them and its commit."""
    if not (ref / "lafan1" / "benchmarks.py").is_file():
        sys.exit(f"--reference {ref}: no lafan1/benchmarks.py there; pass a checkout of ubisoft-laforge-animation-dataset")
    sys.path.insert(0, str(ref))
    try:
        extract = importlib.import_module("lafan1.extract")
        utils = importlib.import_module("lafan1.utils")
        benchmarks = importlib.import_module("lafan1.benchmarks")
    finally:
        sys.path.remove(str(ref))
    for m in (extract, utils, benchmarks):
        if not Path(m.__file__).resolve().is_relative_to(ref.resolve()):
            sys.exit(f"{m.__name__} was imported from {m.__file__}, not from {ref}")
    try:
        commit = subprocess.run(["git", "-C", str(ref), "rev-parse", "HEAD"], capture_output=True, text=True,
                                check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        commit = "unknown (not a git checkout)"
    return extract, utils, benchmarks, commit


def check_numpy_compat(utils: types.ModuleType) -> None:
    """Run each official function the benchmark relies on once on a tiny input under the installed numpy.

    The reference dates from 2019-2021; a numpy-2 incompatibility would show up here, and would have to
    be monkeypatched in this script (never by editing the reference).  None was found with numpy 2.4.
    """
    rng = np.random.default_rng(0)
    q = rng.normal(size=(2, 12, 4, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    x = rng.normal(size=(2, 12, 4, 3))
    parents = np.array([-1, 0, 1, 1])
    probes = {
        "utils.quat_fk": lambda: utils.quat_fk(q, x, parents),
        "utils.quat_ik": lambda: utils.quat_ik(q, x, parents),
        "utils.rotate_at_frame": lambda: utils.rotate_at_frame(x.copy(), q.copy(), parents, n_past=10),
        "utils.interpolate_local": lambda: utils.interpolate_local(
            np.concatenate([x[:, :, :1]] * 2, axis=1), np.concatenate([q] * 2, axis=1), 10, 10),
        "utils.euler_to_quat": lambda: utils.euler_to_quat(rng.normal(size=(3, 4, 3)), order="zyx"),
        "utils.remove_quat_discontinuities": lambda: utils.remove_quat_discontinuities(q[0].copy()),
    }
    for name, call in probes.items():
        try:
            call()
        except Exception as e:  # noqa: BLE001 - report any incompatibility with its name
            sys.exit(f"the reference's {name} fails under numpy {np.__version__}: {e!r}; it needs a monkeypatch here")


def run_official(extract, benchmarks, folder: Path) -> dict:
    """The official pipeline, in the order of the reference's ``evaluate.py``; its prints are captured.

    Two read-only instruments (wrappers that call the original and record what it returned) are put on
    ``extract.read_bvh`` and ``extract.get_lafan1_set``: they record which files were read in which order
    (``os.listdir`` order) and the training windows that ``get_train_stats`` builds internally, so windows
    can be matched one to one with the project's (which are in sorted file order).
    """
    files: list[tuple[str, int]] = []
    sets: list[tuple[list, int, int, np.ndarray, np.ndarray]] = []
    orig_read, orig_set = extract.read_bvh, extract.get_lafan1_set

    def read_bvh(filename, *a, **k):
        anim = orig_read(filename, *a, **k)
        files.append((os.path.basename(filename), anim.pos.shape[0]))
        return anim

    def get_lafan1_set(bvh_path, actors, window=50, offset=20):
        start = len(files)
        X, Q, parents, cl, cr = orig_set(bvh_path, actors, window=window, offset=offset)
        sets.append((files[start:], window, offset, X, Q))
        return X, Q, parents, cl, cr

    extract.read_bvh, extract.get_lafan1_set = read_bvh, get_lafan1_set
    log = io.StringIO()
    try:
        with contextlib.redirect_stdout(log):
            # evaluate.py: x_mean, x_std, offsets = extract.get_train_stats(bvh_folder, train_actors)
            x_mean, x_std, offsets = extract.get_train_stats(str(folder), TRAIN_ACTORS)
            # evaluate.py: X, Q, parents, ... = extract.get_lafan1_set(bvh_folder, test_actors, window=65, offset=40)
            X, Q, parents, _, _ = extract.get_lafan1_set(str(folder), TEST_ACTORS, window=65, offset=40)
            # evaluate.py: results = benchmarks.benchmark_interpolation(X, Q, x_mean, x_std, offsets, parents, out_path=...)
            res = benchmarks.benchmark_interpolation(X, Q, x_mean, x_std, offsets, parents, out_path=None)
    finally:
        extract.read_bvh, extract.get_lafan1_set = orig_read, orig_set
    train_files, _, _, trX, trQ = sets[0]
    test_files = sets[1][0]
    return {"x_mean": np.ravel(x_mean), "x_std": np.ravel(x_std), "X": X, "Q": Q, "trX": trX, "trQ": trQ,
            "offsets": offsets.reshape(-1, 3), "train_files": train_files, "test_files": test_files,
            "res": res, "log": log.getvalue()}


def reorder(files: list[tuple[str, int]], window: int, offset: int) -> np.ndarray:
    """Permutation taking windows in the official (listdir) file order to sorted-file-name order."""
    idx, start = {}, 0
    for name, n in files:
        k = len(W.window_starts(n, window, offset))
        idx[name] = np.arange(start, start + k)
        start += k
    return np.concatenate([idx[name] for name in sorted(idx)] or [np.zeros(0, int)])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--reference", required=True, type=Path, help="checkout of ubisoft-laforge-animation-dataset")
    ap.add_argument("--data", type=Path, help="flat folder of LAFAN-format *_subjectN.bvh files "
                    "(default: the project's synthetic dataset, generated into a temporary folder)")
    ap.add_argument("--clips", type=int, default=40, help="synthetic default only: number of clips")
    ap.add_argument("--seed", type=int, default=0, help="synthetic default only: generator seed")
    ap.add_argument("--tol", type=float, default=1e-6, help="largest accepted absolute difference")
    args = ap.parse_args()

    extract, utils, benchmarks, commit = import_reference(args.reference)
    check_numpy_compat(utils)
    print(f"reference: {args.reference.resolve()}  commit {commit}")
    print(f"numpy {np.__version__}: the reference runs unmodified (no monkeypatch needed or applied)")

    with tempfile.TemporaryDirectory(prefix="lafan_parity_") as tmp:
        if args.data is None:
            folder = generate_dataset(tmp, num_clips=args.clips, seed=args.seed)
            print(f"data: project synthetic dataset, generate_dataset(num_clips={args.clips}, seed={args.seed}) "
                  f"-> {folder}")
        else:
            folder = args.data
            print(f"data: {folder}")
        top = sorted(p.name for p in folder.iterdir() if p.name.endswith(".bvh"))
        nested = sorted(p.name for p in folder.rglob("*.bvh"))
        if top != nested:
            print("error: the official reader lists only the folder's top level; put every .bvh file there")
            return 1

        off = run_official(extract, benchmarks, folder)
        data = load_dataset("lafan1", path=folder, use_cache=False)  # forward +Y, as the reference
        bench = data.benchmark_set()
        ours = {}
        for name in BASELINES.values():
            ours.update({f"{name}/{k}": v for k, v in B.evaluate_transitions(bench, B.BASELINES[name]).items()})
        trX, trQ = W.prepare_windows(data.train, data.skeleton, W.TRAIN_WINDOW, W.TRAIN_OFFSET, data.forward_axis)

    n_tr_files, n_te_files = len(off["train_files"]), len(off["test_files"])
    print(f"files: {len(top)} .bvh ({n_tr_files} train subject1-4, {n_te_files} test subject5; "
          f"project read {len(data.train)} / {len(data.test)})")
    print(f"windows: train (50/20) official {len(off['trX'])}, project {len(trX)}; "
          f"test (65/40) official {len(off['X'])}, project {bench.n_windows}")
    ok = (len(off["trX"]), len(off["X"]), n_tr_files, n_te_files) == (
        len(trX), bench.n_windows, len(data.train), len(data.test))
    if not ok:
        print("error: the two sides did not read the same files / cut the same number of windows")

    rows: list[tuple[str, float, float, float]] = []  # (quantity, official, project, max |diff|)
    for key, mine in (("x_mean", data.pos_mean), ("x_std", data.pos_std)):
        d = float(np.max(np.abs(off[key] - np.asarray(mine))))
        rows.append((f"{key} ({off[key].size} values; max |value|)", float(np.max(np.abs(off[key]))),
                     float(np.max(np.abs(mine))), d))
    for n in W.TRANSITION_LENGTHS:
        for okey, name in BASELINES.items():
            for m_off, m in METRICS.items():
                a, b = float(off["res"][(f"{okey}_{m_off}_loss", n)]), float(ours[f"{name}/{m}@{n}"])
                rows.append((f"{name} {m.upper()}@{n}", a, b, abs(a - b)))

    # Diagnostics (reported, not part of the pass/fail check).  The official benchmark_interpolation builds
    # every pose from the ``offsets`` that extract.get_train_stats takes from ``xtrain[0:1, 0:1, 1:, :]``: the
    # bone offsets of the first training window (first file in os.listdir order) after the IK round trip
    # of utils.rotate_at_frame, whereas the project scores with the BVH file's offsets (Skeleton.offsets).
    diag: list[tuple[str, float]] = []
    if ok:
        ptr = reorder(off["train_files"], 50, 20)
        pte = reorder(off["test_files"], 65, 40)
        o_offsets = off["offsets"]  # what get_train_stats returned (= xtrain[0, 0, 1:])
        skel = data.skeleton
        alt = W.BenchmarkSet(bench.X, bench.Q, type(skel)(skel.names, skel.parents,
                             np.concatenate([skel.offsets[:1], o_offsets])), bench.mean, bench.std)
        alt_l2p = 0.0
        for okey, name in BASELINES.items():
            r = B.evaluate_transitions(alt, B.BASELINES[name])
            alt_l2p = max(alt_l2p, *(abs(float(off["res"][(f"{okey}_pos_loss", n)]) - r[f"l2p@{n}"])
                                     for n in W.TRANSITION_LENGTHS))
        diag = [
            ("train windows, local quaternions", float(np.max(np.abs(off["trQ"][ptr] - trQ)))),
            ("train windows, root positions (cm)", float(np.max(np.abs(off["trX"][ptr][:, :, 0] - trX[:, :, 0])))),
            ("test windows, local quaternions", float(np.max(np.abs(off["Q"][pte] - bench.Q)))),
            ("test windows, root positions (cm)", float(np.max(np.abs(off["X"][pte][:, :, 0] - bench.X[:, :, 0])))),
            (f"official `offsets` (window 0 of {off['train_files'][0][0]}, first in os.listdir order) vs the "
             "BVH offsets (cm)", float(np.max(np.abs(o_offsets - skel.offsets[1:])))),
            ("L2P, project's benchmark.score fed the official `offsets` instead", alt_l2p),
        ]

    w = max(len(r[0]) for r in rows)
    print()
    print(f"{'quantity':<{w}} | {'official':>14} | {'project':>14} | {'max |diff|':>10}")
    print("-" * w + "-+-" + "-" * 14 + "-+-" + "-" * 14 + "-+-" + "-" * 10)
    for q, a, b, d in rows:
        print(f"{q:<{w}} | {a:14.9f} | {b:14.9f} | {d:10.2e}")
    worst_stats = max(d for q, _, _, d in rows[:2])
    worst = {m: max(d for q, _, _, d in rows[2:] if f" {m.upper()}@" in q) for m in METRICS.values()}
    print()
    print(f"max |diff|: training stats {worst_stats:.2e}; " + ", ".join(f"{m.upper()} {v:.2e}" for m, v in worst.items()))
    if diag:
        print("diagnostics (windows matched one to one across the two file orders; max |diff|):")
        for q, d in diag:
            print(f"  {q}: {d:.2e}")
    bad = [q for q, _, _, d in rows if not d <= args.tol]
    if bad or not ok:
        print(f"FAIL: differences above {args.tol:g}: {bad}" if bad else "FAIL")
        return 1
    print(f"PASS: every compared quantity agrees to within {args.tol:g}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
