"""Figures of docs/blender.md from real Blender: a Bandai-Namco-2 test clip, keys every 30 frames, Blender's default
Bezier interpolation against the extension's fill.

    python benchmarks/blender_figures.py [--data ../shared/datasets/bandai-namco-2.zip] [--clip NAME] [--every 30]

Writes docs/blender/timeline.png (F-curves: the original clip, Bezier through the keys, the filled keys) and
docs/blender/poses.png (the project's renderer: poses across one gap).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import tempfile
import zipfile
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from inbetweening.rendering.render import render_png

ROOT = Path(__file__).resolve().parents[1]
CLIP = "Bandai-Namco-Research-Motiondataset-2/data/dataset-2_walk-turn-left_normal_030.bvh"
# sampled; the figure shows the Hips' forward location and, per leg bone, its Euler angle with the largest range
CHANNELS = [["Hips", "location", 1]] + [[b, "rotation_euler", i] for b in ("UpperLeg_L", "LowerLeg_L") for i in range(3)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default=str(ROOT.parent / "shared" / "datasets" / "bandai-namco-2.zip"))
    ap.add_argument("--clip", default=CLIP)
    ap.add_argument("--every", type=int, default=30)
    ap.add_argument("--frames", type=int, default=121)
    args = ap.parse_args()
    from inbetweening.blender.bpyenv import bpy_python
    from inbetweening.blender.build import build

    out_dir = ROOT / "docs" / "blender"
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (zip_path,) = build(tmp / "dist", platforms=["linux-x64"], log=lambda *a: None)
        with zipfile.ZipFile(args.data) as zf:
            (tmp / "clip.bvh").write_bytes(zf.read(args.clip))
        cfg = {"zip": str(zip_path), "bvh": str(tmp / "clip.bvh"), "every": args.every, "frames": args.frames,
               "channels": CHANNELS, "out": str(tmp / "fig.npz")}
        (tmp / "cfg.json").write_text(json.dumps(cfg))
        env = {**os.environ, "BLENDER_USER_RESOURCES": str(tmp / "user"), "OMP_NUM_THREADS": "1"}
        subprocess.run([str(bpy_python()), str(ROOT / "benchmarks" / "blender" / "bpy_figure.py"), str(tmp / "cfg.json")],
                       check=True, env=env, capture_output=True)
        d = dict(np.load(tmp / "fig.npz"))
    keys, frames, grid = list(d["keys"]), list(d["frames"]), d["grid"]
    fig = Figure(figsize=(10, 7.5), dpi=100)
    FigureCanvasAgg(fig)
    rng = np.ptp(d["truth_c"], axis=1)
    show_c = [0] + [1 + 3 * k + int(np.argmax(rng[1 + 3 * k : 4 + 3 * k])) for k in range(2)]
    axes = fig.subplots(len(show_c), 1, sharex=True)
    on_frame = np.isclose(grid % 1, 0)
    gen = np.array([g not in keys for g in grid]) & on_frame
    at_key = np.array([g in keys for g in grid])
    for ax, c in zip(axes, show_c):
        label, t, b, f = d["labels"][c], d["truth_c"][c], d["bezier_c"][c], d["fill_c"][c]
        scale = 1.0 if "location" in str(label) else 180 / np.pi
        ax.plot(grid, t * scale, color="0.6", lw=2.5, label="original clip (every frame a key)")
        ax.plot(grid, b * scale, "--", color="tab:blue", lw=1.5, label="Blender's Bezier (auto-clamped) through the keys")
        ax.plot(grid[gen], f[gen] * scale, ".", color="tab:green", ms=5, label="keys written by Fill In-betweens")
        ax.plot(grid[at_key], f[at_key] * scale, "o", color="tab:red", ms=7, label="your keys (unchanged)")
        ax.set_ylabel(f"{label}\n{'cm' if scale == 1.0 else 'degrees'}", fontsize=8)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, loc="best")
    axes[-1].set_xlabel("frame")
    err_b = np.linalg.norm(d["bezier"] - d["truth"], axis=-1).mean()
    err_f = np.linalg.norm(d["fill"] - d["truth"], axis=-1).mean()
    fig.suptitle(f"{Path(args.clip).name}: keys every {args.every} frames; mean joint error over all frames: "
                 f"Bezier {err_b:.2f} cm, fill {err_f:.2f} cm", fontsize=10)
    fig.savefig(out_dir / "timeline.png")
    # poses across the second gap, every 5 frames
    a, b = keys[1], keys[2]
    gap = slice(a - frames[0], b - frames[0] + 1)
    show = list(range(0, b - a + 1, 5))
    seqs = {"original clip": d["truth"][gap], "Blender Bezier": d["bezier"][gap], "fill": d["fill"][gap]}
    render_png(seqs, d["parents"].tolist(), out_dir / "poses.png", frames=show,
               highlight=np.isin(np.arange(b - a + 1), [0, b - a]), up_axis=2, view=(10.0, -75.0),
               title=f"Blender frames {a}-{b} (shown as 0-{b - a}), every 5th: keys at both ends (red)")
    print(f"wrote {out_dir / 'timeline.png'} and {out_dir / 'poses.png'}")


if __name__ == "__main__":
    main()
