"""What another frame rate costs: Bandai-Namco-2 test clips (30 fps) resampled to 24, 60 and 120 fps by the test's own
writer (tests/bvh_variants.py: rotations slerped, translations linear), keys every 0.5 s and 1 s at the same times,
filled through ``Inbetweener.fill`` (the runtime places the keys on the model's 30 fps frames, fills there and takes
the clip's frames at their time).  Per rate, pooled over the clips: the fill's mean joint error over the generated
frames over interpolation's at that rate, against the 30 fps original's.

    python benchmarks/frame_rates.py [--ckpt A.ckpt ...] [--clip-step 10] [--out results/characters/frame_rates.json]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import warnings
import zipfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "tests"))
DATA = ROOT.parent / "shared" / "datasets" / "bandai-namco-2.zip"
RATES = (30.0, 24.0, 60.0, 120.0)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ckpt", nargs="*", default=None)
    ap.add_argument("--clip-step", type=int, default=10)
    ap.add_argument("--out", default=str(ROOT / "results" / "characters" / "frame_rates.json"))
    args = ap.parse_args(argv)
    from _report import save_json

    import bvh_variants as V
    from inbetweening import Inbetweener
    from inbetweening.api.shipped import SHIPPED_CKPTS
    from inbetweening.data.bvh_writer import write_bvh
    from inbetweening.data.specs import bandai_namco_split

    inb = Inbetweener.from_checkpoint(args.ckpt if args.ckpt else [str(ROOT / p) for p in SHIPPED_CKPTS])
    sums: dict[str, list[float]] = {}
    with zipfile.ZipFile(DATA) as z, tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        names = sorted(n for n in z.namelist() if n.endswith(".bvh") and bandai_namco_split(Path(n).name) == "test")
        for member in names[:: args.clip_step]:
            (tmp / "clip.bvh").write_bytes(z.read(member))
            clip = V.read(tmp / "clip.bvh")
            for fps in RATES:
                c = clip if fps == 30.0 else V.resample(clip, fps)
                V.write(c, tmp / "in.bvh")
                for seconds in (0.5, 1.0):
                    keys = list(range(0, c.frames, int(round(seconds * fps))))
                    if len(keys) < 2:
                        continue
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        write_bvh(inb.fill(str(tmp / "in.bvh"), keyframes=keys), tmp / "out.bvh")
                    n = keys[-1] + 1
                    gen = np.setdiff1d(np.arange(n), keys)
                    truth = V.positions(c)[:n][gen]
                    err = np.linalg.norm(V.positions(V.read(tmp / "out.bvh"))[:n][gen] - truth, axis=-1).mean()
                    base = np.linalg.norm(V.positions(V.interpolate(c, keys))[gen] - truth, axis=-1).mean()
                    s = sums.setdefault(f"{fps:g} fps | keys every {seconds:g} s", [0.0, 0.0, 0])
                    s[0] += float(err)
                    s[1] += float(base)
                    s[2] += 1
            print(Path(member).stem, flush=True)
    table = {k: dict(ratio=e / b, clips=n) for k, (e, b, n) in sums.items()}
    for k, v in table.items():
        print(f"{k:32s} {v['ratio']:.3f} ({v['clips']} clips)")
    save_json(args.out, "frame_rates.py", argv, table=table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
